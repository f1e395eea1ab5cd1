//! The inspection app's backend: a [`Worker`] that reads, detects, writes, plans and tries
//! attempts and runs generation, answering the UI's requests (`mimicgen_ui::protocol`).
//! [`Backend`] runs it on a named thread of the app's own process (the desktop window); `mimicgen
//! serve` runs one for the browsers that connect to it. The UI never waits on it.
//!
//! What it does not do: draw, or decide which paths a request may touch (the server confines
//! them to its root before they get here).

use std::cell::RefCell;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, Sender, channel};

use mimicgen_engine::image::{ImageStream, Pixels};
use mimicgen_engine::spec::Transit;
use mimicgen_engine::transform::WaypointKind;
use mimicgen_engine::{Attempt, Overrides, Plan, Pose, RunStats, SourceDataset, SourceDemo};
use mimicgen_io::{ATTEMPT_ATTR, DemoReader, DemoSource as _, FAILURE_ATTR, INSTANCE_ATTR, IoError, ReadOptions, source_demo_from_group};
use mimicgen_pipeline::annotate::{Annotations, DemoAnnotation};
use mimicgen_pipeline::preview::Previewer;
use mimicgen_pipeline::{AttemptEvent, Event, FrontEnd, Outcome, Pipeline, PipelineError, Report, RunConfig, RunInfo, annotate, prepare};
use mimicgen_viz::rerun::RecordingStream;
use mimicgen_viz::{LogConfig, RunLogger, SceneLevel, Sink};

use mimicgen_ui::protocol::{
    AttemptRow, CameraView, DemoView, ExecutedView, Listing, LoadedFile, ObjectView, OpenedRun, Point, PreviewRequest, PreviewView,
    ProposalView, RankView, Reply, Request, RunUpdate, SubtaskDiagnostics, SubtaskPreview, ViewerSink, Welcome,
};

/// Control rate of the recorded demos (robosuite's 20 Hz), for speeds.
const CONTROL_HZ: f64 = 20.0;

/// Demos per reply while a file streams in.
const CHUNK: usize = 64;

/// What the timeline draws of one demo.
fn demo_view(d: &SourceDemo, a: &DemoAnnotation) -> DemoView {
    let eef: Vec<_> = d.eef_poses.iter().map(|p| p.translation.vector).collect();
    let mut eef_speed: Vec<f64> = eef.windows(2).map(|w| (w[1] - w[0]).norm() * CONTROL_HZ).collect();
    eef_speed.push(eef_speed.last().copied().unwrap_or_default());
    DemoView {
        name: a.demo.clone(),
        len: a.len,
        gripper: (0..d.len()).map(|t| d.gripper_actions.row(t).first().copied().unwrap_or_default()).collect(),
        finger_width_m: a.finger_width_m.clone(),
        eef_speed,
        distances: d
            .object_poses
            .iter()
            .map(|(name, poses)| (name.clone(), poses.iter().zip(&eef).map(|(p, e)| (p.translation.vector - e).norm()).collect()))
            .collect(),
        signals: d.subtask_term_signals.clone(),
        stored_ends: a.signal_ends.clone(),
        stored_starts: d.manual_subtask_starts.clone(),
        proposals: a.proposals.iter().map(|p| ProposalView { end: p.end, confidence: p.confidence, reason: p.reason.clone() }).collect(),
    }
}

