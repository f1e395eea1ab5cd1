//! A MuJoCo environment that steps like robosuite (20 Hz OSC_POSE over 2 ms physics steps) and
//! implements the engine's [`Environment`].
#![allow(
    clippy::indexing_slicing,
    reason = "MuJoCo ids and addresses come from the compiled model (name_to_id, a Scene's names resolved once) and index that model's own arrays; states and actions are checked for length where they come in (set_state, step)"
)]

use std::collections::BTreeMap;
use std::sync::Arc;

use mimicgen_engine::action::DeltaPoseScale;
use mimicgen_engine::base::{BASE_ACTION_DIM, MobileBase};
use mimicgen_engine::pose::{Pose, quat_to_wxyz};
use mimicgen_engine::transit::TransitSpace;
use mimicgen_engine::{EnvError, Environment};
use mujoco_rs::prelude::*;
use rand::{Rng as _, RngCore};
use rand_distr::{Distribution, Normal};

use crate::osc::{Osc, OscConfig};
use crate::scene::Scene;
use crate::state::SimState;
use crate::task::Task;
use crate::transit::{ArmSpace, Planning, robot_geoms};

/// robosuite's Panda gripper: the command moves by this much per physics step towards -1 / +1.
const GRIPPER_SPEED: f64 = 0.01;
/// robosuite's default initialisation noise on the arm joints (Gaussian std, rad).
pub(crate) const ARM_INIT_NOISE: f64 = 0.02;

/// One observation stream: per-step shape, then every step's values row-major.
pub type Observation = (Vec<usize>, Vec<f64>);

/// MuJoCo's warning kinds, in `mjtWarning` order.
const WARNING_NAMES: [&str; 8] = ["INERTIA", "CONTACTFULL", "CNSTRFULL", "VGEOMFULL", "BADQPOS", "BADQVEL", "BADQACC", "BADCTRL"];

/// Puts mocap body `mocap` of `data` at `world_from_body` (position and `wxyz` quaternion).
pub fn set_mocap_pose(data: &mut MjData<Arc<MjModel>>, mocap: usize, world_from_body: &Pose) {
    let t = world_from_body.translation.vector;
    data.mocap_pos_mut()[mocap] = [t.x, t.y, t.z];
    data.mocap_quat_mut()[mocap] = quat_to_wxyz(&world_from_body.rotation);
}

/// Per geom of `scene`: which side of an obstacle contact it is on (see `SimEnv::obstacle_side`);
/// empty for a task without obstacles, so that counting costs its steps nothing.
fn obstacle_sides(scene: &Scene, task: &dyn Task) -> Vec<Option<bool>> {
    let obstacles = task.obstacles();
    if obstacles.is_empty() {
        return Vec::new();
    }
    let mut sides: Vec<Option<bool>> = robot_geoms(scene).into_iter().map(|robot| robot.then_some(false)).collect();
    for (i, object) in scene.objects.iter().enumerate() {
        for &g in &object.geoms {
            if let Some(side) = sides.get_mut(g) {
                *side = Some(obstacles.contains(&i));
            }
        }
    }
    sides
}

/// One robosuite-like environment: a scene, its MuJoCo data, the controller and the task.
pub struct SimEnv {
    state: SimState,
    task: Arc<dyn Task>,
    osc: Osc,
    gripper_command: [f64; 2],
    warnings_seen: i64,
    control_log: Option<Vec<f64>>,
    /// Scratch for the joint-position controller's mass matrix.
    full_m: Vec<f64>,
    /// The object instances resets draw among (`(label, scene)`), and the one in use.
    instances: Vec<(String, Arc<Scene>)>,
    instance: usize,
    /// The planning model for transits, made at the first one.
    planning: Option<Planning>,
    /// Per geom: `Some(true)` an obstacle's, `Some(false)` the robot's or a task object's, `None`
    /// anything else (the table, the walls); empty when the task has no obstacles.
    obstacle_side: Vec<Option<bool>>,
}

impl std::fmt::Debug for SimEnv {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SimEnv").field("scene", &self.state.scene.origin).field("task", &self.task.name()).finish_non_exhaustive()
    }
}

