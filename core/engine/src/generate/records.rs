//! What an attempt leaves behind: its plans per subtask, its trajectory, why it failed.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use crate::action::POSE_ACTION_DIM;
use crate::demo::{Rows, SimPayload, SourceDemo};
use crate::pose::Pose;
use crate::segment::Span;
use crate::transform::WaypointKind;
use crate::transit::TransitStats;

/// Why an attempt failed.
#[derive(Debug, Clone, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum FailureReason {
    /// The subtask ran to its end but its end signal never turned on (e.g. the grasp missed).
    SignalNeverOn {
        /// The signal that stayed off.
        signal: String,
    },
    /// Every subtask ran but the task was never achieved.
    TaskNotAchieved {
        /// The part of the success condition that did not hold at the end, when the
        /// environment can say (`coffee_pod in coffee_machine`).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        unmet: Option<String>,
    },
    /// The simulation became unstable.
    Unstable {
        /// What the simulator reported.
        reason: String,
    },
    /// Planned transit found no collision-free path to the segment.
    NoTransitPath {
        /// The sample budget the search spent (a count, so that the reason is the same on any
        /// machine; the time is in the subtask's [`SubtaskPlan::transit`]).
        samples: usize,
        /// Why, in words (the goal unreachable, or the trees never met).
        detail: String,
    },
}

impl std::fmt::Display for FailureReason {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::SignalNeverOn { signal } => write!(f, "signal {signal:?} never turned on"),
            Self::TaskNotAchieved { unmet: None } => write!(f, "task not achieved"),
            Self::TaskNotAchieved { unmet: Some(unmet) } => write!(f, "task not achieved: {unmet} failed"),
            Self::Unstable { reason } => write!(f, "simulation unstable: {reason}"),
            Self::NoTransitPath { samples, detail } => write!(f, "no collision-free path found in {samples} samples: {detail}"),
        }
    }
}

/// Where and why an attempt failed.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Failure {
    /// Index of the first subtask that went wrong.
    pub subtask: usize,
    /// What went wrong there.
    pub reason: FailureReason,
}

/// How one subtask of an attempt was planned: the pieces the paper's Fig. 2 draws.
#[derive(Debug, Clone, PartialEq)]
pub struct SubtaskPlan {
    /// The source demo the segment came from.
    pub src_demo: usize,
    /// How far each source demo was from the scene by the selection strategy (`None` when the
    /// source was kept from the previous subtask or the strategy is random).
    pub source_distances: Option<Vec<f64>>,
    /// The segment's steps in that demo, after this attempt's offsets.
    pub src_span: Span,
    /// The source segment's poses before the transform (first eef pose, then targets).
    pub source_poses: Vec<Pose>,
    /// The reference object's pose in the source demo at the segment start.
    pub world_from_obj_src: Option<Pose>,
    /// The reference object's pose in the new scene at the subtask start.
    pub world_from_obj_new: Option<Pose>,
    /// The segment re-expressed in the new scene.
    pub transformed_poses: Vec<Pose>,
    /// The waypoints actually executed (interpolation, then transformed).
    pub waypoints: Vec<(Pose, WaypointKind)>,
    /// First executed step of this subtask in the attempt.
    pub first_step: usize,
    /// What planning the transit cost, when it was planned (also when planning failed).
    pub transit: Option<TransitStats>,
}

/// Everything recorded per executed step, step-aligned like a source demo.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Trajectory {
    /// Simulator state before each action.
    pub states: Rows,
    /// The actions executed (noise included, clipped).
    pub actions: Rows,
    /// `world_from_eef` before each action.
    pub eef_poses: Vec<Pose>,
    /// Controller target implied by each executed action.
    pub target_poses: Vec<Pose>,
    /// Gripper part of each action.
    pub gripper_actions: Rows,
    /// `world_from_object` before each action.
    pub object_poses: BTreeMap<String, Vec<Pose>>,
    /// Signals before each action.
    pub subtask_term_signals: BTreeMap<String, Vec<i64>>,
    /// Source demo each step came from.
    pub src_demo_labels: Vec<usize>,
    /// Subtask each step belongs to.
    pub subtask_labels: Vec<usize>,
    /// Whether each step was interpolation or transformed segment.
    pub kinds: Vec<WaypointKind>,
}

impl Trajectory {
    /// An empty trajectory for states of `state_dim` and actions of `action_dim` values.
    #[must_use]
    pub fn new(state_dim: usize, action_dim: usize) -> Self {
        Self {
            states: Rows::new(state_dim),
            actions: Rows::new(action_dim),
            gripper_actions: Rows::new(action_dim.saturating_sub(POSE_ACTION_DIM)),
            ..Self::default()
        }
    }

    /// An empty trajectory for `env`'s states and actions (its gripper's share of an action is
    /// what the pose and a mobile base leave).
    #[must_use]
    pub fn for_env<E: crate::Environment + ?Sized>(env: &E) -> Self {
        let base = if env.mobile_base().is_some() { crate::base::BASE_ACTION_DIM } else { 0 };
        Self {
            gripper_actions: Rows::new(env.action_dim().saturating_sub(POSE_ACTION_DIM + base)),
            ..Self::new(env.state().len(), env.action_dim())
        }
    }

    /// The trajectory as a source demo (for re-use as a source, or for writing out).
    #[must_use]
    pub fn to_source_demo(&self, name: &str) -> SourceDemo {
        SourceDemo {
            name: name.to_owned(),
            eef_poses: self.eef_poses.clone(),
            target_poses: self.target_poses.clone(),
            gripper_actions: self.gripper_actions.clone(),
            object_poses: self.object_poses.clone(),
            subtask_term_signals: self.subtask_term_signals.clone(),
            manual_subtask_ends: None,
            manual_subtask_starts: None,
            sim: SimPayload { actions: self.actions.clone(), states: self.states.clone(), model_xml: None },
        }
    }

    /// Number of executed steps.
    #[must_use]
    pub fn len(&self) -> usize {
        self.eef_poses.len()
    }

    /// True when nothing was executed.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.eef_poses.is_empty()
    }
}

/// The record of one attempt, kept whether it succeeded or not.
#[derive(Debug, Clone, PartialEq)]
pub struct Attempt {
    /// Index in the run (its random stream).
    pub index: u64,
    /// The run seed.
    pub seed: u64,
    /// Whether the task was achieved at any step.
    pub success: bool,
    /// Where and why it failed, if it did.
    pub failure: Option<Failure>,
    /// Source demo chosen for each subtask.
    pub src_demo_per_subtask: Vec<usize>,
    /// Object poses of the sampled scene before the first action.
    pub initial_object_poses: BTreeMap<String, Pose>,
    /// The simulator state of the sampled scene.
    pub initial_state: Vec<f64>,
    /// Per-subtask plans.
    pub plans: Vec<SubtaskPlan>,
    /// Per-step records.
    pub trajectory: Trajectory,
    /// Steps at which the robot, or what it held, touched an obstacle.
    pub obstacle_contact_steps: usize,
    /// What went wrong where it failed ([`crate::diagnose`]), if it did.
    pub cause: Option<crate::diagnose::Cause>,
}
