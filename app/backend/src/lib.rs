//! The inspection app's backend: a [`Worker`] that reads, detects, writes, plans and tries
//! attempts and runs generation, answering the UI's requests (`mimicgen_ui::protocol`).
//! [`Backend`] runs it on a named thread of the app's own process (the desktop window); `mimicgen
//! serve` runs one for the browsers that connect to it. The UI never waits on it.
//!
//! What it does not do: draw, or decide which paths a request may touch (the server confines
//! them to its root before they get here).

use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, Sender, channel};
use std::sync::{Mutex, PoisonError};

use mimicgen_engine::image::{ImageStream, Pixels};
use mimicgen_engine::{Attempt, Overrides, Plan, RunStats};
use mimicgen_pipeline::annotate::Annotations;
use mimicgen_pipeline::preview::Previewer;
use mimicgen_pipeline::{PipelineError, RunConfig, annotate};
use mimicgen_viz::rerun::RecordingStream;
use mimicgen_viz::{LogConfig, RunLogger, SceneLevel, Sink};

use mimicgen_ui::protocol::{CameraView, DoctorUpdate, PreviewRequest, PreviewView, Reply, Request, ViewerSink, Welcome};

mod files;
mod runs;
pub mod vet;
mod views;

use files::read_images;
pub use files::{list_dir, open};
pub use mimicgen_pipeline::prepare::prepared_dir;
use runs::run_generation;
pub use runs::{open_run, read_run};
pub use vet::Vetter;
use views::{preview_failed, preview_view};

/// Makes a recording stream that feeds the viewer embedded in the app's window.
pub type StreamFactory = Arc<dyn Fn() -> Result<RecordingStream, String> + Send + Sync>;

/// Sends a reply to the UI (and asks for a repaint), from any thread.
pub type Notify = Arc<dyn Fn(Reply) + Send + Sync>;

/// `answer()`, or when it panics, a [`Reply::Failed`] saying so under `what` (the request as the
/// user made it): a bug in one request is reported where it was made, and the backend goes on.
pub fn guarded(what: String, answer: impl FnOnce() -> Reply) -> Reply {
    match std::panic::catch_unwind(std::panic::AssertUnwindSafe(answer)) {
        Ok(reply) => reply,
        Err(panic) => {
            let message = panic
                .downcast_ref::<&str>()
                .map(|s| (*s).to_owned())
                .or_else(|| panic.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "a panic".to_owned());
            eprintln!("mimicgen backend: {what}: {message}");
            Reply::Failed { what, error: format!("internal error (a bug; please report it): {message}") }
        }
    }
}

/// The arms a run can use, as `--robot` names them.
#[must_use]
pub fn robots() -> Vec<String> {
    mimicgen_sim::robot::ROBOTS.iter().map(|r| r.name.to_owned()).collect()
}

/// The generation run a worker starts, watches and cancels. A worker makes its own; the server's
/// tabs' workers share one (a run belongs to the server: any tab may watch or cancel it).
#[derive(Clone, Default)]
pub struct RunSlot(Arc<Mutex<Option<RunThread>>>);

/// A run's cancel flag and thread.
type RunThread = (Arc<AtomicBool>, std::thread::JoinHandle<()>);

impl std::fmt::Debug for RunSlot {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RunSlot").field("running", &self.running()).finish()
    }
}

impl RunSlot {
    fn lock(&self) -> std::sync::MutexGuard<'_, Option<RunThread>> {
        self.0.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// Whether a run is going.
    #[must_use]
    pub fn running(&self) -> bool {
        self.lock().as_ref().is_some_and(|(_, thread)| !thread.is_finished())
    }
}

/// The backend's state: the open file's demos and scene (for the 3D view), the previewer of the
/// last previewed file (kept so that moving through scenes does not recompile the scene), and the
/// Rerun stream once the 3D view is open.
pub struct Worker {
    loaded: Option<Annotations>,
    /// The open file (for a plain robomimic file, its prepared copy).
    loaded_path: Option<PathBuf>,
    /// The open file is a two-arm one (annotated per arm, previews tried, runs; no 3D view yet).
    two_arm: bool,
    previewer: Option<(RunConfig, Previewer)>,
    viewer: Option<(ViewerSink, RunLogger)>,
    embedded: Option<StreamFactory>,
    notify: Notify,
    /// Where a run's updates go (all its watchers), from the run's own thread.
    run_notify: Notify,
    /// The running generation's cancel flag and thread.
    run: RunSlot,
    /// The running doctor's cancel flag and thread (this worker's own: a tab's diagnosis).
    doctor: Option<RunThread>,
    /// Reads each user-chosen file in a child process first, when set.
    vetter: Option<Vetter>,
}