/// Streams `path` in: the first [`CHUNK`] demos as [`Reply::Opened`], the rest as
/// [`Reply::MoreDemos`], each sent to `send` except the last, which is returned (it ends the
/// request). Returns the demos and scene read, for the 3D view.
fn stream(path: &Path, prepared_from: Option<&Path>, send: &dyn Fn(Reply)) -> Result<(Reply, Annotations), PipelineError> {
    let found: RefCell<Option<Annotations>> = RefCell::new(None);
    let header: RefCell<Option<(LoadedFile, usize)>> = RefCell::new(None);
    let pending: RefCell<Option<Reply>> = RefCell::new(None);
    annotate::propose_streaming(
        path,
        CHUNK,
        |proposer, total| {
            let spec = proposer.spec();
            let last = spec.subtasks.len().saturating_sub(1);
            let file = LoadedFile {
                path: path.to_path_buf(),
                prepared_from: prepared_from.map(Path::to_path_buf),
                task: spec.name.clone(),
                variants: mimicgen_sim::registry::tasks().find(|t| t.name == spec.name).map(|t| t.variants.clone()).unwrap_or_default(),
                signal_names: spec.subtasks.iter().take(last).map(|s| s.term_signal.clone().unwrap_or_default()).collect(),
                subtask_objects: spec.subtasks.iter().map(|s| s.object_ref.clone()).collect(),
                approach_m: spec.subtasks.iter().map(|s| s.approach_m).collect(),
                planned: spec.subtasks.iter().map(|s| s.transit == Transit::Plan).collect(),
                total_demos: total,
                demos: Vec::new(),
            };
            *header.borrow_mut() = Some((file, 0));
            *found.borrow_mut() = Some(Annotations {
                spec: spec.clone(),
                demos: Vec::with_capacity(total),
                sources: SourceDataset { demos: Vec::with_capacity(total), env_args: None },
                scene: proposer.scene().clone(),
            });
        },
        |chunk| {
            let views: Vec<DemoView> = chunk.iter().map(|(d, a)| demo_view(d, a)).collect();
            if let Some(found) = found.borrow_mut().as_mut() {
                for (d, a) in chunk {
                    found.sources.demos.push(d);
                    found.demos.push(a);
                }
            }
            let mut header = header.borrow_mut();
            let Some((file, sent)) = header.as_mut() else { return };
            let reply = if *sent == 0 {
                Reply::Opened(Box::new(LoadedFile { demos: views, ..file.clone() }))
            } else {
                Reply::MoreDemos { path: path.to_path_buf(), last: *sent + views.len() >= file.total_demos, demos: views }
            };
            *sent += match &reply {
                Reply::Opened(f) => f.demos.len(),
                Reply::MoreDemos { demos, .. } => demos.len(),
                _ => 0,
            };
            if let Some(previous) = pending.borrow_mut().replace(reply) {
                send(previous);
            }
        },
    )?;
    let reply =
        pending.into_inner().ok_or_else(|| PipelineError::Fs { file: path.display().to_string(), reason: "no demos read".to_owned() })?;
    let found =
        found.into_inner().ok_or_else(|| PipelineError::Fs { file: path.display().to_string(), reason: "no demos read".to_owned() })?;
    Ok((reply, found))
}

/// Opens `path`, streaming its demos to `send` as they are read (the returned reply is the last
/// part). A plain robomimic file (no `datagen_info`) is first prepared by replay into the cache
/// (once per version of the file), reporting each demo.
///
/// # Errors
/// The pipeline's error, whole (it names the file and field).
pub fn open(path: &Path, send: &dyn Fn(Reply)) -> Result<(Reply, Annotations), PipelineError> {
    match stream(path, None, send) {
        Err(PipelineError::Io(IoError::NotMimicGen { .. })) => {
            let prepared = prepare::cached_prepared_path(path);
            if !prepared.is_file() {
                if let Some(dir) = prepared.parent() {
                    std::fs::create_dir_all(dir)
                        .map_err(|e| PipelineError::Fs { file: dir.display().to_string(), reason: e.to_string() })?;
                }
                let what = format!("{} has no datagen_info: replaying its demos in MuJoCo", path.display());
                prepare::prepare(path, &prepared, None, |done, total, _| send(Reply::Progress { what: what.clone(), done, total }))?;
            }
            stream(&prepared, Some(path), send)
        }
        other => other,
    }
}