impl SimEnv {
    /// An environment on `scene` for `task` (each worker makes its own; the scene is shared).
    #[must_use]
    pub fn new(scene: Arc<Scene>, task: Arc<dyn Task>) -> Self {
        let data = MjData::new(Arc::clone(&scene.model));
        let nv = usize::try_from(scene.model.ffi().nv).unwrap_or_default();
        let osc = Osc::new(OscConfig::default(), scene.robot.model.init_qpos.to_vec(), nv);
        let obstacle_side = obstacle_sides(&scene, task.as_ref());
        Self {
            state: SimState { scene, data, ever: Vec::new() },
            task,
            osc,
            gripper_command: [0.0; 2],
            warnings_seen: 0,
            control_log: None,
            full_m: Vec::new(),
            instances: Vec::new(),
            instance: 0,
            planning: None,
            obstacle_side,
        }
    }

    /// This environment drawing one of `instances` (`(label, scene)`, from
    /// [`Scene::instances_for_task`]) at every reset, starting in the first: the paper's object
    /// transfer. Every scene must hold the same robot and joints.
    #[must_use]
    pub fn with_instances(mut self, instances: Vec<(String, Arc<Scene>)>) -> Self {
        self.instances = instances;
        self.use_instance(0);
        self
    }

    /// The label of the object instance in use; `None` without instances.
    #[must_use]
    pub fn instance(&self) -> Option<&str> {
        self.instances.get(self.instance).map(|(label, _)| label.as_str())
    }

    fn use_instance(&mut self, k: usize) {
        if let Some((_, scene)) = self.instances.get(k) {
            if !Arc::ptr_eq(scene, &self.state.scene) {
                self.state.scene = Arc::clone(scene);
                self.state.data = MjData::new(Arc::clone(&self.state.scene.model));
                self.obstacle_side = obstacle_sides(&self.state.scene, self.task.as_ref());
            }
            self.instance = k;
        }
    }

    /// The simulated physics: the scene and its MuJoCo data, with what they tell (poses,
    /// contacts, grasps). (The flattened robosuite state is [`Environment::state`].)
    #[must_use]
    pub fn physics(&self) -> &SimState {
        &self.state
    }

    /// Restores a recorded robosuite state as robomimic's `reset_to` does with a model: the
    /// gripper command and controller posture start from their reset values.
    ///
    /// # Errors
    /// [`EnvError::Fatal`] on a state of the wrong length.
    pub fn reset_to_state(&mut self, state: &[f64]) -> Result<(), EnvError> {
        self.gripper_command = [0.0; 2];
        self.osc.initial_joint = self.state.scene.robot.model.init_qpos.to_vec();
        self.state.ever.clear();
        self.set_state(state)
    }

    /// Notes what the task remembers of the episode (its `ever` conditions) in the present
    /// state, as every step does: for stored states restored one by one, as robomimic's
    /// `reset_to` then `is_success` would.
    pub fn record_history(&mut self) {
        self.task.record_history(&mut self.state);
    }

    /// Makes the arm's present joint positions the controller's null-space posture, as a reset
    /// does: after [`SimEnv::reset_to_state`] with an attempt's first state, the controller is the
    /// one that attempt ran with.
    pub fn hold_posture_here(&mut self) {
        let qpos = self.state.data.qpos();
        self.osc.initial_joint = self.state.scene.robot.arm_qpos.iter().map(|&i| qpos[i]).collect();
    }

