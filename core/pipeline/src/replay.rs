//! Replaying a dataset's demos in our simulator step by step, to compare its physics with another
//! simulator's on the same attempt (`scripts/compare_physics.py` runs the same demos in robosuite
//! and reads this module's traces through `mimicgen replay --trace`).
//!
//! Each demo starts from its first stored state in its own scene (`model_file`) and is driven in
//! one of two ways ([`ReplayMode`]): its stored actions open loop, or its stored controller
//! targets closed loop, as generation drove it (each step's action is recomputed from where the
//! arm is now, plus the action noise the attempt drew, recovered from the stored action). Per
//! step the trace holds what decides a grasp or a place: the end effector, the finger joints,
//! every object's pose, the contact count and the finger pads' contacts with each object.

use std::collections::BTreeMap;
use std::path::Path;
use std::sync::Arc;

use mimicgen_engine::Environment as _;
use mimicgen_engine::action::DeltaPoseScale;
use mimicgen_engine::pose::{Mat4, Pose, pose_from_matrix};
use mimicgen_io::RobomimicDataset;
use mimicgen_sim::{Scene, SimEnv};
use serde::{Deserialize, Serialize};

use crate::PipelineError;

/// How a replay drives the arm.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum ReplayMode {
    /// The stored actions, open loop (robomimic's playback).
    Actions,
    /// The stored controller targets, closed loop: each action is recomputed from the current end
    /// effector towards the step's `datagen_info/target_pose`, plus the stored action's noise.
    #[default]
    Targets,
    /// The stored absolute actions (`actions_abs`), open loop: each step's target, as an
    /// absolute-pose controller takes it, sent as the delta from where the arm is now.
    ActionsAbs,
    /// The stored joint-position actions (`actions_joint`), open loop: each step's arm joint
    /// targets under a joint-position controller ([`mimicgen_sim::joint_control`]).
    ActionsJoint,
}

/// What the simulation holds after one step (or at the start).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StepTrace {
    /// End effector: x, y, z (m) and the quaternion w, x, y, z.
    pub eef: [f64; 7],
    /// The finger joints (robosuite's `robot0_gripper_qpos`).
    pub fingers: Vec<f64>,
    /// Every object's pose, as `eef`.
    pub objects: BTreeMap<String, [f64; 7]>,
    /// Contacts in the whole scene.
    pub contacts: usize,
    /// Per object: the finger pads' contacts with it and their summed normal force (N).
    pub pads: BTreeMap<String, (usize, f64)>,
    /// The subtask-end signals.
    pub signals: BTreeMap<String, i64>,
    /// Whether the task is achieved.
    pub success: bool,
}

/// Where an object is in the MJCF, so that another simulator loading the same `model_file` reads
/// the same body and geoms.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ObjectNames {
    /// The body whose frame is the object's pose.
    pub body: String,
    /// Its collision geoms.
    pub geoms: Vec<String>,
}

/// One demo replayed.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DemoTrace {
    /// `demo_N`.
    pub demo: String,
    /// The task's objects by name, as the MJCF names them.
    pub objects: BTreeMap<String, ObjectNames>,
    /// The end-effector site and the left and right finger pads' collision geoms.
    pub eef_site: String,
    /// The finger pads' collision geoms, left then right.
    pub pads: [Vec<String>; 2],
    /// How it was driven.
    pub mode: ReplayMode,
    /// The state before the first action, then after every action.
    pub steps: Vec<StepTrace>,
    /// Whether the task was achieved at any step.
    pub success: bool,
    /// The first step (action index) after which it was.
    pub first_success: Option<usize>,
    /// Why the attempt failed when it was generated (failed-attempt files say).
    pub recorded_failure: Option<String>,
    /// Why the replay stopped early (the physics blew up), if it did.
    pub stopped: Option<String>,
}

