//! A scripted two-arm demonstrator: each arm follows its own legs (a goal pose, a speed, the
//! gripper, a hold), at its own pace, and a leg marked `together` waits until the other arm has
//! reached one too, so that both close on the same step and lift as one. It records what a
//! teleoperated two-arm demo holds (both arms' actions in one row, each arm's poses, targets and
//! grippers, the objects and signals), as a [`TwoArmAttempt`] without plans.

use std::collections::BTreeMap;

use rand::Rng;

use super::{ArmTrack, TwoArmAttempt, TwoArmEnvironment};
use crate::EngineError;
use crate::action::POSE_ACTION_DIM;
use crate::demo::Rows;
use crate::env::EnvError;
use crate::pose::{Pose, Rot, Vec3, pose_from_parts, yaw_of};

/// One move of one arm.
#[derive(Debug, Clone, PartialEq)]
pub struct ArmLeg {
    /// Where the end effector goes.
    pub goal: Pose,
    /// How far the commanded pose moves per step (m); turns go at 0.05 rad per step and at least
    /// as many steps as the move.
    pub speed_m: f64,
    /// The gripper action on the way (-1 open, 1 closed).
    pub gripper: f64,
    /// Steps to hold the goal once the arm is there (within 1 cm).
    pub hold: usize,
    /// The leg starts only when the other arm has come as far (legs are counted alike for both
    /// arms): both close on the same step, both lift on the same step.
    pub together: bool,
}

/// A scripted two-arm lift of one object by two handles, one per arm.
#[derive(Debug, Clone, PartialEq)]
pub struct TwoArmLiftScript {
    /// The lifted object (`pot`).
    pub object: String,
    /// Per arm: the point it grips, in the object's frame (m).
    pub grasp_points_m: [[f64; 3]; 2],
    /// The gripper's yaw relative to the object's at the grasp (rad), modulo a half turn.
    pub grasp_yaw_offset_rad: f64,
    /// Range of the hover height above the grasp before descending (m).
    pub approach_height_m: (f64, f64),
    /// Range of the lift height (m), the same for both arms in one demo.
    pub lift_height_m: (f64, f64),
    /// Steps to hold while closing, drawn from this range.
    pub close_steps: (usize, usize),
}

impl TwoArmLiftScript {
    /// robosuite's Two Arm Lift: the pot's handle bars, 16 cm out on either side of its centre and
    /// 6 cm up (arm 0 at handle 0, +y; arm 1 at handle 1, -y), gripped across.
    #[must_use]
    pub fn pot() -> Self {
        Self {
            object: "pot".to_owned(),
            grasp_points_m: [[0.0, 0.16, 0.06], [0.0, -0.16, 0.06]],
            grasp_yaw_offset_rad: std::f64::consts::FRAC_PI_2,
            approach_height_m: (0.06, 0.10),
            lift_height_m: (0.15, 0.18),
            close_steps: (10, 14),
        }
    }

    /// Records one demo from the environment's present state (call `reset` first).
    ///
    /// # Errors
    /// The environment's error if a step fails, [`EnvError::Fatal`] if the object is missing.
    pub fn record<E: TwoArmEnvironment + ?Sized, R: Rng + ?Sized>(&self, env: &mut E, rng: &mut R) -> Result<TwoArmAttempt, EnvError> {
        let world_from_object = *env
            .object_poses()
            .get(&self.object)
            .ok_or_else(|| EnvError::Fatal { reason: format!("the scene has no object {:?}", self.object) })?;
        let lift = rng.random_range(self.lift_height_m.0..self.lift_height_m.1);
        let lift_speed = rng.random_range(0.004..0.007);
        let mut legs = [Vec::new(), Vec::new()];
        for (arm, arm_legs) in legs.iter_mut().enumerate() {
            let start = env.eef_pose(arm);
            let yaw = yaw_of(&world_from_object) + self.grasp_yaw_offset_rad;
            let eef_yaw = yaw_of(&start);
            let grasp_yaw = yaw + ((eef_yaw - yaw) / std::f64::consts::PI).round() * std::f64::consts::PI + rng.random_range(-0.1..0.1);
            let rotation = Rot::from_axis_angle(&Vec3::z_axis(), grasp_yaw - eef_yaw) * start.rotation;
            let point = self.grasp_points_m.get(arm).copied().unwrap_or_default();
            let offset = Vec3::new(rng.random_range(-0.004..0.004), rng.random_range(-0.002..0.002), rng.random_range(-0.004..0.004));
            let grasp = pose_from_parts((world_from_object * nalgebra::Point3::from(Vec3::from(point))).coords + offset, rotation);
            let up = |h: f64| pose_from_parts(grasp.translation.vector + Vec3::new(0.0, 0.0, h), rotation);
            let (fast, slow) = (rng.random_range(0.012..0.022), rng.random_range(0.004..0.008));
            arm_legs.extend([
                ArmLeg {
                    goal: up(rng.random_range(self.approach_height_m.0..self.approach_height_m.1)),
                    speed_m: fast,
                    gripper: -1.0,
                    hold: rng.random_range(0..4),
                    together: false,
                },
                ArmLeg { goal: grasp, speed_m: slow, gripper: -1.0, hold: rng.random_range(2..5), together: false },
                ArmLeg { goal: grasp, speed_m: slow, gripper: 1.0, hold: self.close_steps.0.max(1), together: true },
                ArmLeg { goal: up(lift), speed_m: lift_speed, gripper: 1.0, hold: 6, together: true },
            ]);
        }
        let close = rng.random_range(self.close_steps.0..=self.close_steps.1);
        for arm_legs in &mut legs {
            if let Some(leg) = arm_legs.get_mut(2) {
                leg.hold = close;
            }
        }
        follow(env, &legs)
    }
}