    /// The arm's configuration space from the present state, carrying the objects the gripper
    /// grasps (what planned transit plans in).
    pub fn arm_space(&mut self) -> ArmSpace<'_> {
        let held: Vec<usize> = (0..self.state.scene.objects.len()).filter(|&i| self.state.is_grasping(i)).collect();
        if !self.planning.as_ref().is_some_and(|p| p.is_for(&self.state.scene)) {
            self.planning = None;
        }
        let planning = self.planning.get_or_insert_with(|| Planning::new(&self.state.scene));
        ArmSpace::new(&self.state.scene, planning, &self.state.data, &held, &self.osc.initial_joint)
    }

    /// Places object `i` at `world_from_object`: at rest for an object with a free joint; a fixed
    /// (mocap) object moves there and stays. Call `forward` (or step) before reading poses.
    pub fn place_object(&mut self, i: usize, world_from_object: &Pose) {
        let object = &self.state.scene.objects[i];
        if let (Some(q), Some(v)) = (object.qpos_adr, object.dof_adr) {
            let t = world_from_object.translation.vector;
            let w = quat_to_wxyz(&world_from_object.rotation);
            let qpos = self.state.data.qpos_mut();
            qpos[q..q + 3].copy_from_slice(t.as_slice());
            qpos[q + 3..q + 7].copy_from_slice(&w);
            self.state.data.qvel_mut()[v..v + 6].fill(0.0);
        } else if let Some(m) = object.mocap {
            set_mocap_pose(&mut self.state.data, m, world_from_object);
        }
    }

    /// Puts the fixed (mocap) objects where `world_from_objects` (by object name) has them: the
    /// part of a scene robosuite's flattened state does not hold. Objects not named stay.
    pub fn place_fixed_objects(&mut self, world_from_objects: &BTreeMap<String, Pose>) {
        for i in 0..self.state.scene.objects.len() {
            if let Some(pose) = world_from_objects.get(&self.state.scene.objects[i].name)
                && self.state.scene.objects[i].mocap.is_some()
            {
                self.place_object(i, pose);
            }
        }
        self.state.data.forward();
    }

    /// robosuite's low-dim observations in the current state, keyed as robomimic expects
    /// (`robot0_eef_pos`, `robot0_eef_quat` in `xyzw`, `object`, ...).
    #[must_use]
    pub fn observation(&self) -> BTreeMap<String, Vec<f64>> {
        let mut obs = arm_observation(&self.state, &self.state.scene.robot, "robot0_");
        obs.insert("object".to_owned(), self.task.object_obs(&self.state));
        if let Some(base) = &self.state.scene.base {
            // robosuite 1.5's mobile robots' keys: the base in the world, the hand on the base.
            let world_from_base = base.world_from_base(&self.state.data);
            let base_from_eef = world_from_base.inverse() * self.state.eef_pose();
            let xyzw = |q: [f64; 4]| vec![q[1], q[2], q[3], q[0]];
            obs.insert("robot0_base_pos".to_owned(), world_from_base.translation.vector.as_slice().to_vec());
            obs.insert("robot0_base_quat".to_owned(), xyzw(quat_to_wxyz(&world_from_base.rotation)));
            obs.insert("robot0_base_to_eef_pos".to_owned(), base_from_eef.translation.vector.as_slice().to_vec());
            obs.insert("robot0_base_to_eef_quat".to_owned(), xyzw(quat_to_wxyz(&base_from_eef.rotation)));
        }
        obs
    }

    /// Observations for every recorded state, as `(per-step shape, values)` per key. Leaves the
    /// environment in the last state.
    ///
    /// # Errors
    /// [`EnvError::Fatal`] on a state of the wrong length.
    pub fn observations_for_states(&mut self, states: &mimicgen_engine::Rows) -> Result<BTreeMap<String, Observation>, EnvError> {
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

    /// The absolute form of recorded delta-pose actions (`actions_abs`): per step, the target
    /// the controller servoed to from that step's state (position, rotation as an axis-angle
    /// vector, both in the world frame), then the rest of the action as it was (gripper; a base's
    /// three), as robomimic's `robosuite_add_absolute_actions.py` computes it. Leaves the
    /// environment in the last state.
    ///
    /// # Errors
    /// [`EnvError::Fatal`] on a state of the wrong length or fewer states than actions.
    pub fn absolute_actions(
        &mut self,
        states: &mimicgen_engine::Rows,
        actions: &mimicgen_engine::Rows,
    ) -> Result<mimicgen_engine::Rows, EnvError> {
        if states.len() < actions.len() {
            return Err(EnvError::Fatal { reason: format!("{} states for {} actions", states.len(), actions.len()) });
        }
        let mut out = mimicgen_engine::Rows::new(actions.width());
        for (state, action) in states.iter().zip(actions.iter()) {
            self.set_state(state)?;
            let target = self.action_to_target_pose(action);
            let mut row = Vec::with_capacity(action.len());
            row.extend_from_slice(target.translation.vector.as_slice());
            row.extend_from_slice(target.rotation.scaled_axis().as_slice());
            row.extend_from_slice(action.get(6..).unwrap_or_default());
            out.push(&row).map_err(|e| EnvError::Fatal { reason: e.to_string() })?;
        }
        Ok(out)
    }

    /// Joint-position actions (`actions_joint`) for recorded states and delta-pose actions: per
    /// step, the arm's joint positions at the next recorded state (the last step holds its own),
    /// then the rest of the action as it was (gripper). [`SimEnv::step_joint`] replays them.
    ///
    /// # Errors
    /// [`EnvError::Fatal`] on fewer states than actions or a state too short for the arm.
    pub fn joint_actions(
        &self,
        states: &mimicgen_engine::Rows,
        actions: &mimicgen_engine::Rows,
    ) -> Result<mimicgen_engine::Rows, EnvError> {
        if states.len() < actions.len() || actions.is_empty() {
            return Err(EnvError::Fatal { reason: format!("{} states for {} actions", states.len(), actions.len()) });
        }
        let arm = &self.state.scene.robot.arm_qpos;
        let width = arm.len() + actions.width().saturating_sub(6);
        let mut out = mimicgen_engine::Rows::new(width);
        for (t, action) in actions.iter().enumerate() {
            let next = states.row((t + 1).min(actions.len() - 1));
            let mut row: Vec<f64> = arm.iter().map(|&i| SimState::qpos_in_flat(next, i)).collect::<Option<_>>().ok_or_else(|| {
                EnvError::Fatal { reason: format!("state {} has {} values, too few for the arm's joints", t + 1, next.len()) }
            })?;
            row.extend_from_slice(action.get(6..).unwrap_or_default());
            out.push(&row).map_err(|e| EnvError::Fatal { reason: e.to_string() })?;
        }
        Ok(out)
    }

    /// One control step from an `actions_joint` row: the arm's joint-position targets, then the
    /// gripper action, under [`crate::joint_control`]'s controller.
    ///
    /// # Errors
    /// [`EnvError::Unstable`] on a row of the wrong length or with a NaN, or when the simulation
    /// fails; [`EnvError::Fatal`] for an arm on a mobile base.
    pub fn step_joint(&mut self, action: &[f64]) -> Result<(), EnvError> {
        if self.state.scene.base.is_some() {
            return Err(EnvError::Fatal { reason: "joint-position actions drive a fixed arm; this arm rides a mobile base".into() });
        }
        let robot = &self.state.scene.robot;
        let n = robot.arm_qpos.len();
        if action.len() != n + 1 || action.iter().any(|a| !a.is_finite()) {
            return Err(EnvError::Unstable { reason: format!("joint action {action:?} is not {} finite numbers", n + 1) });
        }
        self.state.data.forward();
        let qpos = self.state.data.qpos();
        let goal = crate::joint_control::JointGoal {
            start: robot.arm_qpos.iter().map(|&i| qpos[i]).collect(),
            target: action[..n].to_vec(),
            substeps: self.state.scene.substeps,
        };
        #[allow(clippy::cast_precision_loss)] // a step count
        let period = self.state.scene.model.opt().timestep * goal.substeps as f64;
        for k in 1..=goal.substeps {
            let (q, dq) = goal.at(k, period);
            self.physics_step(action[n], Some((&q, &dq)))?;
        }
        self.state.data.forward();
        self.task.record_history(&mut self.state);
        Ok(())
    }

    /// Camera images for every recorded state (see [`crate::camera`]), keyed `<camera>_image`
    /// (and `<camera>_depth`). Leaves the environment in the last state.
    ///
    /// # Errors
    /// [`EnvError::Fatal`] on a state of the wrong length or when rendering fails.
    pub fn images_for_states(
        &mut self,
        states: &mimicgen_engine::Rows,
        cameras: &crate::camera::Cameras,
    ) -> Result<BTreeMap<String, crate::camera::ImageStream>, EnvError> {
        let mut out = cameras.streams(states.len());
        for state in states.iter() {
            self.set_state(state)?;
            cameras.capture(&self.state.data, &mut out).map_err(|e| EnvError::Fatal { reason: e.to_string() })?;
        }
        Ok(out)
    }

    /// Starts (or stops, with `false`) recording the controls applied at every physics step, so a
    /// benchmark can replay exactly the same physics with no controller around it.
    pub fn record_controls(&mut self, on: bool) {
        self.control_log = on.then(Vec::new);
    }

    /// The controls recorded since [`SimEnv::record_controls`], `nu` values per physics step.
    pub fn take_controls(&mut self) -> Vec<f64> {
        self.control_log.as_mut().map(std::mem::take).unwrap_or_default()
    }

    /// Bare MuJoCo: restores `state` and runs `mj_step` once per recorded control vector, with no
    /// controller, recording or checks. The baseline generation is measured against.
    ///
    /// # Errors
    /// [`EnvError::Fatal`] on a state of the wrong length.
    pub fn replay_controls_bare(&mut self, state: &[f64], controls: &[f64]) -> Result<(), EnvError> {
        self.set_state(state)?;
        let nu = self.state.data.ctrl().len().max(1);
        for ctrl in controls.chunks(nu) {
            self.state.data.ctrl_mut().copy_from_slice(ctrl);
            self.state.data.step();
        }
        Ok(())
    }

    /// One physics step, the arm driven by the OSC, or towards `joint_goal` (position and
    /// velocity per arm joint) when given.
    fn physics_step(&mut self, gripper_action: f64, joint_goal: Option<(&[f64], &[f64])>) -> Result<(), EnvError> {
        // robosuite runs mj_forward, sets controls, then mj_step. With the Euler integrator,
        // mj_step1 + controls + mj_step2 computes the same thing without the second forward pass.
        self.state.data.step1();
        let robot = &self.state.scene.robot;
        let torques = match joint_goal {
            None => self.osc.torques(&self.state.data, robot),
            Some((q, dq)) => crate::joint_control::joint_torques(&self.state.data, robot, q, dq, &mut self.full_m),
        };
        drive_arm(&mut self.state.data, &torques, robot, &mut self.gripper_command, gripper_action);
        if let Some(log) = self.control_log.as_mut() {
            log.extend_from_slice(self.state.data.ctrl());
        }
        self.state.data.step2();
        check_stable(&self.state.data, &mut self.warnings_seen)
    }
}

