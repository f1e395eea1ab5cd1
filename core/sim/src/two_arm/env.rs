//! The two-arm environment: robosuite's two-arm scene stepped with an OSC_POSE controller per
//! arm, its resets, signals, success and observations ([`TwoArmSimEnv`]).
#![allow(
    clippy::indexing_slicing,
    reason = "MuJoCo ids and addresses come from the compiled model (name_to_id, a Scene's names resolved once) and index that model's own arrays; states and actions are checked for length where they come in (set_state, step)"
)]

use std::collections::BTreeMap;
use std::f64::consts::PI;
use std::sync::Arc;

use mimicgen_engine::action::DeltaPoseScale;
use mimicgen_engine::pose::{Pose, Rot, Vec3, pose_from_parts, quat_to_xyzw};
use mimicgen_engine::two_arm::TwoArmEnvironment;
use mimicgen_engine::{EnvError, Rows};
use mujoco_rs::prelude::*;
use rand::{Rng as _, RngCore};
use rand_distr::{Distribution, Normal};

use super::{
    HANDOVER_HEIGHT_M, HANDOVER_SUCCESS_M, HANDOVER_TOLERANCE_M, HANDOVER_XY_M, LIFT_M, POT_HALF_HEIGHT_M, TaskIndices, TwoArmTask,
    robosuite_hammer_quat,
};
use crate::SimError;
use crate::env::{ARM_INIT_NOISE, Observation, arm_observation, check_stable, drive_arm};
use crate::osc::{Osc, OscConfig};
use crate::scene::{RobotIndices, Scene};
use crate::state::SimState;

/// A robosuite-like two-arm environment: the scene, its MuJoCo data, a controller per arm and the
/// task.
pub struct TwoArmSimEnv {
    state: SimState,
    task: TwoArmTask,
    variant: String,
    indices: TaskIndices,
    table_top_site: usize,
    robots: [RobotIndices; 2],
    oscs: [Osc; 2],
    gripper_commands: [[f64; 2]; 2],
    warnings_seen: i64,
}

impl std::fmt::Debug for TwoArmSimEnv {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TwoArmSimEnv").field("task", &self.task).field("variant", &self.variant).finish_non_exhaustive()
    }
}

impl TwoArmSimEnv {
    /// An environment for `task`'s `variant` on `scene` (from [`TwoArmTask::scene`]; each
    /// worker makes its own environment, the scene is shared).
    ///
    /// # Errors
    /// [`SimError::MissingName`] when the scene lacks the second arm or a site or geom the task
    /// reads.
    pub fn new(scene: Arc<Scene>, task: TwoArmTask, variant: &str) -> Result<Self, SimError> {
        let second = scene.second_robot.clone().ok_or_else(|| SimError::MissingName {
            file: scene.origin.clone(),
            kind: "body".to_owned(),
            name: "robot1_base".to_owned(),
        })?;
        let indices = TaskIndices::resolve(task, &scene)?;
        let table_site = task.table_site();
        let table_top_site = scene.model.name_to_id(MjtObjBase::mjOBJ_SITE, table_site).ok_or_else(|| SimError::MissingName {
            file: scene.origin.clone(),
            kind: "site".to_owned(),
            name: table_site.to_owned(),
        })?;
        let robots = [scene.robot.clone(), second];
        let nv = usize::try_from(scene.model.ffi().nv).unwrap_or_default();
        let osc = |r: &RobotIndices| Osc::new(OscConfig::default(), r.model.init_qpos.to_vec(), nv);
        let oscs = [osc(&robots[0]), osc(&robots[1])];
        let data = MjData::new(Arc::clone(&scene.model));
        Ok(Self {
            state: SimState { scene, data, ever: Vec::new() },
            task,
            variant: variant.to_owned(),
            indices,
            table_top_site,
            robots,
            oscs,
            gripper_commands: [[0.0; 2]; 2],
            warnings_seen: 0,
        })
    }

    /// The task.
    #[must_use]
    pub fn task(&self) -> TwoArmTask {
        self.task
    }

    /// The simulated physics.
    #[must_use]
    pub fn physics(&self) -> &SimState {
        &self.state
    }

    /// The scene's MJCF (robosuite's, local asset paths): the `model_file` of its episodes.
    #[must_use]
    pub fn model_xml(&self) -> &str {
        &self.state.scene.xml
    }

