//! Turning a plain robomimic dataset into MimicGen source demos by replaying its recorded states
//! in the simulator, as the reference's `prepare_src_dataset.py` does: per step the end-effector
//! pose, the controller target the action implies, the gripper action, every object's pose and the
//! subtask-end signals (`datagen_info`). Actions, states, rewards, dones and observations are copied.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use mimicgen_engine::Environment as _;
use mimicgen_engine::demo::Rows;
use mimicgen_io::tree::Group;
use mimicgen_io::{DatagenInfo, DatasetWriter, DemoData, RobomimicDataset, WriterOptions};
use mimicgen_sim::two_arm::{TwoArmSimEnv, TwoArmTask};
use mimicgen_sim::{Scene, SimEnv, registry};

use crate::PipelineError;

pub(crate) fn rows(demo: &Group, field: &str, file: &str, name: &str) -> Result<Rows, PipelineError> {
    let at = format!("data/{name}/{field}");
    let d = demo.dataset(field).ok_or_else(|| PipelineError::input(file, format!("data/{name}"), format!("has no `{field}`")))?;
    let width = d.array.shape.get(1).copied().unwrap_or(1);
    let values = d.array.values.to_f64().ok_or_else(|| PipelineError::input(file, at.clone(), "is not numeric"))?;
    Rows::from_vec(width, values, &format!("{file}: {at}")).map_err(|e| PipelineError::engine(file, e))
}

/// The task named by `--task`, else by the file's `env_args`.
///
/// # Errors
/// [`PipelineError::Input`] naming `--task` or the `env_args` attribute.
pub(crate) fn task_of(task: Option<&str>, env_args: Option<&str>, file: &str) -> Result<Arc<dyn mimicgen_sim::Task>, PipelineError> {
    match task {
        Some(name) => registry::task(name, "D0").map_err(|e| PipelineError::input("", "--task", e)),
        None => registry::task_from_env_args(env_args)
            .map(|(task, _)| task)
            .map_err(|e| PipelineError::input(file, "data attribute env_args", format!("{e}; pass --task"))),
    }
}

/// Replays every demo of `input` and writes MimicGen source demos to `out`. `task` names the task
/// when the file's `env_args` do not; `on_demo(done, total, name)` is called after each demo.
/// Returns the number of demos written.
///
/// # Errors
/// [`PipelineError`] naming the file and field: unreadable input, unknown task, a demo without
/// `states`, `actions` or `model_file`, a scene that does not compile, a state the simulator
/// rejects, or a failure to write (the output is then left as an incomplete `.partial`).
pub fn prepare(input: &Path, out: &Path, task: Option<&str>, mut on_demo: impl FnMut(usize, usize, &str)) -> Result<usize, PipelineError> {
    let file = input.display().to_string();
    let dataset = RobomimicDataset::open(input)?;
    let env_args = dataset.env_args().map(str::to_owned);
    let two_arm = match task {
        Some(name) => TwoArmTask::from_name(name),
        None => env_args.as_deref().and_then(TwoArmTask::from_env_args),
    };
    if let Some(two_arm) = two_arm {
        return prepare_two_arm(&dataset, two_arm, out, env_args, &mut on_demo);
    }
    let task = task_of(task, env_args.as_deref(), &file)?;
    let mut writer = DatasetWriter::create(out, WriterOptions { env_args, compress_obs: true, valid_fraction: None, split_seed: 0 })?;
    let mut scenes: BTreeMap<String, Arc<Scene>> = BTreeMap::new();
    let names = dataset.demo_names().to_vec();
    for (done, name) in names.iter().enumerate() {
        let (demo, xml, scene) = demo_scene(&dataset, &mut scenes, name, |xml, origin| Scene::from_model_file(xml, origin, task.as_ref()))?;
        let mut env = SimEnv::new(scene, Arc::clone(&task));
        let states = rows(demo, "states", &file, name)?;
        let actions = rows(demo, "actions", &file, name)?;
        if states.len() != actions.len() {
            return Err(PipelineError::input(
                file.clone(),
                format!("data/{name}"),
                format!("{} states but {} actions", states.len(), actions.len()),
            ));
        }
        let mut info = DatagenInfo { gripper_actions: Rows::new(actions.width().saturating_sub(6)), ..DatagenInfo::default() };
        for (t, (state, action)) in states.iter().zip(actions.iter()).enumerate() {
            env.reset_to_state(state).map_err(|e| PipelineError::input(file.clone(), format!("data/{name}/states[{t}]"), e.to_string()))?;
            info.eef_poses.push(env.eef_pose());
            info.target_poses.push(env.action_to_target_pose(action));
            info.gripper_actions.push(action.get(6..).unwrap_or_default()).map_err(|e| PipelineError::engine(file.clone(), e))?;
            for (object, pose) in env.object_poses() {
                info.object_poses.entry(object).or_default().push(pose);
            }
            for (signal, value) in env.subtask_term_signals() {
                info.subtask_term_signals.entry(signal).or_default().push(value);
            }
        }
        let (obs, images) = demo.group("obs").map(mimicgen_io::observations_from_group).unwrap_or_default();
        let data = DemoData {
            actions,
            other_actions: BTreeMap::new(),
            states,
            rewards: demo.dataset("rewards").and_then(|d| d.array.values.to_f64()),
            dones: demo.dataset("dones").and_then(|d| d.array.values.to_i64()),
            obs,
            images,
            datagen_info: Some(info),
            src_demo_inds: Vec::new(),
            src_demo_labels: Vec::new(),
            model_xml: Some(xml.to_owned()),
            attempt_index: None,
            failure: None,
            cause: None,
            object_instance: None,
        };
        writer.append(&data)?;
        on_demo(done + 1, names.len(), name);
    }
    writer.finish()?;
    Ok(names.len())
}