impl std::fmt::Debug for Worker {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Worker").field("previewer", &self.previewer).field("embedded", &self.embedded.is_some()).finish_non_exhaustive()
    }
}

fn viz_error(e: &mimicgen_viz::VizError) -> String {
    e.to_string()
}

impl Worker {
    /// A worker that sends progress and run updates to `notify` and whose
    /// [`ViewerSink::Embedded`] streams come from `embedded`.
    #[must_use]
    pub fn new(notify: Notify, embedded: Option<StreamFactory>) -> Self {
        let run_notify = Arc::clone(&notify);
        Self {
            loaded: None,
            loaded_path: None,
            two_arm: false,
            previewer: None,
            viewer: None,
            embedded,
            notify,
            run_notify,
            run: RunSlot::default(),
            doctor: None,
            vetter: None,
        }
    }

    /// Sends the updates of runs started from now on to `notify` instead (every tab watching).
    #[must_use]
    pub fn with_run_notify(self, notify: Notify) -> Self {
        Self { run_notify: notify, ..self }
    }

    /// Starts, watches and cancels runs in `slot` (shared with other workers) instead of its own.
    #[must_use]
    pub fn with_run_slot(self, slot: RunSlot) -> Self {
        Self { run: slot, ..self }
    }

    /// Reads every file a request names in a child process first (see [`vet`]): a file that
    /// crashes the HDF5 library is refused, naming it, and this process goes on.
    #[must_use]
    pub fn with_vetter(self, vetter: Option<Vetter>) -> Self {
        Self { vetter, ..self }
    }

    /// Whether a run is going.
    #[must_use]
    pub fn running(&self) -> bool {
        self.run.running()
    }

    /// Answers one request; a panic while answering is caught and answered as a failure (the
    /// worker and the app go on), and so is a file that crashes its reader in the vetting child.
    pub fn handle_guarded(&mut self, request: Request) -> Reply {
        let what: String = format!("answering {request:?}").chars().take(100).collect();
        if let Some(vetter) = &self.vetter
            && let Err(error) = vetter.check_request(&request)
        {
            return Reply::Failed { what: "reading the file".to_owned(), error };
        }
        guarded(what, || self.handle(request))
    }

    /// Starts `mimicgen doctor` on its own thread; its updates go to this worker's `notify`.
    fn start_doctor(&mut self, run: PathBuf, budget: usize, top: usize) -> Reply {
        if self.doctor.as_ref().is_some_and(|(_, thread)| !thread.is_finished()) {
            return Reply::Failed {
                what: "starting the doctor".to_owned(),
                error: "the doctor is at work; stop it or wait for it".to_owned(),
            };
        }
        let cancel = Arc::new(AtomicBool::new(false));
        let (flag, notify) = (Arc::clone(&cancel), Arc::clone(&self.notify));
        let workers = std::thread::available_parallelism().map_or(1, std::num::NonZero::get);
        let config = mimicgen_pipeline::doctor::DoctorConfig { run, budget, top, workers, check: 0 };
        let spawned = std::thread::Builder::new().name("mimicgen-gui-doctor".to_owned()).spawn(move || {
            let on_event = |event: &mimicgen_pipeline::doctor::DoctorEvent| {
                use mimicgen_pipeline::doctor::DoctorEvent;
                notify(Reply::Doctor(match event {
                    DoctorEvent::Started { suggestions, arms, attempts } => {
                        DoctorUpdate::Started { suggestions: suggestions.clone(), arms: *arms, attempts: *attempts }
                    }
                    DoctorEvent::Attempt { arm, done, successes } => {
                        DoctorUpdate::Attempt { arm: *arm, done: *done, successes: *successes }
                    }
                    DoctorEvent::Checking { .. } => return,
                }));
            };
            let update = match mimicgen_pipeline::doctor::doctor(&config, &flag, on_event) {
                Ok(diagnosis) => DoctorUpdate::Finished(Box::new(diagnosis)),
                Err(e) => DoctorUpdate::Failed(e.worded(mimicgen_pipeline::FrontEnd::App)),
            };
            notify(Reply::Doctor(update));
        });
        match spawned {
            Ok(thread) => {
                self.doctor = Some((cancel, thread));
                Reply::DoctorAccepted
            }
            Err(e) => Reply::Failed { what: "starting the doctor".to_owned(), error: e.to_string() },
        }
    }