    /// The table top's height (m).
    fn table_z(&self) -> f64 {
        self.state.data.site_xpos()[self.table_top_site][2]
    }

    /// How high over the table the task's object is, as its success reads it (m): the pot's
    /// bottom; the hammer's handle, lowered by its tilt (robosuite's `_get_task_info`).
    fn object_height_m(&self) -> f64 {
        let data = &self.state.data;
        match &self.indices {
            TaskIndices::Lift { center_site, .. } => data.site_xpos()[*center_site][2] - POT_HALF_HEIGHT_M - self.table_z(),
            TaskIndices::Handover { handle, handle_half_length_m, handle_radius_m, head_half_size_m } => {
                let axis = self.state.object_pose(0).rotation * Vec3::z();
                let angle = std::f64::consts::FRAC_PI_2 - axis.z.clamp(-1.0, 1.0).acos();
                let tilt = (handle_half_length_m + 2.0 * head_half_size_m) * angle.sin();
                data.geom_xpos()[*handle][2] - handle_radius_m - tilt - self.table_z()
            }
            TaskIndices::Transport(_) => self.state.object_pose(0).translation.z - self.table_z(),
        }
    }

    /// Whether arm 0 grasps any part of the hammer and arm 1 its handle (robosuite's checks).
    fn handover_grasps(&self) -> (bool, bool) {
        let TaskIndices::Handover { handle, .. } = &self.indices else { return (false, false) };
        (self.state.grasps(&self.robots[0], &self.state.scene.objects[0].geoms), self.state.grasps(&self.robots[1], &[*handle]))
    }

    /// robosuite's observations now: each arm's (`robot0_*`, `robot1_*`) and `object` as the
    /// task's `object-state` orders it: Two Arm Lift the pot's position and `xyzw` quaternion,
    /// both handles' positions, each handle from its arm's gripper; Two Arm Handover the hammer's
    /// position and quaternion, its handle's position, the handle from each gripper; Two Arm
    /// Transport as `transport.rs` says.
    #[must_use]
    pub fn observation(&self) -> BTreeMap<String, Vec<f64>> {
        let mut obs = BTreeMap::new();
        for (arm, robot) in self.robots.iter().enumerate() {
            obs.extend(arm_observation(&self.state, robot, &format!("robot{arm}_")));
        }
        let data = &self.state.data;
        let eef = |arm: usize| data.site_xpos()[self.robots[arm].eef_site];
        let from_eef = |point: [f64; 3], arm: usize| (0..3).map(move |i| point[i] - eef(arm)[i]);
        // The task object's position and `xyzw` quaternion, with which Lift's and Handover's start.
        let object_pose = || {
            let pose = self.state.object_pose(0);
            let mut object: Vec<f64> = pose.translation.vector.iter().copied().collect();
            object.extend(quat_to_xyzw(&pose.rotation));
            object
        };
        let object = match &self.indices {
            TaskIndices::Lift { handle_sites, .. } => {
                let mut object = object_pose();
                let handle = |k: usize| data.site_xpos()[handle_sites[k]];
                object.extend(handle(0));
                object.extend(handle(1));
                for k in 0..2 {
                    object.extend(from_eef(handle(k), k));
                }
                object
            }
            TaskIndices::Handover { handle, .. } => {
                let mut object = object_pose();
                let handle = data.geom_xpos()[*handle];
                object.extend(handle);
                for arm in 0..2 {
                    object.extend(from_eef(handle, arm));
                }
                object
            }
            TaskIndices::Transport(transport) => transport.object_observation(&self.state, &self.robots),
        };
        obs.insert("object".to_owned(), object);
        obs
    }

    /// Observations for every recorded state, as `(per-step shape, values)` per key. Leaves the
    /// environment in the last state.
    ///
    /// # Errors
    /// [`EnvError::Fatal`] on a state of the wrong length.
    pub fn observations_for_states(&mut self, states: &Rows) -> Result<BTreeMap<String, Observation>, EnvError> {
        let mut out: BTreeMap<String, Observation> = BTreeMap::new();
        for state in states.iter() {
            self.set_state(state)?;
            for (key, value) in self.observation() {
                let entry = out.entry(key).or_insert_with(|| (vec![value.len()], Vec::with_capacity(value.len() * states.len())));
                entry.1.extend(value);
            }
        }
        Ok(out)
    }

