//! The inspection app, part 1: load MimicGen source demos, see each demo's timeline (gripper
//! command and finger opening, end-effector speed, distance to every object, the stored
//! signals), annotate subtask ends by hand or accept the proposals auto-detection makes, and save
//! them where MimicGen reads them.
//!
//! Architecture (as rerun's viewer and egui's demo app): an [`AppModel`] that only
//! [`AppModel::apply`] changes, from [`Command`]s the UI (or a test) sends; a backend thread that
//! does every file read, detection and write and answers with serializable [`protocol::Reply`]s;
//! drawing that reads the model and returns commands. A frame never waits on disk.
//! The preview screen plans an attempt over a new scene and tries it in simulation
//! ([`preview_ui`]). Not built yet: the 3D view (Rerun).
//!
//! ```no_run
//! mimicgen_gui::run(Some("core/io/tests/data/source_D0_prepared.hdf5".into())).ok();
//! ```

pub mod backend;
pub mod model;
pub mod preview_ui;
pub mod protocol;
pub mod ui;

use std::path::PathBuf;

pub use egui;
pub use model::{AppModel, Command, Screen};

use crate::backend::Backend;
use crate::ui::UiState;

/// The app: its model, its backend and the UI's own fields.
#[derive(Debug)]
pub struct MimicgenApp {
    /// The state (public so tests and the CLI can read it).
    pub model: AppModel,
    backend: Backend,
    ui: UiState,
}

impl MimicgenApp {
    /// Starts the backend (`repaint` is called when a reply arrives) and opens `file` if given.
    #[must_use]
    pub fn new(repaint: impl Fn() + Send + 'static, file: Option<PathBuf>) -> Self {
        let mut app = Self { model: AppModel::default(), backend: Backend::start(repaint), ui: UiState::default() };
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

    /// Takes the backend's replies that have arrived.
    pub fn poll(&mut self) {
        for reply in self.backend.try_replies() {
            self.model.on_reply(reply);
        }
    }

    /// One frame: replies in, panels drawn, commands applied.
    pub fn show(&mut self, ui: &mut egui::Ui) {
        self.poll();
        let ctx = ui.ctx().clone();
        let mut commands = Vec::new();
        ui::keys(&ctx, &mut commands);
        if let Some(path) = ctx.input(|i| i.raw.dropped_files.first().map(|f| f.path().to_path_buf())) {
            self.ui.open_path = path.display().to_string();
            commands.push(Command::Open(path));
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
        match self.model.screen {
            Screen::Annotate => {
                egui::Panel::left("demos").default_size(220.0).show(ui, |ui| ui::demo_list(ui, &self.model, &mut commands));
                egui::CentralPanel::default().show(ui, |ui| ui::timeline(ui, &self.model, &mut self.ui, &mut commands));
            }
            Screen::Preview => {
                egui::Panel::left("preview").default_size(300.0).show(ui, |ui| preview_ui::controls(ui, &self.model, &mut commands));
                egui::CentralPanel::default().show(ui, |ui| preview_ui::views(ui, &self.model));
            }
        }
        for command in commands {
            self.command(command);
        }
    }
}

impl eframe::App for MimicgenApp {
    fn ui(&mut self, ui: &mut egui::Ui, _frame: &mut eframe::Frame) {
        self.show(ui);
    }
}

/// Opens the app's window (with `file` loaded, if given) and runs until it is closed.
///
/// # Errors
/// eframe's error when no window can be opened (no display).
pub fn run(file: Option<PathBuf>) -> Result<(), eframe::Error> {
    let options = eframe::NativeOptions {
        viewport: egui::ViewportBuilder::default().with_inner_size([1280.0, 800.0]).with_drag_and_drop(true),
        ..eframe::NativeOptions::default()
    };
    eframe::run_native(
        "mimicgen",
        options,
        Box::new(move |cc| {
            let ctx = cc.egui_ctx.clone();
            Ok(Box::new(MimicgenApp::new(move || ctx.request_repaint(), file)))
        }),
    )
}