    fn start_run(&mut self, config: RunConfig) -> Reply {
        let slot = self.run.clone();
        let mut run = slot.lock();
        if run.as_ref().is_some_and(|(_, thread)| !thread.is_finished()) {
            return Reply::Failed {
                what: "starting a run".to_owned(),
                error: "a run is going; cancel it or wait for it to end".to_owned(),
            };
        }
        let cancel = Arc::new(AtomicBool::new(false));
        let (flag, notify) = (Arc::clone(&cancel), Arc::clone(&self.run_notify));
        let job: Box<dyn FnOnce() + Send> = if self.two_arm {
            Box::new(move || runs::run_two_arm_generation(&config, &flag, &notify))
        } else {
            // The run's own recording (its attempts on the `attempt` and `frame` timelines): a new
            // recording in the embedded viewer or the spawned one, `<file>_run.rrd` beside a saved one.
            let logger = match self.viewer.as_ref().map(|(sink, _)| sink.clone()) {
                Some(ViewerSink::Save(path)) => self.logger(&ViewerSink::Save(mimicgen_pipeline::sibling(&path, "_run", "rrd"))).ok(),
                Some(sink) => self.logger(&sink).ok(),
                None => None,
            };
            Box::new(move || run_generation(&config, &flag, &notify, logger))
        };
        match std::thread::Builder::new().name("mimicgen-gui-run".to_owned()).spawn(job) {
            Ok(thread) => {
                *run = Some((cancel, thread));
                Reply::RunAccepted
            }
            Err(e) => Reply::Failed { what: "starting a run".to_owned(), error: e.to_string() },
        }
    }

    /// A logger on a new stream to `sink`.
    fn logger(&self, sink: &ViewerSink) -> Result<RunLogger, String> {
        let loaded = self.loaded.as_ref().ok_or("open a file first")?;
        let rec = match sink {
            ViewerSink::Spawn => Sink::Spawn.open("mimicgen").map_err(|e| viz_error(&e))?,
            ViewerSink::Connect(url) => Sink::Connect(url.clone()).open("mimicgen").map_err(|e| viz_error(&e))?,
            ViewerSink::Save(path) => Sink::Save(path.clone()).open("mimicgen").map_err(|e| viz_error(&e))?,
            ViewerSink::Embedded => {
                let make = self.embedded.as_ref().ok_or("this build has no embedded viewer (build with `--features viewer`)")?;
                let rec = make()?;
                rec.send_blueprint_opts(&mimicgen_viz::rerun::blueprint::BlueprintOpts {
                    blueprint: mimicgen_viz::app_blueprint(),
                    activation: mimicgen_viz::rerun::blueprint::BlueprintActivation { make_active: true, make_default: true },
                })
                .map_err(|e| e.to_string())?;
                rec
            }
        };
        let config = LogConfig { scene: SceneLevel::All, scene_stride: 1 };
        RunLogger::new(rec, &loaded.scene, config).map_err(|e| viz_error(&e))
    }

    /// The logger to show something new with: the open stream, or for the embedded viewer a new
    /// recording (so every demo and attempt starts at step 0 of its own).
    fn fresh_logger(&mut self) -> Result<&mut RunLogger, String> {
        let Some((sink, _)) = &self.viewer else { return Err("the 3D view is not open".to_owned()) };
        if *sink == ViewerSink::Embedded {
            let logger = self.logger(sink)?;
            if let Some((_, old)) = &mut self.viewer {
                *old = logger;
            }
        }
        self.viewer.as_mut().map(|(_, l)| l).ok_or_else(|| "the 3D view is not open".to_owned())
    }

    fn open_3d(&mut self, sink: ViewerSink, demo: usize) -> Result<String, String> {
        let logger = self.logger(&sink)?;
        let said = match &sink {
            ViewerSink::Spawn => "the Rerun viewer".to_owned(),
            ViewerSink::Connect(url) => url.clone(),
            ViewerSink::Save(path) => path.display().to_string(),
            ViewerSink::Embedded => "the viewer in this window".to_owned(),
        };
        self.viewer = Some((sink, logger));
        self.show_3d(demo, &self.images(demo))?;
        Ok(said)
    }