    /// Restores a flattened robosuite state (`[time, qpos, qvel]`).
    ///
    /// # Errors
    /// [`EnvError::Fatal`] on a state of the wrong length.
    pub fn set_state(&mut self, state: &[f64]) -> Result<(), EnvError> {
        self.state.set_flat_state(state)
    }

    /// The task's objects' placements, drawn as robosuite's reset draws them (in `variant`'s
    /// range): `(object index, world_from_object)`.
    fn sample_scene(&self, rng: &mut dyn RngCore) -> Vec<(usize, Pose)> {
        match &self.indices {
            TaskIndices::Lift { .. } => vec![(
                0,
                self.on_table(rng, POT_HALF_HEIGHT_M, |rng| {
                    Rot::from_axis_angle(&Vec3::z_axis(), rng.random_range(PI - PI / 3.0..=PI + PI / 3.0))
                }),
            )],
            TaskIndices::Handover { handle_radius_m, .. } => vec![(
                0,
                self.on_table(rng, *handle_radius_m, |rng| {
                    let angle = rng.random_range(0.0..2.0 * PI);
                    robosuite_hammer_quat(angle, rng.random_bool(0.5))
                }),
            )],
            TaskIndices::Transport(transport) => transport.placements(&self.state, &self.variant, rng),
        }
    }

    /// Lift's and Handover's one object on the table, `z` over it: x and y drawn in `variant`'s
    /// range first, then its turn.
    fn on_table(&self, rng: &mut dyn RngCore, z: f64, turn: impl FnOnce(&mut dyn RngCore) -> Rot) -> Pose {
        let ([x0, x1], [y0, y1]) = self.task.placement(&self.variant);
        let (x, y) = (rng.random_range(x0..=x1), rng.random_range(y0..=y1));
        let table = self.state.data.site_xpos()[self.table_top_site];
        pose_from_parts(Vec3::new(table[0] + x, table[1] + y, table[2] + z), turn(rng))
    }
}

impl TwoArmEnvironment for TwoArmSimEnv {
    fn reset(&mut self, rng: &mut dyn RngCore) -> Result<(), EnvError> {
        self.state.data.reset();
        self.state.data.forward();
        self.warnings_seen = 0;
        let noise = Normal::new(0.0, ARM_INIT_NOISE).map_err(|e| EnvError::Fatal { reason: e.to_string() })?;
        for (robot, osc) in self.robots.iter().zip(&mut self.oscs) {
            let arm: Vec<f64> = robot.model.init_qpos.iter().map(|q| q + noise.sample(rng)).collect();
            let qpos = self.state.data.qpos_mut();
            for (adr, q) in robot.arm_qpos.iter().zip(&arm) {
                qpos[*adr] = *q;
            }
            for (adr, q) in robot.finger_qpos.iter().zip(robot.model.finger_init_qpos.iter().copied()) {
                qpos[*adr] = q;
            }
            osc.initial_joint = arm;
        }
        for (i, world_from_object) in self.sample_scene(rng) {
            let object = &self.state.scene.objects[i];
            if let (Some(q), Some(v)) = (object.qpos_adr, object.dof_adr) {
                let t = world_from_object.translation.vector;
                let w = mimicgen_engine::pose::quat_to_wxyz(&world_from_object.rotation);
                let qpos = self.state.data.qpos_mut();
                qpos[q..q + 3].copy_from_slice(t.as_slice());
                qpos[q + 3..q + 7].copy_from_slice(&w);
                self.state.data.qvel_mut()[v..v + 6].fill(0.0);
            }
        }
        self.state.data.forward();
        self.gripper_commands = [[0.0; 2]; 2];
        Ok(())
    }

    fn eef_pose(&self, arm: usize) -> Pose {
        self.robots.get(arm).map_or_else(Pose::identity, |r| self.state.eef_pose_of(r))
    }

    fn object_poses(&self) -> BTreeMap<String, Pose> {
        (0..self.state.scene.objects.len()).map(|i| (self.state.scene.objects[i].name.clone(), self.state.object_pose(i))).collect()
    }