/// [`prepare`] for a two-arm dataset: per step each arm's end effector, target and gripper
/// (`datagen_info/<field>/robot0`, `robot1`), the objects and the task's signals.
fn prepare_two_arm(
    dataset: &RobomimicDataset,
    task: TwoArmTask,
    out: &Path,
    env_args: Option<String>,
    on_demo: &mut dyn FnMut(usize, usize, &str),
) -> Result<usize, PipelineError> {
    use mimicgen_engine::two_arm::TwoArmEnvironment as _;
    let file = dataset.file.clone();
    let mut writer = DatasetWriter::create(out, WriterOptions { env_args, compress_obs: true, valid_fraction: None, split_seed: 0 })?;
    let mut scenes: BTreeMap<String, Arc<Scene>> = BTreeMap::new();
    let names = dataset.demo_names().to_vec();
    for (done, name) in names.iter().enumerate() {
        let (demo, xml, scene) = demo_scene(dataset, &mut scenes, name, |xml, origin| task.scene_from_model_file(xml, origin))?;
        let mut env = TwoArmSimEnv::new(scene, task, "D0")?;
        let states = rows(demo, "states", &file, name)?;
        let actions = rows(demo, "actions", &file, name)?;
        if states.len() != actions.len() || actions.width() != 14 {
            return Err(PipelineError::input(
                file.clone(),
                format!("data/{name}"),
                format!("{} states and {} actions of {} values (two arms: 14 per step)", states.len(), actions.len(), actions.width()),
            ));
        }
        let mut attempt = mimicgen_engine::two_arm::TwoArmAttempt {
            index: 0,
            success: false,
            failure: None,
            initial_object_poses: BTreeMap::new(),
            initial_state: Vec::new(),
            states: states.clone(),
            actions: actions.clone(),
            object_poses: BTreeMap::new(),
            subtask_term_signals: BTreeMap::new(),
            arms: (0..2).map(|_| mimicgen_engine::two_arm::ArmTrack { gripper_actions: Rows::new(1), ..Default::default() }).collect(),
        };
        for (t, (state, action)) in states.iter().zip(actions.iter()).enumerate() {
            env.set_state(state).map_err(|e| PipelineError::input(file.clone(), format!("data/{name}/states[{t}]"), e.to_string()))?;
            for (arm, track) in attempt.arms.iter_mut().enumerate() {
                let arm_action = action.get(7 * arm..7 * arm + 7).unwrap_or_default();
                track.eef_poses.push(env.eef_pose(arm));
                track.target_poses.push(env.action_to_target_pose(arm, arm_action));
                track.gripper_actions.push(arm_action.get(6..).unwrap_or_default()).map_err(|e| PipelineError::engine(file.clone(), e))?;
            }
            for (object, pose) in env.object_poses() {
                attempt.object_poses.entry(object).or_default().push(pose);
            }
            for (signal, value) in env.subtask_term_signals() {
                attempt.subtask_term_signals.entry(signal).or_default().push(value);
            }
        }
        let (obs, images) = demo.group("obs").map(mimicgen_io::observations_from_group).unwrap_or_default();
        let mut data = DemoData::from_two_arm_attempt(&attempt, &crate::two_arm::ARMS, obs, Some(xml.to_owned()));
        data.images = images;
        data.rewards = demo.dataset("rewards").and_then(|d| d.array.values.to_f64());
        data.dones = demo.dataset("dones").and_then(|d| d.array.values.to_i64());
        (data.attempt_index, data.src_demo_labels, data.failure) = (None, Vec::new(), None);
        writer.append(&data)?;
        on_demo(done + 1, names.len(), name);
    }
    writer.finish()?;
    Ok(names.len())
}