    /// Demo `demo`'s camera images in the open file (none for a file without cameras, or when
    /// they cannot be read: the timeline works without).
    fn images(&self, demo: usize) -> Vec<CameraView> {
        self.loaded_path.as_deref().map(|path| read_images(path, demo)).unwrap_or_default()
    }

    fn show_3d(&mut self, demo: usize, images: &[CameraView]) -> Result<String, String> {
        self.fresh_logger()?;
        let (Some(loaded), Some((_, logger))) = (&self.loaded, &mut self.viewer) else { return Err("the 3D view is not open".to_owned()) };
        let source = loaded.sources.demos.get(demo).ok_or_else(|| format!("there is no demo {demo}"))?;
        logger.log_demos([(demo, source)]).map_err(|e| viz_error(&e))?;
        let streams = images
            .iter()
            .map(|c| {
                let stream = ImageStream { shape: [c.height, c.width, 3], pixels: Pixels::Rgb(c.rgb.clone()) };
                (format!("{}_image", c.name), stream)
            })
            .collect();
        logger.log_demo_images(demo, &streams).map_err(|e| viz_error(&e))?;
        logger.stream().flush_blocking().map_err(|e| e.to_string())?;
        Ok(format!("{} in 3D", source.name))
    }

    /// Logs a planned attempt to the 3D view, if it is open.
    fn show_plan_3d(&mut self, plan: &Plan) -> Result<(), String> {
        if self.viewer.is_none() {
            return Ok(());
        }
        let logger = self.fresh_logger()?;
        logger.log_plan(plan).map_err(|e| viz_error(&e))?;
        logger.stream().flush_blocking().map_err(|e| e.to_string())
    }

    /// Logs a tried attempt to the 3D view, if it is open.
    fn show_attempt_3d(&mut self, attempt: &Attempt) -> Result<(), String> {
        if self.viewer.is_none() {
            return Ok(());
        }
        let num_demos = self.loaded.as_ref().map_or(0, |l| l.sources.demos.len());
        let logger = self.fresh_logger()?;
        let mut stats = RunStats::new(num_demos);
        stats.record(attempt);
        logger.log_attempt(attempt, &stats).map_err(|e| viz_error(&e))?;
        logger.stream().flush_blocking().map_err(|e| e.to_string())
    }

    fn preview(&mut self, request: &PreviewRequest) -> Result<PreviewView, PipelineError> {
        // What the previewer is made from; the ends and seed it takes without rebuilding.
        let config = RunConfig {
            source: Some(request.source.clone()),
            variant: request.variant.clone(),
            spec: request.spec.clone(),
            ..RunConfig::default()
        };
        let previewer = match &mut self.previewer {
            Some((made_from, previewer)) if *made_from == config => previewer,
            slot => {
                let previewer = Previewer::new(&config, &request.marks)?;
                &mut slot.insert((config, previewer)).1
            }
        };
        previewer.configure(&request.marks, request.seed)?;
        let mut overrides = Overrides { sources: request.sources.clone(), ..Overrides::default() };
        if !request.moved.is_empty() {
            let sampled = previewer.plan(request.index, &overrides)?.initial_object_poses;
            for (name, [x, y]) in &request.moved {
                let mut pose = *sampled.get(name).ok_or_else(|| PipelineError::Engine {
                    file: "preview".to_owned(),
                    source: mimicgen_engine::EngineError::UnknownName {
                        field: "moved object".to_owned(),
                        name: name.clone(),
                        available: sampled.keys().cloned().collect(),
                    },
                })?;
                pose.translation.vector.x = *x;
                pose.translation.vector.y = *y;
                overrides.object_poses.insert(name.clone(), pose);
            }
        }
        let plan = previewer.plan(request.index, &overrides)?;
        let executed = if request.execute { Some(previewer.try_attempt(request.index, &overrides)?) } else { None };
        let view = preview_view(previewer, &plan, executed.as_ref());
        let shown = match &executed {
            Some(attempt) => self.show_attempt_3d(attempt),
            None => self.show_plan_3d(&plan),
        };
        match shown {
            Ok(()) => Ok(view),
            Err(e) => Ok(PreviewView { failure_3d: Some(e), ..view }),
        }
    }