/// Sets `robot`'s controls for one physics step: the controller's torques for the present state
/// (`data` after `mj_step1`) and the gripper's command moved one step towards `gripper_action`'s
/// sign, as robosuite's Panda gripper moves it.
pub(crate) fn drive_arm(
    data: &mut MjData<Arc<MjModel>>,
    torques: &[f64],
    robot: &crate::scene::RobotIndices,
    gripper_command: &mut [f64; 2],
    gripper_action: f64,
) {
    let sign = if gripper_action > 0.0 {
        1.0
    } else if gripper_action < 0.0 {
        -1.0
    } else {
        0.0
    };
    for (command, direction) in gripper_command.iter_mut().zip(robot.model.close_direction) {
        *command = (*command + direction * GRIPPER_SPEED * sign).clamp(-1.0, 1.0);
    }
    let ctrl = data.ctrl_mut();
    for ((a, [lo, hi]), tau) in robot.arm_actuators.iter().zip(torques.iter().copied()) {
        ctrl[*a] = tau.clamp(*lo, *hi);
    }
    for ((a, [lo, hi]), command) in robot.finger_actuators.iter().zip(gripper_command.iter()) {
        ctrl[*a] = 0.5 * (hi + lo) + 0.5 * (hi - lo) * command;
    }
}

