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
//! let options = mimicgen_gui::RunOptions { file: Some("core/io/tests/data/source_D0_prepared.hdf5".into()), ..Default::default() };
//! mimicgen_gui::run(options).ok();
//! ```

pub mod backend;
#[cfg(feature = "viewer")]
mod embedded;
pub mod model;
pub mod preview_ui;
pub mod protocol;
pub mod run_ui;
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
    pub fn new(repaint: impl Fn() + Send + Sync + 'static, file: Option<PathBuf>) -> Self {
        Self::with_streams(repaint, file, None)
    }

    /// [`MimicgenApp::new`] whose [`protocol::ViewerSink::Embedded`] 3D view streams come from
    /// `embedded` (the viewer in the app's window).
    #[must_use]
    pub fn with_streams(
        repaint: impl Fn() + Send + Sync + 'static,
        file: Option<PathBuf>,
        embedded: Option<backend::StreamFactory>,
    ) -> Self {
        let mut app = Self { model: AppModel::default(), backend: Backend::start(repaint, embedded), ui: UiState::default() };
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
                main_area(ui, viewer, beside, |ui| preview_ui::views(ui, &self.model, &mut self.ui, &mut commands));
            }
            Screen::Generate => {
                egui::Panel::left("run_form").default_size(300.0).show(ui, |ui| run_ui::form(ui, &self.model, &mut self.ui, &mut commands));
                // Beside the 3D view, at most 60 % of the height, however much the run shows.
                let beside = egui::Panel::bottom("run").default_size(420.0).max_size(0.6 * ctx.content_rect().height());
                main_area(ui, viewer, beside, |ui| run_ui::progress(ui, &self.model, &mut self.ui, &mut commands));
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

/// How the window starts: what to open and show, and (for the docs) a screenshot to take.
#[derive(Debug, Clone, Default)]
pub struct RunOptions {
    /// The file to open.
    pub file: Option<PathBuf>,
    /// The screen to show once it is open.
    pub screen: Screen,
    /// The demo to show.
    pub demo: Option<usize>,
    /// The step to put the time cursor at.
    pub step: Option<usize>,
    /// Run "try it" on the preview screen.
    pub try_it: bool,
    /// Start a run of this many attempts (to `out/app_run.hdf5`, replacing it) on the generate
    /// screen.
    pub run: Option<usize>,
    /// Once the run has ended, select this attempt (the 3D view stays on it) and, for a failed
    /// one, show it beside the nearest success.
    pub attempt: Option<u64>,
    /// Once everything asked for is shown, save the window to this PNG and close.
    pub screenshot: Option<PathBuf>,
}

/// The app in its window, with the start-up steps of [`RunOptions`] still to do.
struct Window {
    app: MimicgenApp,
    steps: Vec<Command>,
    screenshot: Option<PathBuf>,
    idle_frames: usize,
    shot_requested: bool,
}

impl Window {
    fn new(app: MimicgenApp, options: &RunOptions) -> Self {
        let mut steps = Vec::new();
        if let Some(d) = options.demo {
            steps.push(Command::SelectDemo(d));
        }
        if let Some(t) = options.step {
            steps.push(Command::SetCursor(t));
        }
        if options.screen != Screen::Annotate {
            steps.push(Command::Show(options.screen));
        }
        if options.try_it {
            steps.push(Command::TryIt);
        }
        if let Some(attempts) = options.run {
            steps.push(Command::Show(Screen::Generate));
            steps.push(Command::SetRunForm(model::RunForm { attempts, overwrite: true, ..model::RunForm::default() }));
            steps.push(Command::StartRun);
        }
        if let Some(k) = options.attempt {
            steps.push(Command::SelectAttempt(k));
            steps.push(Command::SideBySide { failed: k, success: None });
        }
        steps.reverse();
        Self { app, steps, screenshot: options.screenshot.clone(), idle_frames: 0, shot_requested: false }
    }

    /// Takes the next start-up step once the backend is idle; then the screenshot, if asked for.
    fn script(&mut self, ctx: &egui::Context) {
        let running = self.app.model.run.as_ref().is_some_and(model::RunState::running);
        if self.app.model.in_flight > 0 || self.app.model.file.is_none() || running {
            self.idle_frames = 0;
            ctx.request_repaint();
            return;
        }
        if let Some(step) = self.steps.pop() {
            self.app.command(step);
            ctx.request_repaint();
            return;
        }
        let Some(path) = self.screenshot.clone() else { return };
        self.idle_frames += 1;
        ctx.request_repaint();
        if self.idle_frames == 10 && !self.shot_requested {
            self.shot_requested = true;
            ctx.send_viewport_cmd(egui::ViewportCommand::Screenshot(egui::UserData::default()));
        }
        let shot = ctx.input(|i| {
            i.raw.events.iter().find_map(|e| match e {
                egui::Event::Screenshot { image, .. } => Some(std::sync::Arc::clone(image)),
                _ => None,
            })
        });
        if let Some(image) = shot {
            let [w, h] = image.size;
            let bytes: Vec<u8> = image.pixels.iter().flat_map(egui::Color32::to_array).collect();
            #[allow(clippy::cast_possible_truncation)]
            let saved = image::save_buffer(&path, &bytes, w as u32, h as u32, image::ExtendedColorType::Rgba8);
            match saved {
                Ok(()) => eprintln!("saved {}", path.display()),
                Err(e) => eprintln!("cannot save {}: {e}", path.display()),
            }
            ctx.send_viewport_cmd(egui::ViewportCommand::Close);
        }
    }
}

impl eframe::App for Window {
    fn ui(&mut self, ui: &mut egui::Ui, _frame: &mut eframe::Frame) {
        let ctx = ui.ctx().clone();
        self.app.show(ui);
        self.script(&ctx);
    }
}

impl eframe::App for MimicgenApp {
    fn ui(&mut self, ui: &mut egui::Ui, _frame: &mut eframe::Frame) {
        self.show(ui);
    }
}

/// Opens the app's window as `options` say and runs until it is closed. With the `viewer` feature
/// the Rerun viewer is embedded in the window (and the 3D view opens by itself).
///
/// # Errors
/// eframe's error when no window can be opened (no display).
pub fn run(options: RunOptions) -> Result<(), eframe::Error> {
    #[cfg(feature = "viewer")]
    return embedded::run(options);
    #[cfg(not(feature = "viewer"))]
    run_plain(options)
}

#[cfg_attr(feature = "viewer", allow(dead_code))]
fn run_plain(options: RunOptions) -> Result<(), eframe::Error> {
    let native = eframe::NativeOptions {
        viewport: egui::ViewportBuilder::default().with_inner_size([1280.0, 800.0]).with_drag_and_drop(true),
        ..eframe::NativeOptions::default()
    };
    eframe::run_native(
        "mimicgen",
        native,
        Box::new(move |cc| {
            let ctx = cc.egui_ctx.clone();
            let app = MimicgenApp::new(move || ctx.request_repaint(), options.file.clone());
            Ok(Box::new(Window::new(app, &options)))
        }),
    )
}