/// Demo `name` of `dataset`, its `model_file`, and its scene: compiled by `compile(xml, origin)`
/// once per distinct `model_file` (kept in `scenes`).
///
/// # Errors
/// A demo without a `model_file` attribute, or `compile`'s error.
fn demo_scene<'a>(
    dataset: &'a RobomimicDataset,
    scenes: &mut BTreeMap<String, Arc<Scene>>,
    name: &str,
    compile: impl FnOnce(&str, &str) -> Result<Scene, mimicgen_sim::SimError>,
) -> Result<(&'a Group, &'a str, Arc<Scene>), PipelineError> {
    let file = &dataset.file;
    let demo = dataset.demo(name).ok_or_else(|| PipelineError::input(file.clone(), format!("data/{name}"), "vanished"))?;
    let xml = demo
        .attrs
        .get("model_file")
        .and_then(|a| a.as_str())
        .ok_or_else(|| PipelineError::input(file.clone(), format!("data/{name}"), "has no model_file attribute"))?;
    let scene = match scenes.get(xml) {
        Some(s) => Arc::clone(s),
        None => {
            let s = Arc::new(compile(xml, &format!("{file}: data/{name}/model_file"))?);
            scenes.insert(xml.to_owned(), Arc::clone(&s));
            s
        }
    };
    Ok((demo, xml, scene))
}

/// The folder of the app's prepared copies: `$MIMICGEN_CACHE/prepared`.
#[must_use]
pub fn prepared_dir() -> PathBuf {
    mimicgen_sim::assets::cache_dir().join("prepared")
}

/// Where the app keeps a prepared copy of `input`: `$MIMICGEN_CACHE/prepared/<stem>-<hash>.hdf5`,
/// the hash over the input's path, size and modification time (a changed file is prepared again).
#[must_use]
pub fn cached_prepared_path(input: &Path) -> PathBuf {
    let meta = std::fs::metadata(input).ok();
    let stamp = format!(
        "{}|{}|{:?}",
        input.canonicalize().unwrap_or_else(|_| input.to_path_buf()).display(),
        meta.as_ref().map_or(0, std::fs::Metadata::len),
        meta.and_then(|m| m.modified().ok())
    );
    let hash = mimicgen_engine::fingerprint::fnv1a_hex(stamp.as_bytes());
    let stem = input.file_stem().map_or_else(|| "dataset".into(), |s| s.to_string_lossy().into_owned());
    prepared_dir().join(format!("{stem}-{hash}.hdf5"))
}