    fn subtask_term_signals(&self) -> BTreeMap<String, i64> {
        match &self.indices {
            TaskIndices::Lift { handle_geoms, .. } => {
                (0..2).map(|k| (format!("grasp_handle{k}"), i64::from(self.state.grasps(&self.robots[k], &handle_geoms[k])))).collect()
            }
            TaskIndices::Handover { .. } => {
                let (arm0_holds, arm1_holds_handle) = self.handover_grasps();
                let at = self.state.object_pose(0).translation.vector;
                let height = at.z - self.table_z();
                let near = (at.x - HANDOVER_XY_M[0]).hypot(at.y - HANDOVER_XY_M[1]) < HANDOVER_TOLERANCE_M;
                BTreeMap::from([
                    ("lift".to_owned(), i64::from(arm0_holds && height > 0.08)),
                    ("at_handover".to_owned(), i64::from(near && height > HANDOVER_HEIGHT_M)),
                    ("handle_grasp".to_owned(), i64::from(arm1_holds_handle)),
                ])
            }
            TaskIndices::Transport(transport) => transport.signals(&self.state, &self.robots),
        }
    }

    fn is_success(&self) -> bool {
        match &self.indices {
            TaskIndices::Lift { .. } => self.object_height_m() > LIFT_M,
            TaskIndices::Handover { .. } => {
                let (arm0_holds, arm1_holds_handle) = self.handover_grasps();
                arm1_holds_handle && !arm0_holds && self.object_height_m() > HANDOVER_SUCCESS_M
            }
            TaskIndices::Transport(transport) => transport.is_success(&self.state),
        }
    }

    fn unmet_success(&self) -> Option<String> {
        let unmet: Vec<String> = match &self.indices {
            TaskIndices::Lift { .. } => {
                let height = self.object_height_m();
                (height <= LIFT_M)
                    .then(|| format!("the pot's bottom is {height:.3} m over the table, not over {LIFT_M:.2} m"))
                    .into_iter()
                    .collect()
            }
            TaskIndices::Handover { .. } => {
                let height = self.object_height_m();
                let (arm0_holds, arm1_holds_handle) = self.handover_grasps();
                [
                    (!arm1_holds_handle).then(|| "arm 1 does not hold the handle".to_owned()),
                    arm0_holds.then(|| "arm 0 still holds the hammer".to_owned()),
                    (height <= HANDOVER_SUCCESS_M)
                        .then(|| format!("the hammer is {height:.3} m over the table, not over {HANDOVER_SUCCESS_M:.2} m")),
                ]
                .into_iter()
                .flatten()
                .collect()
            }
            TaskIndices::Transport(transport) => transport.unmet_success(&self.state),
        };
        (!unmet.is_empty()).then(|| unmet.join("; "))
    }

    fn target_pose_to_action(&self, arm: usize, world_from_target: &Pose) -> [f64; 6] {
        self.oscs[arm.min(1)].scale().action_from_target(&self.eef_pose(arm), world_from_target)
    }

    fn action_to_target_pose(&self, arm: usize, arm_action: &[f64]) -> Pose {
        // Clipped as the controller clips it (see `SimEnv`'s).
        let mut a = [0.0; 6];
        for (dst, src) in a.iter_mut().zip(arm_action) {
            *dst = src.clamp(-1.0, 1.0);
        }
        DeltaPoseScale::target_from_action(&self.oscs[arm.min(1)].scale(), &self.eef_pose(arm), &a)
    }

    fn gripper_dim(&self, _arm: usize) -> usize {
        1
    }

    fn step(&mut self, action: &[f64]) -> Result<(), EnvError> {
        if action.len() != 14 || action.iter().any(|a| !a.is_finite()) {
            return Err(EnvError::Unstable { reason: format!("action {action:?} is not 14 finite numbers (7 per arm)") });
        }
        self.state.data.forward();
        for (arm, (osc, robot)) in self.oscs.iter_mut().zip(&self.robots).enumerate() {
            osc.set_goal(&self.state.data, robot, &action[7 * arm..7 * arm + 7]);
        }
        for _ in 0..self.state.scene.substeps {
            self.state.data.step1();
            for arm in 0..2 {
                let torques = self.oscs[arm].torques(&self.state.data, &self.robots[arm]);
                drive_arm(&mut self.state.data, &torques, &self.robots[arm], &mut self.gripper_commands[arm], action[7 * arm + 6]);
            }
            self.state.data.step2();
            check_stable(&self.state.data, &mut self.warnings_seen)?;
        }
        self.state.data.forward();
        Ok(())
    }

    fn state(&self) -> Vec<f64> {
        self.state.flat_state()
    }
}
