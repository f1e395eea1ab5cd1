//! What the engine asks of a simulator, and no more (MimicGen's environment interface).

use std::collections::BTreeMap;

use rand::RngCore;

use crate::pose::Pose;
use crate::transit::TransitSpace;

/// Why an environment call failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum EnvError {
    /// The simulation became unusable for this attempt (NaN state, solver warning, blow-up); the
    /// attempt fails with this reason and the run goes on.
    #[error("simulation unstable: {reason}")]
    Unstable {
        /// What the simulator reported.
        reason: String,
    },
    /// A problem no further attempt can escape (bad model, missing name); the run stops.
    #[error("{reason}")]
    Fatal {
        /// What went wrong, naming the file or field.
        reason: String,
    },
}

/// Where a mobile base stands and how fast its actions move it (see the engine's `base` module).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MobileBase {
    /// The base's frame (the arm's mount): x forward, z up.
    pub world_from_base: Pose,
    /// Metres the base moves in one control step at a full forward or sideways command.
    pub max_step_m: f64,
    /// Radians it turns in one control step at a full turning command.
    pub max_turn_rad: f64,
}

/// A simulated scene the engine can reset, observe and drive with delta-pose actions.
///
/// Implementations own their simulator state; run several attempts in parallel by giving each
/// worker its own environment.
pub trait Environment {
    /// Samples a new scene from the task's reset distribution using `rng`, and resets to it.
    ///
    /// # Errors
    /// [`EnvError`] if the scene cannot be built.
    fn reset(&mut self, rng: &mut dyn RngCore) -> Result<(), EnvError>;

    /// Current end-effector pose `world_from_eef`.
    fn eef_pose(&self) -> Pose;

    /// Current `world_from_object` of every object the task names.
    fn object_poses(&self) -> BTreeMap<String, Pose>;

    /// Current value of every subtask-end signal (nonzero = on).
    fn subtask_term_signals(&self) -> BTreeMap<String, i64>;

    /// Whether the task is currently achieved.
    fn is_success(&self) -> bool;

    /// The parts of the success condition that do not hold now, in words (`coffee_pod in coffee_machine`),
    /// for failure reports; `None` when achieved or when the environment cannot say.
    fn unmet_success(&self) -> Option<String> {
        None
    }

    /// The label of the object instance this episode uses (the paper's object transfer: one mug
    /// of several drawn at reset); `None` for a task without instances.
    fn object_instance(&self) -> Option<String> {
        None
    }

    /// Pose part of the action that moves the controller towards `world_from_target`.
    fn target_pose_to_action(&self, world_from_target: &Pose) -> [f64; 6];

    /// Controller target pose implied by the pose part of `action` in the current state.
    fn action_to_target_pose(&self, action: &[f64]) -> Pose;

    /// Total action width: six pose dimensions, the gripper, then a mobile base's three for a
    /// robot on one.
    fn action_dim(&self) -> usize;

    /// The mobile base the arm stands on, `None` for an arm fixed in the world (the default).
    /// With a base, the pose part of an action is in the base's frame (the arm's target rides
    /// with the base) and the action ends with the base's velocity command.
    fn mobile_base(&self) -> Option<MobileBase> {
        None
    }

    /// Applies one action (one control step).
    ///
    /// # Errors
    /// [`EnvError::Unstable`] if the physics blew up.
    fn step(&mut self, action: &[f64]) -> Result<(), EnvError>;

    /// The flattened simulator state.
    fn state(&self) -> Vec<f64>;

    /// Moves the named objects to these poses (at rest), after a reset: a scene set by hand.
    ///
    /// # Errors
    /// [`EnvError::Fatal`] naming an object the scene does not have, or when the environment
    /// cannot place objects (the default).
    fn place_objects(&mut self, world_from_objects: &BTreeMap<String, Pose>) -> Result<(), EnvError> {
        match world_from_objects.keys().next() {
            Some(name) => Err(EnvError::Fatal { reason: format!("this environment cannot place objects (asked to move {name:?})") }),
            None => Ok(()),
        }
    }

    /// The configuration space for planning a transit from the present state: the robot's joints,
    /// collisions as the simulator sees them, with what the gripper holds carried along.
    ///
    /// # Errors
    /// [`EnvError::Fatal`] when the environment cannot plan (the default).
    fn transit_space(&mut self) -> Result<Box<dyn TransitSpace + '_>, EnvError> {
        Err(EnvError::Fatal { reason: "this environment cannot plan transit (use transit = \"interpolate\")".to_owned() })
    }

    /// How many contacts the robot, or what it holds, makes with the scene's obstacles now.
    fn obstacle_contacts(&self) -> usize {
        0
    }

    /// The arm's joints within `margin` (rad, or m for a sliding joint) of a limit in `state` (one
    /// of this environment's [`Environment::state`]s), by name; empty when it cannot tell, as by
    /// default. Failure causes name the joint that held a lagging arm back.
    fn joints_at_limit(&self, _state: &[f64], _margin: f64) -> Vec<String> {
        Vec::new()
    }

    /// Restores a state returned by [`Environment::state`].
    ///
    /// # Errors
    /// [`EnvError`] if the state has the wrong size or is rejected.
    fn set_state(&mut self, state: &[f64]) -> Result<(), EnvError>;
}