/// `datagen_info/<field>` of a demo: one 4x4 pose per step.
fn poses(demo: &mimicgen_io::tree::Group, field: &str, file: &str, name: &str) -> Result<Vec<Pose>, PipelineError> {
    let at = format!("data/{name}/datagen_info/{field}");
    let d = demo.dataset_at(&format!("datagen_info/{field}")).ok_or_else(|| {
        PipelineError::input(
            file,
            format!("data/{name}"),
            format!("has no datagen_info/{field} (--mode targets needs it; --mode actions does not)"),
        )
    })?;
    let values = d.array.values.to_f64().ok_or_else(|| PipelineError::input(file, at.clone(), "is not numeric"))?;
    if !matches!(d.array.shape.as_slice(), [_, 4, 4]) {
        return Err(PipelineError::input(file, at, format!("has shape {:?}, not (steps, 4, 4)", d.array.shape)));
    }
    values
        .chunks(16)
        .enumerate()
        .map(|(t, m)| {
            pose_from_matrix(&Mat4::from_row_slice(m), &format!("step {t}"))
                .map_err(|e| PipelineError::input(file, at.clone(), e.to_string()))
        })
        .collect()
}

/// The pose an `actions_abs` row targets: position, then rotation as an axis-angle vector.
fn absolute_target(row: &[f64]) -> Pose {
    let at = |i: usize| row.get(i).copied().unwrap_or_default();
    Pose::from_parts(
        nalgebra::Translation3::new(at(0), at(1), at(2)),
        nalgebra::UnitQuaternion::from_scaled_axis(nalgebra::Vector3::new(at(3), at(4), at(5))),
    )
}

fn flat(pose: &Pose) -> [f64; 7] {
    let t = pose.translation.vector;
    let q = pose.rotation.quaternion();
    [t.x, t.y, t.z, q.w, q.i, q.j, q.k]
}

fn observe(env: &SimEnv) -> StepTrace {
    let scene = env.physics().scene();
    let qpos = env.physics().data().qpos();
    StepTrace {
        eef: flat(&env.eef_pose()),
        fingers: scene.robot.finger_qpos.iter().filter_map(|&i| qpos.get(i).copied()).collect(),
        objects: env.object_poses().iter().map(|(name, pose)| (name.clone(), flat(pose))).collect(),
        contacts: env.physics().contact_count(),
        pads: scene.objects.iter().enumerate().map(|(i, o)| (o.name.clone(), env.physics().pad_contacts(i))).collect(),
        signals: env.subtask_term_signals(),
        success: env.is_success(),
    }
}

