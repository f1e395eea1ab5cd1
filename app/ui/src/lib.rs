//! The inspection app's model, protocol and drawing: one UI for the desktop window and the
//! browser. Load MimicGen source demos, see each demo's timeline, annotate subtask ends by hand or
//! accept the proposals auto-detection makes and save them where MimicGen reads them; preview an
//! attempt over a new scene and try it; launch a run and watch it, its coverage and its failures.
//!
//! Architecture (as rerun's viewer and egui's demo app): an [`AppModel`] that only
//! [`AppModel::apply`] changes, from [`Command`]s the UI (or a test) sends; a backend behind a
//! [`Transport`] that does every file read, detection, simulation and write and answers with
//! serializable [`protocol::Reply`]s; drawing that reads the model and returns commands. A frame
//! never waits on disk or physics.
//!
//! What it does not do: read files or simulate. It has no native dependency and compiles for
//! `wasm32-unknown-unknown`; the backend is `mimicgen-backend`, which the desktop window
//! (`mimicgen-gui`) runs in-process and `mimicgen serve` (`mimicgen-server`) runs for browsers.
//!
//! ```
//! use mimicgen_ui::protocol::{Reply, Request};
//! use mimicgen_ui::{Command, MimicgenApp, Transport};
//!
//! /// A backend that answers nothing (a real one is a thread or a WebSocket).
//! struct Silent(Vec<Request>);
//! impl Transport for Silent {
//!     fn send(&mut self, request: Request) { self.0.push(request); }
//!     fn try_replies(&mut self) -> Vec<Reply> { Vec::new() }
//! }
//!
//! let mut app = MimicgenApp::new(Box::new(Silent(Vec::new())), None);
//! app.command(Command::Open("demos.hdf5".into()));
//! assert_eq!(app.model.in_flight, 1);
//! ```

pub mod annotation;
pub mod command;
pub mod coverage_ui;
pub mod doctor_ui;
pub mod model;
pub mod preview_ui;
pub mod protocol;
pub mod run_form_ui;
pub mod run_state;
pub mod run_ui;
pub mod style;
pub mod ui;

use std::path::PathBuf;

pub use egui;
pub use model::{AppModel, Command, Screen};

use crate::protocol::{Reply, Request};
use crate::ui::UiState;

/// The app's end of its backend: where requests go and replies come from. On the desktop a
/// thread in the same process (`mimicgen-gui`), in the browser a WebSocket to `mimicgen serve`
/// (`mimicgen-web`). Neither call may block.
pub trait Transport {
    /// Queues a request.
    fn send(&mut self, request: Request);
    /// The replies that have arrived.
    fn try_replies(&mut self) -> Vec<Reply>;
}

/// The app: its model, its backend and the UI's own fields.
pub struct MimicgenApp {
    /// The state (public so tests and the CLI can read it).
    pub model: AppModel,
    backend: Box<dyn Transport>,
    ui: UiState,
}

impl std::fmt::Debug for MimicgenApp {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("MimicgenApp").field("model", &self.model).finish_non_exhaustive()
    }
}

impl MimicgenApp {
    /// The app over `backend`; opens `file` if given.
    #[must_use]
    pub fn new(backend: Box<dyn Transport>, file: Option<PathBuf>) -> Self {
        let mut app = Self { model: AppModel::default(), backend, ui: UiState::default() };
        if let Some(file) = file {
            app.ui.open_path = file.display().to_string();
            app.command(Command::Open(file));
        }
        app
    }

    /// Applies a command and sends the backend what it needs.
    pub fn command(&mut self, command: Command) {
        if let Some(request) = self.model.apply(command) {
            self.backend.send(request);
        }
    }

    /// What the "save to" field holds.
    #[must_use]
    pub fn ui_save_path(&self) -> &str {
        &self.ui.save_path
    }