    /// Answers one request.
    pub fn handle(&mut self, request: Request) -> Reply {
        if self.two_arm
            && let Some(what) = match &request {
                Request::SideBySide(_) => Some("comparing two attempts"),
                Request::Open3d { .. } | Request::ShowDemo { in_3d: true, .. } => Some("the 3D view"),
                _ => None,
            }
        {
            return Reply::Failed {
                what: what.to_owned(),
                error: "the open file is a two-arm one: the app annotates its arms, tries attempts and runs generation; side by side and the 3D view are one-arm only so far (`mimicgen generate --task two_arm_lift --rerun run.rrd` shows two arms in Rerun)".to_owned(),
            };
        }
        match request {
            Request::Run(config) => self.start_run(*config),
            Request::ListDir { path } => match list_dir(&path) {
                Ok(listing) => Reply::Listing(Box::new(listing)),
                Err(e) => Reply::Failed { what: format!("listing {}", path.display()), error: e.to_string() },
            },
            Request::OpenCompare { path } => match read_run(&path) {
                Ok(run) => Reply::Compared(Box::new(run)),
                Err(e) => Reply::Failed { what: format!("opening {} to compare", path.display()), error: e.to_string() },
            },
            Request::OpenRun { path } => match open_run(&path, &self.notify) {
                Ok(()) => Reply::RunOpened,
                Err(e) => Reply::Failed { what: format!("opening the run {}", path.display()), error: e.to_string() },
            },
            Request::Doctor { run, budget, top } => self.start_doctor(run, budget, top),
            Request::CancelDoctor => {
                if let Some((cancel, _)) = &self.doctor {
                    cancel.store(true, Ordering::Relaxed);
                }
                Reply::Cancelling
            }
            Request::CancelRun => {
                if let Some((cancel, _)) = self.run.lock().as_ref() {
                    cancel.store(true, Ordering::Relaxed);
                }
                Reply::Cancelling
            }
            Request::Open { path } => match open(&path, &*Arc::clone(&self.notify)) {
                Ok((reply, found)) => {
                    self.loaded = Some(found);
                    self.two_arm = matches!(&reply, Reply::Opened(file) if !file.arms.is_empty());
                    // The stream's static scene is the old file's: a new file needs a new stream.
                    self.viewer = None;
                    if let Reply::Opened(file) = &reply {
                        self.loaded_path = Some(file.path.clone());
                        // Before `Opened`: the model drops images when asked to open a file.
                        (self.notify)(Reply::Images { demo: 0, cameras: self.images(0) });
                    }
                    reply
                }
                Err(e) => Reply::Failed { what: format!("opening {}", path.display()), error: e.to_string() },
            },
            Request::SaveArms { source, out, arms, overwrite } => {
                if let Some(refused) = refuse_output(&source, &out, overwrite) {
                    return refused;
                }
                let arms: Vec<annotate::ArmEnds> = arms.into_iter().map(|a| (a.signal_names, a.ends)).collect();
                match annotate::write_arm_signals(&source, &out, &arms) {
                    Ok(()) => Reply::Saved { out, demos: arms.first().map_or(0, |(_, ends)| ends.len()) },
                    Err(e) => Reply::Failed { what: format!("saving {}", out.display()), error: e.to_string() },
                }
            }
            Request::Save { source, out, marks, signal_names, overwrite } => {
                if let Some(refused) = refuse_output(&source, &out, overwrite) {
                    return refused;
                }
                match annotate::write_signals(&source, &out, &signal_names, &marks.ends, &marks.starts) {
                    Ok(()) => Reply::Saved { out, demos: marks.ends.len() },
                    Err(e) => Reply::Failed { what: format!("saving {}", out.display()), error: e.to_string() },
                }
            }
            Request::Open3d { sink, demo } => match self.open_3d(sink, demo) {
                Ok(to) => Reply::Streaming { to },
                Err(error) => Reply::Failed { what: "opening the 3D view".to_owned(), error },
            },
            Request::ShowDemo { demo, in_3d } => {
                let cameras = self.images(demo);
                (self.notify)(Reply::Images { demo, cameras: cameras.clone() });
                if !in_3d {
                    return Reply::Shown { what: format!("demo {demo}") };
                }
                match self.show_3d(demo, &cameras) {
                    Ok(what) => Reply::Shown { what },
                    Err(error) => Reply::Failed { what: format!("showing demo {demo} in 3D"), error },
                }
            }
            Request::Preview(request) if self.two_arm => match self.loaded_path.clone().map(|path| two_arm_preview(&path, &request)) {
                Some(Ok(view)) => Reply::Previewed(Box::new(view)),
                Some(Err(e)) => preview_failed(&request, &e),
                None => Reply::Failed { what: "trying an attempt".to_owned(), error: "open a file first".to_owned() },
            },
            Request::Preview(request) => match self.preview(&request) {
                Ok(view) => Reply::Previewed(Box::new(view)),
                Err(e) => preview_failed(&request, &e),
            },
            Request::SideBySide(pair) => {
                let [a, b] = *pair;
                // The failure (`a`) last, so that it is what the 3D view shows.
                let shown_b = self.preview(&b);
                match (self.preview(&a), shown_b) {
                    (Ok(a), Ok(b)) => Reply::SideBySide(Box::new([a, b])),
                    (Err(e), _) => preview_failed(&a, &e),
                    (_, Err(e)) => preview_failed(&b, &e),
                }
            }
        }
    }
}