/// Replays the demos `demos` of `input` (all of them when empty) in our simulator. `task` names
/// the task when the file's `env_args` do not; `on_demo(done, total, name)` is called after each.
///
/// # Errors
/// [`PipelineError`] naming the file and field: unreadable input, unknown task or demo, a demo
/// without `states`, `actions`, `model_file` or (for [`ReplayMode::Targets`]) `datagen_info`, or a
/// scene that does not compile.
pub fn replay(
    input: &Path,
    demos: &[String],
    mode: ReplayMode,
    task: Option<&str>,
    mut on_demo: impl FnMut(usize, usize, &str),
) -> Result<Vec<DemoTrace>, PipelineError> {
    let file = input.display().to_string();
    let dataset = RobomimicDataset::open(input)?;
    let task = crate::prepare::task_of(task, dataset.env_args(), &file)?;
    let names: Vec<String> = if demos.is_empty() { dataset.demo_names().to_vec() } else { demos.to_vec() };
    let mut scenes: BTreeMap<String, Arc<Scene>> = BTreeMap::new();
    let mut out = Vec::with_capacity(names.len());
    for (done, name) in names.iter().enumerate() {
        let at = format!("data/{name}");
        let demo = dataset.demo(name).ok_or_else(|| {
            PipelineError::input(file.clone(), "--demos", format!("no demo {name:?} (the file has {})", dataset.demo_names().join(", ")))
        })?;
        let xml = demo
            .attrs
            .get("model_file")
            .and_then(|a| a.as_str())
            .ok_or_else(|| PipelineError::input(file.clone(), at.clone(), "has no model_file attribute"))?;
        let scene = match scenes.get(xml) {
            Some(s) => Arc::clone(s),
            None => {
                let s = Arc::new(Scene::from_model_file(xml, &format!("{file}: {at}/model_file"), task.as_ref())?);
                scenes.insert(xml.to_owned(), Arc::clone(&s));
                s
            }
        };
        let states = crate::prepare::rows(demo, "states", &file, name)?;
        let actions = crate::prepare::rows(demo, "actions", &file, name)?;
        let other_key = match mode {
            ReplayMode::ActionsAbs => Some("actions_abs"),
            ReplayMode::ActionsJoint => Some("actions_joint"),
            ReplayMode::Actions | ReplayMode::Targets => None,
        };
        let other = other_key.map(|key| crate::prepare::rows(demo, key, &file, name)).transpose()?;
        if let (Some(key), Some(n)) = (other_key, other.as_ref().map(mimicgen_engine::Rows::len).filter(|&n| n != actions.len())) {
            return Err(PipelineError::input(
                file.clone(),
                format!("{at}/{key}"),
                format!("has {n} steps but actions has {}", actions.len()),
            ));
        }
        let targets = match mode {
            ReplayMode::Actions | ReplayMode::ActionsAbs | ReplayMode::ActionsJoint => None,
            ReplayMode::Targets => Some((poses(demo, "eef_pose", &file, name)?, poses(demo, "target_pose", &file, name)?)),
        };
        if let Some((field, n)) = targets.as_ref().and_then(|(eefs, targets)| {
            [("eef_pose", eefs.len()), ("target_pose", targets.len())].into_iter().find(|&(_, n)| n != actions.len())
        }) {
            return Err(PipelineError::input(
                file.clone(),
                format!("{at}/datagen_info/{field}"),
                format!("has {n} steps but actions has {}", actions.len()),
            ));
        }
        let first = states.iter().next().ok_or_else(|| PipelineError::input(file.clone(), format!("{at}/states"), "is empty"))?;
        let mut env = SimEnv::new(scene, Arc::clone(&task));
        env.reset_to_state(first).map_err(|e| PipelineError::input(file.clone(), format!("{at}/states[0]"), e.to_string()))?;
        // The first state is the attempt's reset: its arm pose is the posture the controller held.
        env.hold_posture_here();
        let scale = DeltaPoseScale::default();
        let scene = env.physics().scene();
        let mut trace = DemoTrace {
            demo: name.clone(),
            objects: scene
                .objects
                .iter()
                .map(|o| (o.name.clone(), ObjectNames { body: o.body_name.clone(), geoms: scene.geom_names(&o.geoms) }))
                .collect(),
            eef_site: scene.site_name(scene.robot.eef_site),
            pads: [scene.geom_names(&scene.robot.finger_pads[0]), scene.geom_names(&scene.robot.finger_pads[1])],
            mode,
            steps: vec![observe(&env)],
            success: false,
            first_success: None,
            recorded_failure: demo.attrs.get("mimicgen_failure").and_then(|a| a.as_str()).map(str::to_owned),
            stopped: None,
        };
        for (t, stored) in actions.iter().enumerate() {
            let mut action = stored.to_vec();
            // Both lists have one pose per action (checked above).
            if let Some((Some(eef), Some(target))) = targets.as_ref().map(|(eefs, targets)| (eefs.get(t), targets.get(t))) {
                // The attempt's noise is what the stored action adds to the clean action from
                // the stored end effector to the target; add it to the clean action from here.
                let clean_then = scale.action_from_target(eef, target);
                let clean_now = env.target_pose_to_action(target);
                for (((a, &s), now), then) in action.iter_mut().zip(stored).zip(clean_now).zip(clean_then) {
                    *a = now + (s - then);
                }
            }
            let row = other.as_ref().map(|rows| rows.row(t));
            if let (ReplayMode::ActionsAbs, Some(row)) = (mode, row) {
                let target = absolute_target(row);
                action = env.target_pose_to_action(&target).to_vec();
                action.extend_from_slice(row.get(6..).unwrap_or_default());
            }
            let stepped = match (mode, row) {
                (ReplayMode::ActionsJoint, Some(row)) => env.step_joint(row),
                _ => env.step(&action),
            };
            if let Err(e) = stepped {
                trace.stopped = Some(format!("step {t}: {e}"));
                break;
            }
            let step = observe(&env);
            if step.success && trace.first_success.is_none() {
                trace.first_success = Some(t);
            }
            trace.success |= step.success;
            trace.steps.push(step);
        }
        out.push(trace);
        on_demo(done + 1, names.len(), name);
    }
    Ok(out)
}