/// One arm as it follows its legs.
struct Follower<'a> {
    legs: &'a [ArmLeg],
    leg: usize,
    commanded: Pose,
    held: usize,
    gripper: f64,
}

/// Steps both arms through their legs and records every step.
///
/// # Errors
/// The environment's error if a step fails.
pub fn follow<E: TwoArmEnvironment + ?Sized>(env: &mut E, legs: &[Vec<ArmLeg>; 2]) -> Result<TwoArmAttempt, EnvError> {
    let fatal = |e: EngineError| EnvError::Fatal { reason: e.to_string() };
    let action_dim: usize = (0..2).map(|a| POSE_ACTION_DIM + env.gripper_dim(a)).sum();
    let initial_state = env.state();
    let mut attempt = TwoArmAttempt {
        index: 0,
        success: false,
        failure: None,
        initial_object_poses: env.object_poses(),
        states: Rows::new(initial_state.len()),
        initial_state,
        actions: Rows::new(action_dim),
        object_poses: BTreeMap::new(),
        subtask_term_signals: BTreeMap::new(),
        arms: (0..2).map(|a| ArmTrack { gripper_actions: Rows::new(env.gripper_dim(a)), ..ArmTrack::default() }).collect(),
    };
    let mut followers: Vec<Follower<'_>> = legs
        .iter()
        .enumerate()
        .map(|(arm, legs)| Follower { legs, leg: 0, commanded: env.eef_pose(arm), held: 0, gripper: -1.0 })
        .collect();
    // A bound on the recording: no demo of a scripted table-top task is this long.
    for _ in 0..2000 {
        if followers.iter().all(|f| f.leg >= f.legs.len()) {
            return Ok(attempt);
        }
        // How far each arm is (done: past every leg).
        let progress: Vec<usize> = followers.iter().map(|f| if f.leg < f.legs.len() { f.leg } else { usize::MAX }).collect();
        let mut action = Vec::with_capacity(action_dim);
        for (arm, f) in followers.iter_mut().enumerate() {
            let other_ready = progress.get(1 - arm).is_none_or(|&other| other >= f.leg);
            if let Some(leg) = f.legs.get(f.leg)
                && (!leg.together || other_ready)
            {
                f.gripper = leg.gripper;
                f.commanded = step_towards(&f.commanded, &leg.goal, leg.speed_m);
                let arrived = f.commanded == leg.goal && (env.eef_pose(arm).translation.vector - leg.goal.translation.vector).norm() < 0.01;
                if arrived || (f.commanded == leg.goal && f.held > 0) {
                    f.held += 1;
                }
                if f.held > leg.hold {
                    f.leg += 1;
                    f.held = 0;
                }
            }
            let pose_action = env.target_pose_to_action(arm, &f.commanded);
            let arm_action: Vec<f64> = pose_action.iter().copied().chain(std::iter::repeat_n(f.gripper, env.gripper_dim(arm))).collect();
            let track = attempt.arms.get_mut(arm).ok_or_else(|| EnvError::Fatal { reason: format!("no arm {arm}") })?;
            track.eef_poses.push(env.eef_pose(arm));
            track.target_poses.push(env.action_to_target_pose(arm, &arm_action));
            track.gripper_actions.push(arm_action.get(POSE_ACTION_DIM..).unwrap_or_default()).map_err(fatal)?;
            track.src_demo_labels.push(0);
            track.subtask_labels.push(0);
            track.holding.push(false);
            action.extend(arm_action);
        }
        attempt.states.push(&env.state()).map_err(fatal)?;
        attempt.actions.push(&action).map_err(fatal)?;
        for (name, pose) in env.object_poses() {
            attempt.object_poses.entry(name).or_default().push(pose);
        }
        for (name, value) in env.subtask_term_signals() {
            attempt.subtask_term_signals.entry(name).or_default().push(value);
        }
        env.step(&action)?;
        attempt.success |= env.is_success();
    }
    Err(EnvError::Fatal { reason: "the script did not end within 2000 steps".to_owned() })
}

/// `from` moved towards `to` by at most `speed_m` (and 0.05 rad), along the straight line and the
/// shortest turn; `to` itself once within reach.
fn step_towards(from: &Pose, to: &Pose, speed_m: f64) -> Pose {
    let delta = to.translation.vector - from.translation.vector;
    let angle = from.rotation.angle_to(&to.rotation);
    #[allow(clippy::cast_precision_loss, reason = "a step count, far below 2^52")]
    let steps = (delta.norm() / speed_m.max(1e-6)).max(angle / 0.05).ceil();
    if steps <= 1.0 {
        return *to;
    }
    let f = 1.0 / steps;
    pose_from_parts(from.translation.vector + delta * f, from.rotation.slerp(&to.rotation, f))
}
