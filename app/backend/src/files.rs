//! Source files as the annotate screen sees them: streamed in with proposals, a demo's camera
//! images, and folder listings for the file browser.

use std::cell::RefCell;
use std::path::Path;

use mimicgen_engine::image::Pixels;
use mimicgen_engine::spec::Transit;
use mimicgen_engine::{SourceDataset, SourceDemo};
use mimicgen_io::{DemoReader, DemoSource as _, IoError, ReadOptions};
use mimicgen_pipeline::annotate::{Annotations, DemoAnnotation};
use mimicgen_pipeline::{PipelineError, annotate, prepare};

use mimicgen_ui::protocol::{CameraView, DemoView, Listing, LoadedFile, ProposalView, Reply};

/// Control rate of the recorded demos (robosuite's 20 Hz), for speeds.
const CONTROL_HZ: f64 = 20.0;

/// Demos per reply while a file streams in.
const CHUNK: usize = 64;

/// What the timeline draws of one demo.
pub(crate) fn demo_view(d: &SourceDemo, a: &DemoAnnotation) -> DemoView {
    let eef: Vec<_> = d.eef_poses.iter().map(|p| p.translation.vector).collect();
    let mut eef_speed: Vec<f64> = eef.iter().zip(eef.iter().skip(1)).map(|(a, b)| (b - a).norm() * CONTROL_HZ).collect();
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
pub(crate) fn stream(path: &Path, prepared_from: Option<&Path>, send: &dyn Fn(Reply)) -> Result<(Reply, Annotations), PipelineError> {
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
                arms: Vec::new(),
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
    if let Some(task) = two_arm_task(path) {
        return open_two_arm(path, task);
    }
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

/// The two-arm task a file's `env_args` names, when its demos hold one view per arm.
pub(crate) fn two_arm_task(path: &Path) -> Option<mimicgen_sim::two_arm::TwoArmTask> {
    let reader = DemoReader::open_with(path, ReadOptions::default()).ok()?;
    let task = mimicgen_sim::two_arm::TwoArmTask::from_env_args(reader.env_args_json()?)?;
    let first = reader.demo_names().first()?.clone();
    let demo = reader.load_demo(&first).ok()?;
    demo.group("datagen_info")?.group("eef_pose").is_some().then_some(task)
}

/// Opens a two-arm source file: each arm's view of every demo with its proposals, the first
/// arm's in the file's main fields (and in the returned annotations, which preview and runs,
/// one-arm only, do not use for a two-arm file).
///
/// # Errors
/// As [`annotate::propose_two_arm`].
fn open_two_arm(path: &Path, task: mimicgen_sim::two_arm::TwoArmTask) -> Result<(Reply, Annotations), PipelineError> {
    let (arms, scene) = annotate::propose_two_arm(path, task)?;
    let arm_files: Vec<mimicgen_ui::protocol::ArmFile> = arms
        .iter()
        .map(|arm| {
            let last = arm.spec.subtasks.len().saturating_sub(1);
            mimicgen_ui::protocol::ArmFile {
                name: arm.name.clone(),
                signal_names: arm.spec.subtasks.iter().take(last).map(|s| s.term_signal.clone().unwrap_or_default()).collect(),
                subtask_objects: arm.spec.subtasks.iter().map(|s| s.object_ref.clone()).collect(),
                demos: arm.demos.iter().map(|(d, a)| demo_view(d, a)).collect(),
            }
        })
        .collect();
    let no_arms = || PipelineError::Input { file: path.display().to_string(), field: "arm".to_owned(), reason: "no arms".to_owned() };
    let first = arms.into_iter().next().ok_or_else(no_arms)?;
    let file0 = arm_files.first().cloned().ok_or_else(no_arms)?;
    let file = LoadedFile {
        path: path.to_path_buf(),
        prepared_from: None,
        task: task.name().to_owned(),
        variants: task.variants().iter().map(|v| (*v).to_owned()).collect(),
        signal_names: file0.signal_names,
        subtask_objects: file0.subtask_objects,
        approach_m: first.spec.subtasks.iter().map(|s| s.approach_m).collect(),
        planned: vec![false; first.spec.subtasks.len()],
        total_demos: file0.demos.len(),
        demos: file0.demos,
        arms: arm_files,
    };
    let (sources, demos): (Vec<SourceDemo>, Vec<DemoAnnotation>) = first.demos.into_iter().unzip();
    let found = Annotations { spec: first.spec, demos, sources: SourceDataset { demos: sources, env_args: None }, scene };
    Ok((Reply::Opened(Box::new(file)), found))
}

/// Demo `demo`'s RGB camera streams in `path` (none when it has no camera observations or
/// cannot be read).
pub(crate) fn read_images(path: &Path, demo: usize) -> Vec<CameraView> {
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