/// The UI's end of the backend.
#[derive(Debug)]
pub struct Backend {
    requests: Sender<Request>,
    replies: Receiver<Reply>,
}

impl Backend {
    /// Starts the worker thread; `repaint` is called after every reply.
    ///
    /// # Panics
    /// Never on purpose; if the OS cannot start a thread, replies report it.
    #[must_use]
    pub fn start(repaint: impl Fn() + Send + Sync + 'static, embedded: Option<StreamFactory>) -> Self {
        Self::start_vetted(repaint, embedded, None)
    }

    /// [`Backend::start`], reading each file a request names in a `vetter` child first (see
    /// [`vet`]): a file that crashes the HDF5 library is refused, and the app goes on.
    ///
    /// # Panics
    /// Never on purpose; if the OS cannot start a thread, replies report it.
    #[must_use]
    pub fn start_vetted(repaint: impl Fn() + Send + Sync + 'static, embedded: Option<StreamFactory>, vetter: Option<Vetter>) -> Self {
        let (requests, inbox) = channel::<Request>();
        let (outbox, replies) = channel::<Reply>();
        let failed = outbox.clone();
        let repaint = Arc::new(repaint);
        let notify: Notify = {
            let (outbox, repaint) = (std::sync::Mutex::new(outbox.clone()), Arc::clone(&repaint));
            Arc::new(move |reply| {
                if let Ok(outbox) = outbox.lock() {
                    let _ = outbox.send(reply);
                }
                repaint();
            })
        };
        let spawned = std::thread::Builder::new().name("mimicgen-gui-backend".to_owned()).spawn(move || {
            let cores = std::thread::available_parallelism().map_or(1, std::num::NonZero::get);
            notify(Reply::Welcome(Box::new(Welcome { cores, robots: robots(), ..Welcome::default() })));
            let mut worker = Worker::new(notify, embedded).with_vetter(vetter);
            for request in inbox {
                let reply = worker.handle_guarded(request);
                if outbox.send(reply).is_err() {
                    break;
                }
                repaint();
            }
        });
        if let Err(e) = spawned {
            let _ = failed.send(Reply::Failed { what: "starting the backend thread".to_owned(), error: e.to_string() });
        }
        Self { requests, replies }
    }
}

impl mimicgen_ui::Transport for Backend {
    fn send(&mut self, request: Request) {
        let _ = self.requests.send(request);
    }

    fn try_replies(&mut self) -> Vec<Reply> {
        self.replies.try_iter().collect()
    }
}