/// Demo `demo`'s RGB camera streams in `path` (none when it has no camera observations or
/// cannot be read).
fn read_images(path: &Path, demo: usize) -> Vec<CameraView> {
    let Ok(reader) = DemoReader::open_with(path, ReadOptions::default()) else { return Vec::new() };
    let Some(name) = reader.demo_names().get(demo).cloned() else { return Vec::new() };
    let Ok(group) = reader.load_demo(&name) else { return Vec::new() };
    let Some(obs) = group.group("obs") else { return Vec::new() };
    let (_, images) = mimicgen_io::observations_from_group(obs);
    images
        .into_iter()
        .filter_map(|(key, stream)| {
            let name = key.strip_suffix("_image")?.to_owned();
            let ([height, width, 3], Pixels::Rgb(rgb)) = (stream.shape, stream.pixels) else { return None };
            Some(CameraView { name, width, height, rgb })
        })
        .collect()
}

fn point(pose: &Pose) -> Point {
    let t = pose.translation.vector;
    [t.x, t.y, t.z]
}

fn objects(poses: &BTreeMap<String, Pose>) -> Vec<ObjectView> {
    poses.iter().map(|(name, p)| ObjectView { name: name.clone(), position: point(p), yaw: p.rotation.euler_angles().2 }).collect()
}

/// Each executed subtask of `attempt` in numbers (see [`SubtaskDiagnostics`]).
fn diagnostics(attempt: &Attempt, subtasks: &[mimicgen_engine::SubtaskSpec]) -> Vec<SubtaskDiagnostics> {
    let t = &attempt.trajectory;
    let mm = |v: mimicgen_engine::pose::Vec3| v.norm() * 1000.0;
    attempt
        .plans
        .iter()
        .enumerate()
        .filter_map(|(k, plan)| {
            let first = plan.first_step;
            let end = attempt.plans.get(k + 1).map_or(t.len(), |p| p.first_step).min(t.len());
            let last = end.checked_sub(1).filter(|&l| l >= first)?;
            let target_error_mm = mm(t.target_poses[last].translation.vector - t.eef_poses[last].translation.vector);
            let track = |name: &Option<String>| name.as_ref().and_then(|n| t.object_poses.get(n));
            let object_moved_mm =
                track(&subtasks.get(k)?.object_ref).map(|poses| mm(poses[last].translation.vector - poses[first].translation.vector));
            let held_object_slip_mm = k.checked_sub(1).and_then(|j| track(&subtasks.get(j)?.object_ref)).map(|poses| {
                let eef_from_obj = |s: usize| t.eef_poses[s].inverse() * poses[s];
                mm(eef_from_obj(last).translation.vector - eef_from_obj(first).translation.vector)
            });
            Some(SubtaskDiagnostics { subtask: k, steps: (first, end), target_error_mm, object_moved_mm, held_object_slip_mm })
        })
        .collect()
}