    /// Takes the backend's replies that have arrived. A backend that names a file to open when
    /// it greets the app (`mimicgen serve FILE`) gets it opened, unless one is open already.
    pub fn poll(&mut self) {
        for reply in self.backend.try_replies() {
            let open = match &reply {
                Reply::Welcome(welcome) if self.model.file.is_none() && self.model.in_flight == 0 => welcome.file.clone(),
                _ => None,
            };
            self.model.on_reply(reply);
            if let Some(file) = open {
                self.ui.open_path = file.display().to_string();
                self.command(Command::Open(file));
            }
        }
    }

    /// One frame: replies in, panels drawn, commands applied.
    pub fn show(&mut self, ui: &mut egui::Ui) {
        self.show_with(ui, None::<fn(&mut egui::Ui)>);
    }

    /// [`MimicgenApp::show`] beside a 3D view: the timeline (or the preview plots) moves to a
    /// bottom (or right) panel and `viewer` draws in the space left.
    pub fn show_with(&mut self, ui: &mut egui::Ui, viewer: Option<impl FnOnce(&mut egui::Ui)>) {
        self.poll();
        let ctx = ui.ctx().clone();
        let mut commands = Vec::new();
        ui::keys(&ctx, &mut commands);
        if let Some(path) = ctx.input(|i| i.raw.dropped_files.first().map(|f| f.path().to_path_buf())) {
            self.ui.open_path = path.display().to_string();
            commands.push(Command::Open(path));
        }
        if self.model.run.as_ref().is_some_and(model::RunState::running) {
            // Run updates arrive with a repaint; this keeps the ETA ticking between them.
            ctx.request_repaint_after(std::time::Duration::from_millis(250));
        }
        if self.model.playing {
            let now = ctx.input(|i| i.time);
            if now - self.ui.last_tick_s >= 0.05 {
                self.ui.last_tick_s = now;
                commands.push(Command::Tick);
            }
            ctx.request_repaint_after(std::time::Duration::from_millis(50));
        }
        egui::Panel::top("top").show(ui, |ui| ui::top_bar(ui, &self.model, &mut self.ui, &mut commands));
        ui::file_browser(&ctx, &self.model, &mut commands);
        match self.model.screen {
            Screen::Annotate => {
                egui::Panel::left("demos").default_size(220.0).show(ui, |ui| ui::demo_list(ui, &self.model, &mut commands));
                let beside = egui::Panel::bottom("timeline").default_size(360.0);
                main_area(ui, viewer, beside, |ui| ui::timeline(ui, &self.model, &mut self.ui, &mut commands));
            }
            Screen::Preview => {
                egui::Panel::left("preview").default_size(300.0).show(ui, |ui| preview_ui::controls(ui, &self.model, &mut commands));
                let beside = egui::Panel::right("views").default_size(520.0);
                main_area(ui, viewer, beside, |ui| preview_ui::views(ui, &self.model, &mut self.ui.preview, &mut commands));
            }
            Screen::Generate => {
                egui::Panel::left("run_form")
                    .default_size(300.0)
                    .show(ui, |ui| run_form_ui::form(ui, &self.model, &mut self.ui.run, &mut commands));
                // Beside the 3D view, at most 60 % of the height, however much the run shows.
                let beside = egui::Panel::bottom("run").default_size(420.0).max_size(0.6 * ctx.content_rect().height());
                main_area(ui, viewer, beside, |ui| run_ui::progress(ui, &self.model, &mut self.ui.run, &mut commands));
            }
        }
        for command in commands {
            if let Command::Open(path) = &command {
                self.ui.open_path = path.display().to_string();
            }
            self.command(command);
        }
    }
}

/// Draws a screen's main content: in the central area, or beside a 3D view in `beside` (a
/// resizable panel) with `viewer` drawing in the space left.
fn main_area(ui: &mut egui::Ui, viewer: Option<impl FnOnce(&mut egui::Ui)>, beside: egui::Panel, content: impl FnOnce(&mut egui::Ui)) {
    match viewer {
        Some(viewer) => {
            beside.resizable(true).show(ui, content);
            viewer(ui);
        }
        None => {
            egui::CentralPanel::default().show(ui, content);
        }
    }
}