/// [`EnvError::Unstable`] when MuJoCo warned since `warnings_seen` warnings (which it then
/// counts) or the state is no longer finite.
pub(crate) fn check_stable(data: &MjData<Arc<MjModel>>, warnings_seen: &mut i64) -> Result<(), EnvError> {
    let warnings: i64 = data.warning().iter().map(|w| i64::from(w.number)).sum();
    if warnings > *warnings_seen {
        *warnings_seen = warnings;
        let kinds: Vec<String> = data
            .warning()
            .iter()
            .enumerate()
            .filter(|(_, w)| w.number > 0)
            .map(|(i, w)| format!("{} (x{})", WARNING_NAMES.get(i).unwrap_or(&"warning"), w.number))
            .collect();
        return Err(EnvError::Unstable { reason: format!("MuJoCo {} at t = {:.3} s", kinds.join(", "), data.time()) });
    }
    if data.qpos().iter().chain(data.qvel()).any(|v| !v.is_finite()) {
        return Err(EnvError::Unstable { reason: format!("non-finite state at t = {:.3} s", data.time()) });
    }
    Ok(())
}

/// robosuite's proprioceptive observations of `robot`, keyed with `prefix` (`robot0_eef_pos`,
/// `robot0_eef_quat` in `xyzw`, ...).
pub(crate) fn arm_observation(state: &SimState, robot: &crate::scene::RobotIndices, prefix: &str) -> BTreeMap<String, Vec<f64>> {
    let (qpos, qvel) = (state.data.qpos(), state.data.qvel());
    let joint_pos: Vec<f64> = robot.arm_qpos.iter().map(|&i| qpos[i]).collect();
    let site = robot.eef_site;
    let (jacp, jacr) = state.data.jac_site(true, true, site);
    let nv = qvel.len();
    let twist = |jac: &[f64]| -> Vec<f64> { (0..3).map(|r| (0..nv).map(|c| jac[r * nv + c] * qvel[c]).sum()).collect() };
    let hand = state.data.xquat()[robot.hand_body];
    let key = |name: &str| format!("{prefix}{name}");
    BTreeMap::from([
        (key("eef_pos"), state.data.site_xpos()[site].to_vec()),
        (key("eef_quat"), vec![hand[1], hand[2], hand[3], hand[0]]),
        (key("eef_vel_ang"), twist(&jacr)),
        (key("eef_vel_lin"), twist(&jacp)),
        (key("gripper_qpos"), robot.finger_qpos.iter().map(|&i| qpos[i]).collect()),
        (key("gripper_qvel"), robot.finger_dof.iter().map(|&i| qvel[i]).collect()),
        (key("joint_pos_cos"), joint_pos.iter().map(|q| q.cos()).collect()),
        (key("joint_pos_sin"), joint_pos.iter().map(|q| q.sin()).collect()),
        (key("joint_vel"), robot.arm_dof.iter().map(|&i| qvel[i]).collect()),
        (key("joint_pos"), joint_pos),
    ])
}