/// Turns a plan (and an executed attempt) into what the preview screen draws.
fn preview_view(previewer: &Previewer, plan: &Plan, executed: Option<&Attempt>) -> PreviewView {
    let demos = &previewer.generator().dataset().demos;
    let spec = previewer.generator().spec();
    // Once executed, the segments the attempt really ran: from subtask 1 on, the selection sees
    // where the objects are then, which a plan made before executing cannot know.
    let ran = executed.map_or(&[][..], |a| &a.plans[..]);
    let subtasks = plan
        .subtasks
        .iter()
        .enumerate()
        .map(|(k, s)| ran.get(k).unwrap_or(s))
        .zip(&spec.subtasks)
        .map(|(s, subtask)| {
            let mut ranking: Vec<RankView> = s
                .source_distances
                .iter()
                .flatten()
                .enumerate()
                .map(|(demo, &distance)| RankView { demo, name: demos[demo].name.clone(), distance })
                .collect();
            ranking.sort_by(|a, b| a.distance.total_cmp(&b.distance).then(a.demo.cmp(&b.demo)));
            let bridge = s.waypoints.iter().take_while(|(_, k)| *k == WaypointKind::Interpolation).map(|(p, _)| point(p)).collect();
            let transit = s.waypoints.iter().take_while(|(_, k)| *k == WaypointKind::Transit).map(|(p, _)| point(p)).collect();
            SubtaskPreview {
                object: subtask.object_ref.clone(),
                src_demo: s.src_demo,
                src_demo_name: demos[s.src_demo].name.clone(),
                src_span: s.src_span,
                ranking,
                source_path: s.source_poses.iter().map(point).collect(),
                source_object: s.world_from_obj_src.as_ref().map(point),
                bridge,
                transit,
                transformed: s.transformed_poses.iter().map(point).collect(),
            }
        })
        .collect();
    let executed = executed.map(|a| ExecutedView {
        success: a.success,
        failure: a.failure.as_ref().map(|f| format!("subtask {}: {}", f.subtask, f.reason)),
        path: a.trajectory.eef_poses.iter().map(point).collect(),
        planned: a.plans.iter().flat_map(|p| p.waypoints.iter().map(|(w, _)| point(w))).collect(),
        subtask_of_step: a.trajectory.subtask_labels.clone(),
        sources: a.src_demo_per_subtask.clone(),
        final_objects: objects(&a.trajectory.object_poses.iter().filter_map(|(n, p)| Some((n.clone(), *p.last()?))).collect()),
        diagnostics: diagnostics(a, &spec.subtasks),
    });
    PreviewView {
        task: previewer.pipeline().task().name().to_owned(),
        variant: previewer.pipeline().variant().to_owned(),
        seed: spec.generation.seed,
        index: plan.index,
        eef: point(&plan.world_from_eef),
        objects: objects(&plan.initial_object_poses),
        subtasks,
        executed,
        failure_3d: None,
    }
}

/// Makes a recording stream that feeds the viewer embedded in the app's window.
pub type StreamFactory = Arc<dyn Fn() -> Result<RecordingStream, String> + Send + Sync>;

/// Sends a reply to the UI (and asks for a repaint), from any thread.
pub type Notify = Arc<dyn Fn(Reply) + Send + Sync>;

/// An attempt event as the attempt table shows it.
fn attempt_row(event: &AttemptEvent) -> AttemptRow {
    let a = &event.attempt;
    AttemptRow {
        index: a.index,
        success: a.success,
        failed_subtask: a.failure.as_ref().map(|f| f.subtask),
        reason: a.failure.as_ref().map(|f| f.reason.to_string()),
        sources: a.src_demo_per_subtask.clone(),
        steps: a.trajectory.len(),
        outcome: match &event.outcome {
            Outcome::Written { demo } => demo.clone(),
            Outcome::KeptFailed { demo } => format!("{demo} (failed)"),
            Outcome::Discarded => "discarded".to_owned(),
        },
        elapsed_s: event.elapsed_s,
        objects: objects(&a.initial_object_poses),
        instance: event.instance.clone(),
        stats: event.stats.clone(),
    }
}

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

/// Runs `config` through the pipeline, reporting every event to `notify`; stops when `cancel` is set.
/// With the 3D view open, every attempt is also logged to `logger` as it is decided (a failure
/// to log ends the logging, not the run).
fn run_generation(config: &RunConfig, cancel: &AtomicBool, notify: &Notify, mut logger: Option<RunLogger>) {
    let update = |u: RunUpdate| notify(Reply::Run(u));
    let pipeline = match Pipeline::prepare(config) {
        Ok(p) => p,
        Err(e) => return update(RunUpdate::Failed(e.worded(FrontEnd::App))),
    };
    let result = pipeline.run(cancel, |event| match event {
        Event::Started(info) => update(RunUpdate::Started { info: info.clone(), dimensions: pipeline.task().coverage_dimensions() }),
        Event::Attempt(a) => {
            update(RunUpdate::Attempt(Box::new(attempt_row(a))));
            if let Some(l) = &mut logger
                && l.log_attempt(&a.attempt, &a.stats).is_err()
            {
                logger = None;
            }
        }
        Event::Finished(_) => {}
    });
    if let Some(l) = logger {
        let _ = l.finish();
    }
    match result {
        Ok(report) => update(RunUpdate::Finished(Box::new(report))),
        Err(e) => update(RunUpdate::Failed(e.worded(FrontEnd::App))),
    }
}