/// Tries attempt `request.index` of a two-arm file at `path` with each arm's ends
/// (`request.arm_ends`), seed and variant: the attempt as the two-arm generator runs it.
fn two_arm_preview(path: &std::path::Path, request: &PreviewRequest) -> Result<PreviewView, PipelineError> {
    use mimicgen_sim::two_arm::{TwoArmSimEnv, TwoArmTask};
    let task = files::two_arm_task(path).ok_or_else(|| PipelineError::Input {
        file: path.display().to_string(),
        field: "data attribute env_args".to_owned(),
        reason: "names no two-arm task".to_owned(),
    })?;
    let variant = request.variant.clone().unwrap_or_else(|| "D0".to_owned());
    let variant = if task.variants().contains(&variant.as_str()) { variant } else { "D0".to_owned() };
    let file = mimicgen_io::RobomimicDataset::open(path)?;
    let mut views = file.to_arm_source_datasets(&mimicgen_engine::spec::SourceSelection::default(), &mimicgen_pipeline::two_arm::ARMS)?;
    for (view, ends) in views.iter_mut().zip(&request.arm_ends) {
        for demo in &mut view.demos {
            if let Some(e) = ends.get(&demo.name) {
                demo.manual_subtask_ends = Some(e.clone());
            }
        }
    }
    let mut spec = task.spec().map_err(|e| PipelineError::Engine { file: "bundled spec".to_owned(), source: e })?;
    spec.generation.seed = request.seed;
    let generator = mimicgen_engine::two_arm::TwoArmGenerator::new(spec.clone(), views)
        .map_err(|e| PipelineError::Engine { file: path.display().to_string(), source: e })?;
    let scene = std::sync::Arc::new(task.scene()?);
    let mut env = TwoArmSimEnv::new(scene, task, &variant)?;
    let attempt = generator.attempt(&mut env, request.index).map_err(|e| PipelineError::Engine { file: String::new(), source: e })?;
    Ok(views::two_arm_preview_view(TwoArmTask::name(task), &variant, &spec, &attempt))
}

/// The reply refusing to save `out`: over the open file, or over an existing file without
/// `overwrite`.
fn refuse_output(source: &std::path::Path, out: &std::path::Path, overwrite: bool) -> Option<Reply> {
    if out.canonicalize().is_ok_and(|o| source.canonicalize().is_ok_and(|s| s == o)) {
        return Some(Reply::Failed {
            what: format!("saving {}", out.display()),
            error: format!("{} is the open file: saving over it is not allowed; choose a new file", out.display()),
        });
    }
    (out.exists() && !overwrite).then(|| Reply::Failed {
        what: format!("saving {}", out.display()),
        error: format!("{} exists: choose a new file, or tick \"replace\" to save over it", out.display()),
    })
}

#[cfg(test)]
mod tests {
    use std::sync::mpsc::channel;

    use mimicgen_ui::protocol::RunUpdate;

    use super::*;

    #[test]
    fn workers_sharing_a_run_slot_run_one_at_a_time_and_any_of_them_cancels_it() {
        let dir = tempfile::tempdir().unwrap();
        let source = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../core/io/tests/data/source_D0_prepared.hdf5");
        let config = RunConfig {
            source: Some(source),
            out: dir.path().join("run.hdf5"),
            num_demos: Some(1000),
            seed: Some(1),
            ..RunConfig::default()
        };
        // The run's first update waits until the test lets it go: it is going, whatever the machine.
        let (updates, seen) = channel();
        let (release, gate) = channel::<()>();
        let (updates, gate) = (Mutex::new(updates), Mutex::new(gate));
        // Every update waits until the gate is dropped (then `recv` returns at once).
        let run_notify: Notify = Arc::new(move |reply| {
            let _ = updates.lock().unwrap().send(reply);
            let _ = gate.lock().unwrap().recv();
        });
        let slot = RunSlot::default();
        let quiet: Notify = Arc::new(|_| {});
        let mut a = Worker::new(Arc::clone(&quiet), None).with_run_notify(Arc::clone(&run_notify)).with_run_slot(slot.clone());
        let mut b = Worker::new(quiet, None).with_run_notify(run_notify).with_run_slot(slot.clone());
        assert_eq!(a.handle(Request::Run(Box::new(config.clone()))), Reply::RunAccepted);
        let _first = seen.recv().unwrap();
        assert!(b.running(), "the other worker sees the run");
        let Reply::Failed { error, .. } = b.handle(Request::Run(Box::new(config))) else { panic!("a second run refused") };
        assert!(error.contains("a run is going"), "{error}");
        // The worker that did not start it cancels it.
        assert_eq!(b.handle(Request::CancelRun), Reply::Cancelling);
        drop(release);
        let report = loop {
            match seen.recv().unwrap() {
                Reply::Run(RunUpdate::Finished(report)) => break report,
                Reply::Run(RunUpdate::Failed(e)) => panic!("{e}"),
                _ => {}
            }
        };
        assert!(report.cancelled && report.attempts < 1000, "{report:?}");
    }
}