impl Environment for SimEnv {
    fn object_instance(&self) -> Option<String> {
        self.instance().map(str::to_owned)
    }

    fn reset(&mut self, rng: &mut dyn RngCore) -> Result<(), EnvError> {
        if self.instances.len() > 1 {
            let k = rng.random_range(0..self.instances.len());
            self.use_instance(k);
        }
        self.state.data.reset();
        self.state.ever.clear();
        self.warnings_seen = 0;
        let noise = Normal::new(0.0, ARM_INIT_NOISE).map_err(|e| EnvError::Fatal { reason: e.to_string() })?;
        let robot = self.state.scene.robot.clone();
        let arm: Vec<f64> = robot.model.init_qpos.iter().map(|q| q + noise.sample(rng)).collect();
        {
            let qpos = self.state.data.qpos_mut();
            for (adr, q) in robot.arm_qpos.iter().zip(&arm) {
                qpos[*adr] = *q;
            }
            for (adr, q) in robot.finger_qpos.iter().zip(robot.model.finger_init_qpos.iter().copied()) {
                qpos[*adr] = q;
            }
        }
        let placements = self.task.sample_scene(rng, self.instance())?;
        for (i, pose) in placements.iter().enumerate() {
            self.place_object(i, pose);
        }
        self.state.data.forward();
        self.osc.initial_joint = arm;
        self.gripper_command = [0.0; 2];
        Ok(())
    }

    fn eef_pose(&self) -> Pose {
        self.state.eef_pose()
    }

    fn place_objects(&mut self, world_from_objects: &BTreeMap<String, Pose>) -> Result<(), EnvError> {
        for (name, pose) in world_from_objects {
            let i = self.state.scene.objects.iter().position(|o| &o.name == name).ok_or_else(|| EnvError::Fatal {
                reason: format!(
                    "no object {name:?} in the scene (it has {:?})",
                    self.state.scene.objects.iter().map(|o| &o.name).collect::<Vec<_>>()
                ),
            })?;
            self.place_object(i, pose);
        }
        self.state.data.forward();
        Ok(())
    }

    fn object_poses(&self) -> BTreeMap<String, Pose> {
        (0..self.state.scene.objects.len()).map(|i| (self.state.scene.objects[i].name.clone(), self.state.object_pose(i))).collect()
    }

    fn subtask_term_signals(&self) -> BTreeMap<String, i64> {
        self.task.signals(&self.state)
    }

    fn is_success(&self) -> bool {
        self.task.is_success(&self.state)
    }

    fn unmet_success(&self) -> Option<String> {
        self.task.unmet_success(&self.state)
    }

    fn target_pose_to_action(&self, world_from_target: &Pose) -> [f64; 6] {
        match &self.state.scene.base {
            None => self.osc.scale().action_from_target(&self.eef_pose(), world_from_target),
            // On a mobile base the pose part is in the base's frame.
            Some(base) => {
                let base_from_world = base.world_from_base(&self.state.data).inverse();
                self.osc.scale().action_from_target(&(base_from_world * self.eef_pose()), &(base_from_world * world_from_target))
            }
        }
    }