/// Lists `path`'s subdirectories (not hidden) and HDF5 files.
///
/// # Errors
/// The OS error, naming the directory.
pub fn list_dir(path: &Path) -> Result<Listing, PipelineError> {
    let fs = |e: std::io::Error| PipelineError::Fs { file: path.display().to_string(), reason: e.to_string() };
    let dir = path.canonicalize().map_err(fs)?;
    let (mut dirs, mut files) = (Vec::new(), Vec::new());
    for entry in std::fs::read_dir(&dir).map_err(fs)? {
        let Ok(entry) = entry else { continue };
        let (p, name) = (entry.path(), entry.file_name().to_string_lossy().into_owned());
        if name.starts_with('.') {
            continue;
        }
        if p.is_dir() {
            dirs.push(p);
        } else if p.extension().is_some_and(|e| e == "hdf5" || e == "h5") {
            files.push((p, entry.metadata().map_or(0, |m| m.len())));
        }
    }
    dirs.sort();
    files.sort();
    Ok(Listing { parent: dir.parent().map(Path::to_path_buf), dir, dirs, files })
}

/// Reads a finished run's outputs (the dataset `path`, its `_failed.hdf5` and its `.json` report
/// where they exist) and reports them to `notify` as a run would: started, every kept attempt in
/// index order, finished. Attempts that were not kept (failures beyond `max_num_failures`, or all
/// failures without `--keep-failed`) are not in the files; the report still counts them.
///
/// # Errors
/// A file that cannot be read, or demos without `mimicgen_attempt` (not made by `generate`).
pub fn open_run(path: &Path, notify: &Notify) -> Result<(), PipelineError> {
    let run = read_run(path)?;
    let update = |u: RunUpdate| notify(Reply::Run(u));
    update(RunUpdate::Started { info: Box::new(run.info), dimensions: run.dimensions });
    for row in run.rows {
        update(RunUpdate::Attempt(Box::new(row)));
    }
    update(RunUpdate::Finished(Box::new(run.report)));
    Ok(())
}

