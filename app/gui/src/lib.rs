//! The inspection app in a desktop window: the UI of `mimicgen-ui` over the backend of
//! `mimicgen-backend` running on a thread of the same process, with (cargo feature `viewer`) the
//! Rerun viewer embedded in the window. The same UI runs in a browser against `mimicgen serve`.
//!
//! ```no_run
//! let options = mimicgen_gui::RunOptions { file: Some("core/io/tests/data/source_D0_prepared.hdf5".into()), ..Default::default() };
//! mimicgen_gui::run(options).ok();
//! ```

#[cfg(feature = "viewer")]
mod embedded;

use std::path::PathBuf;

pub use mimicgen_backend as backend;
pub use mimicgen_ui::{AppModel, Command, MimicgenApp, Screen, Transport, egui, model, preview_ui, protocol, run_ui, ui};

/// The app over a backend thread of this process (`repaint` is called when a reply arrives),
/// opening `file` if given; [`protocol::ViewerSink::Embedded`] 3D view streams come from
/// `embedded` (the viewer in the app's window); with `vet`, each file a request names is read in
/// that child process first (a file that crashes the HDF5 library is refused, the app goes on).
#[must_use]
pub fn desktop(
    repaint: impl Fn() + Send + Sync + 'static,
    file: Option<PathBuf>,
    embedded: Option<backend::StreamFactory>,
    vet: Option<backend::Vetter>,
) -> MimicgenApp {
    MimicgenApp::new(Box::new(backend::Backend::start_vetted(repaint, embedded, vet)), file)
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
    /// The task variant the preview and the run draw scenes from (`None`: the source file's).
    pub variant: Option<String>,
    /// Spec fields set over the task spec's, in the run form (so in the preview and the run).
    pub spec: model::SpecOverrides,
    /// The run's arm (`ur5e`; the source demos' when `None`).
    pub robot: Option<String>,
    /// Render robomimic's two cameras into the run's dataset.
    pub cameras: bool,
    /// Once the run has ended, select this attempt (the 3D view stays on it) and, for a failed
    /// one, show it beside the nearest success.
    pub attempt: Option<u64>,
    /// Once the run has ended, diagnose it (`mimicgen doctor`) with this budget of attempts.
    pub doctor: Option<usize>,
    /// Once everything asked for is shown, save the window to this PNG and close.
    pub screenshot: Option<PathBuf>,
    /// Read each file a request names in this child process first (`mimicgen app` sets
    /// `mimicgen vet`).
    pub vet: Option<backend::Vetter>,
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
        // Before the screen: showing the preview copies the form's variant and spec fields.
        let form = model::RunForm { variant: options.variant.clone(), spec: options.spec.clone(), ..model::RunForm::default() };
        if form.variant.is_some() || form.spec != model::SpecOverrides::default() {
            steps.push(Command::SetRunForm(Box::new(form.clone())));
        }
        if options.screen != Screen::Annotate {
            steps.push(Command::Show(options.screen));
        }
        if options.try_it {
            steps.push(Command::TryIt);
        }
        if let Some(attempts) = options.run {
            steps.push(Command::Show(Screen::Generate));
            steps.push(Command::SetRunForm(Box::new(model::RunForm {
                attempts,
                overwrite: true,
                robot: options.robot.clone(),
                cameras: options.cameras.then(model::CameraConfig::default),
                ..form
            })));
            steps.push(Command::StartRun);
        }
        if let Some(k) = options.attempt {
            steps.push(Command::SelectAttempt(k));
            steps.push(Command::SideBySide { failed: k, success: None });
        }
        if let Some(budget) = options.doctor {
            steps.push(Command::SetDoctor { budget, top: 3 });
            steps.push(Command::Diagnose);
        }
        steps.reverse();
        Self { app, steps, screenshot: options.screenshot.clone(), idle_frames: 0, shot_requested: false }
    }

    /// Takes the next start-up step once the backend is idle; then the screenshot, if asked for.
    fn script(&mut self, ctx: &egui::Context) {
        let running = self.app.model.run.as_ref().is_some_and(model::RunState::running) || self.app.model.doctor.running;
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
            let app = desktop(move || ctx.request_repaint(), options.file.clone(), None, options.vet.clone());
            Ok(Box::new(Window::new(app, &options)))
        }),
    )
}