    fn action_to_target_pose(&self, action: &[f64]) -> Pose {
        // Clipped to [-1, 1] as the controller clips it: the target it really servoes to. (The
        // reference scales unclipped actions; teleoperated demos such as robosuite's Lift ones
        // hold actions up to 3.75, which would put targets 19 cm away from where the arm went.)
        let mut a = [0.0; 6];
        for (dst, src) in a.iter_mut().zip(action) {
            *dst = src.clamp(-1.0, 1.0);
        }
        match &self.state.scene.base {
            None => DeltaPoseScale::target_from_action(&self.osc.scale(), &self.eef_pose(), &a),
            Some(base) => {
                let world_from_base = base.world_from_base(&self.state.data);
                world_from_base * DeltaPoseScale::target_from_action(&self.osc.scale(), &(world_from_base.inverse() * self.eef_pose()), &a)
            }
        }
    }

    fn action_dim(&self) -> usize {
        if self.state.scene.base.is_some() { 7 + BASE_ACTION_DIM } else { 7 }
    }

    fn mobile_base(&self) -> Option<MobileBase> {
        let dt = self.state.scene.model.opt().timestep * f64::from(u32::try_from(self.state.scene.substeps).unwrap_or(1));
        self.state.scene.base.as_ref().map(|base| base.describe(&self.state.data, dt))
    }

    fn step(&mut self, action: &[f64]) -> Result<(), EnvError> {
        let dim = self.action_dim();
        if action.len() != dim || action.iter().any(|a| !a.is_finite()) {
            return Err(EnvError::Unstable { reason: format!("action {action:?} is not {dim} finite numbers") });
        }
        self.state.data.forward();
        let base = self.state.scene.base.clone();
        let Some(base) = base else {
            self.osc.set_goal(&self.state.data, &self.state.scene.robot, action);
            for _ in 0..self.state.scene.substeps {
                self.physics_step(action[6], None)?;
            }
            self.state.data.forward();
            self.task.record_history(&mut self.state);
            return Ok(());
        };
        // The arm's goal is set in the base's frame and rides with the base as it drives.
        let mut world_from_base = base.world_from_base(&self.state.data);
        self.osc.set_goal_in(&self.state.data, &self.state.scene.robot, action, &world_from_base.rotation);
        base.drive(&mut self.state.data, action.get(7..).unwrap_or_default());
        for _ in 0..self.state.scene.substeps {
            let now = base.world_from_base(&self.state.data);
            self.osc.move_goal(&(now * world_from_base.inverse()));
            world_from_base = now;
            self.physics_step(action[6], None)?;
        }
        self.state.data.forward();
        self.task.record_history(&mut self.state);
        Ok(())
    }

    fn transit_space(&mut self) -> Result<Box<dyn TransitSpace + '_>, EnvError> {
        Ok(Box::new(self.arm_space()))
    }

    fn obstacle_contacts(&self) -> usize {
        if self.obstacle_side.is_empty() {
            return 0;
        }
        let side = |g: i32| usize::try_from(g).ok().and_then(|g| self.obstacle_side.get(g).copied().flatten());
        self.state.data.contact().iter().filter(|c| matches!((side(c.geom[0]), side(c.geom[1])), (Some(a), Some(b)) if a != b)).count()
    }

    fn joints_at_limit(&self, state: &[f64], margin: f64) -> Vec<String> {
        let scene = &self.state.scene;
        let model = &scene.model;
        scene
            .robot
            .model
            .arm_joints
            .iter()
            .zip(&scene.robot.arm_qpos)
            .filter_map(|(name, &qpos)| {
                let q = SimState::qpos_in_flat(state, qpos)?;
                let joint = model.name_to_id(MjtObjBase::mjOBJ_JOINT, name)?;
                let [low, high] = *model.jnt_range().get(joint)?;
                let limited = model.jnt_limited().get(joint).copied().unwrap_or(false);
                (limited && (q - low < margin || high - q < margin)).then(|| (*name).to_owned())
            })
            .collect()
    }

    fn state(&self) -> Vec<f64> {
        self.state.flat_state()
    }

    fn set_state(&mut self, state: &[f64]) -> Result<(), EnvError> {
        self.state.set_flat_state(state)
    }
}