/// A finished run's outputs read whole (see [`open_run`]).
///
/// # Errors
/// As [`open_run`].
pub fn read_run(path: &Path) -> Result<OpenedRun, PipelineError> {
    let label = path.display().to_string();
    let report_path = mimicgen_pipeline::sibling(path, "", "json");
    let report: Option<Report> = match std::fs::read_to_string(&report_path) {
        Ok(text) => Some(
            serde_json::from_str(&text)
                .map_err(|e| PipelineError::Fs { file: report_path.display().to_string(), reason: format!("not a run report: {e}") })?,
        ),
        Err(_) => None,
    };
    let mut rows: Vec<AttemptRow> = Vec::new();
    let mut env_args = None;
    let failed = mimicgen_pipeline::failed_path(path);
    for (file, success) in [(path.to_path_buf(), true), (failed.clone(), false)] {
        if !success && !file.is_file() {
            continue;
        }
        let reader = DemoReader::open_with(&file, ReadOptions::default())?.without_observations();
        let file_label = file.display().to_string();
        env_args = env_args.or_else(|| reader.env_args_json().map(str::to_owned));
        for name in reader.demo_names() {
            let group = reader.load_demo(name)?;
            let index = group.attrs.get(ATTEMPT_ATTR).and_then(mimicgen_io::tree::Array::as_i64).and_then(|i| u64::try_from(i).ok());
            let index = index.ok_or_else(|| PipelineError::Fs {
                file: file_label.clone(),
                reason: format!("data/{name} has no {ATTEMPT_ATTR} attribute: the file was not written by `mimicgen generate`"),
            })?;
            let demo = source_demo_from_group(&file_label, name, &group)?;
            let sources = group
                .dataset("src_demo_inds")
                .and_then(|d| d.array.values.to_i64())
                .map(|v| v.into_iter().filter_map(|i| usize::try_from(i).ok()).collect())
                .unwrap_or_default();
            // `subtask k: reason`, as the writer puts it.
            let failure = group.attrs.get(FAILURE_ATTR).and_then(mimicgen_io::tree::Array::as_str);
            let parsed = failure.and_then(|f| {
                let (subtask, reason) = f.strip_prefix("subtask ")?.split_once(": ")?;
                Some((subtask.parse::<usize>().ok()?, reason.to_owned()))
            });
            let (failed_subtask, reason) = match parsed {
                Some((k, r)) => (Some(k), Some(r)),
                None => (None, failure.map(str::to_owned)),
            };
            rows.push(AttemptRow {
                index,
                success,
                failed_subtask,
                reason: if success { None } else { Some(reason.unwrap_or_else(|| "not recorded in the file".to_owned())) },
                sources,
                steps: demo.len(),
                outcome: if success { name.clone() } else { format!("{name} (failed)") },
                elapsed_s: 0.0,
                objects: objects(&demo.object_poses.iter().filter_map(|(k, v)| Some((k.clone(), *v.first()?))).collect()),
                instance: group.attrs.get(INSTANCE_ATTR).and_then(mimicgen_io::tree::Array::as_str).map(str::to_owned),
                stats: RunStats::default(),
            });
        }
    }
    rows.sort_by_key(|r| r.index);
    let num_sources = report
        .as_ref()
        .map_or(0, |r| r.per_source_demo.len())
        .max(rows.iter().flat_map(|r| r.sources.iter().map(|d| d + 1)).max().unwrap_or(0));
    let mut stats = RunStats::new(num_sources);
    for row in &mut rows {
        stats.attempts += 1;
        stats.successes += usize::from(row.success);
        let mut used: Vec<usize> = row.sources.clone();
        used.sort_unstable();
        used.dedup();
        for d in used {
            if let Some(u) = stats.per_source_demo.get_mut(d) {
                u.attempts += 1;
                u.successes += usize::from(row.success);
            }
        }
        row.stats = stats.clone();
    }
    let (task, variant) = mimicgen_sim::registry::task_from_env_args(env_args.as_deref())
        .map_err(|e| PipelineError::Fs { file: label.clone(), reason: format!("data attribute env_args: {e}") })?;
    let info = RunInfo {
        task: task.name().to_owned(),
        variant,
        source: report.as_ref().map(|r| PathBuf::from(&r.source)).unwrap_or_default(),
        num_sources,
        workers: report.as_ref().map_or(1, |r| r.workers),
        seed: report.as_ref().map_or(0, |r| r.seed),
        spec_overrides: report.as_ref().map(|r| r.spec_overrides.clone()).unwrap_or_default(),
        target: report.as_ref().map_or(rows.len(), |r| r.attempts),
        guarantee: false,
        resumed_from: 0,
    };
    let kept = rows.len();
    let report = report.unwrap_or_else(|| Report {
        task: task.name().to_owned(),
        variant: String::new(),
        seed: 0,
        workers: 1,
        source: String::new(),
        output: label.clone(),
        failed_output: failed.is_file().then(|| failed.display().to_string()),
        attempts: kept,
        successes: stats.successes,
        generation_rate: stats.rate(),
        wall_time_s: 0.0,
        attempts_per_s: 0.0,
        control_steps: 0,
        per_source_demo: Vec::new(),
        peak_rss_mib: None,
        failures: Vec::new(),
        cancelled: false,
        resumed_from: 0,
        early_abort: false,
        spec_overrides: mimicgen_pipeline::SpecOverrides::default(),
        shard: None,
        transit: mimicgen_engine::generate::TransitTotals::default(),
    });
    Ok(OpenedRun { path: path.to_path_buf(), info, dimensions: task.coverage_dimensions(), rows, report })
}

/// The backend's state: the open file's demos and scene (for the 3D view), the previewer of the
/// last previewed file (kept so that moving through scenes does not recompile the scene), and the
/// Rerun stream once the 3D view is open.
pub struct Worker {
    loaded: Option<Annotations>,
    /// The open file (for a plain robomimic file, its prepared copy).
    loaded_path: Option<PathBuf>,
    previewer: Option<(RunConfig, Previewer)>,
    viewer: Option<(ViewerSink, RunLogger)>,
    embedded: Option<StreamFactory>,
    notify: Notify,
    /// Where a run's updates go (all its watchers), from the run's own thread.
    run_notify: Notify,
    /// The running generation's cancel flag and thread.
    run: Option<(Arc<AtomicBool>, std::thread::JoinHandle<()>)>,
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
        Self { loaded: None, loaded_path: None, previewer: None, viewer: None, embedded, notify, run_notify, run: None }
    }

    /// Sends the updates of runs started from now on to `notify` instead (every tab watching).
    #[must_use]
    pub fn with_run_notify(self, notify: Notify) -> Self {
        Self { run_notify: notify, ..self }
    }

    /// Whether a run is going.
    #[must_use]
    pub fn running(&self) -> bool {
        self.run.as_ref().is_some_and(|(_, thread)| !thread.is_finished())
    }

    /// Answers one request; a panic while answering is caught and answered as a failure (the
    /// worker and the app go on).
    pub fn handle_guarded(&mut self, request: Request) -> Reply {
        let what: String = format!("answering {request:?}").chars().take(100).collect();
        guarded(what, || self.handle(request))
    }

    fn start_run(&mut self, config: RunConfig) -> Reply {
        if self.running() {
            return Reply::Failed {
                what: "starting a run".to_owned(),
                error: "a run is going; cancel it or wait for it to end".to_owned(),
            };
        }
        let cancel = Arc::new(AtomicBool::new(false));
        let (flag, notify) = (Arc::clone(&cancel), Arc::clone(&self.run_notify));
        // The run's own recording (its attempts on the `attempt` and `frame` timelines): a new
        // recording in the embedded viewer or the spawned one, `<file>_run.rrd` beside a saved one.
        let logger = match self.viewer.as_ref().map(|(sink, _)| sink.clone()) {
            Some(ViewerSink::Save(path)) => self.logger(&ViewerSink::Save(mimicgen_pipeline::sibling(&path, "_run", "rrd"))).ok(),
            Some(sink) => self.logger(&sink).ok(),
            None => None,
        };
        let spawned =
            std::thread::Builder::new().name("mimicgen-gui-run".to_owned()).spawn(move || run_generation(&config, &flag, &notify, logger));
        match spawned {
            Ok(thread) => {
                self.run = Some((cancel, thread));
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
            Request::CancelRun => {
                if let Some((cancel, _)) = &self.run {
                    cancel.store(true, Ordering::Relaxed);
                }
                Reply::Cancelling
            }
            Request::Open { path } => match open(&path, &*Arc::clone(&self.notify)) {
                Ok((reply, found)) => {
                    self.loaded = Some(found);
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
            Request::Save { source, out, marks, signal_names, overwrite } => {
                if out.canonicalize().is_ok_and(|o| source.canonicalize().is_ok_and(|s| s == o)) {
                    return Reply::Failed {
                        what: format!("saving {}", out.display()),
                        error: format!("{} is the open file: saving over it is not allowed; choose a new file", out.display()),
                    };
                }
                if out.exists() && !overwrite {
                    return Reply::Failed {
                        what: format!("saving {}", out.display()),
                        error: format!("{} exists: choose a new file, or tick \"replace\" to save over it", out.display()),
                    };
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

fn preview_failed(request: &PreviewRequest, e: &PipelineError) -> Reply {
    Reply::Failed {
        what: format!(
            "{} attempt {} of {}",
            if request.execute { "trying" } else { "previewing" },
            request.index,
            request.source.display()
        ),
        error: e.to_string(),
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
            let mut worker = Worker::new(notify, embedded);
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
