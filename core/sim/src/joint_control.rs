//! Joint-position control, for `actions_joint` (each step's arm joint targets, then the gripper):
//! robosuite's JOINT_POSITION law, `torque = M (kp (q* - q) + kd (dq* - dq)) + bias` on the arm's
//! joints, with its linear interpolator (the goal moves from where the arm was at the start of
//! the control step to the target over the step's physics steps, at the velocity that takes) and
//! a stiffer gain than its default, so that replayed joint targets retrace the recorded motion.
#![allow(
    clippy::indexing_slicing,
    reason = "MuJoCo ids and addresses come from the compiled model and index that model's own arrays; the goal holds one value per arm joint (checked where a step starts)"
)]

use std::sync::Arc;

use mujoco_rs::prelude::*;

use crate::scene::RobotIndices;

/// Stiffness on the joint error (per joint, mass-matrix scaled; robosuite's JOINT_POSITION takes
/// 0 to 300, default 50: too soft to track a 20 Hz trajectory closely).
pub const JOINT_KP: f64 = 300.0;

/// The arm's joint goal within one control step.
#[derive(Debug, Clone, PartialEq)]
pub struct JointGoal {
    /// Where the arm was when the step started.
    pub start: Vec<f64>,
    /// The step's target.
    pub target: Vec<f64>,
    /// Physics steps per control step.
    pub substeps: usize,
}

impl JointGoal {
    /// Position and velocity goal at physics step `k` (1-based) of the control step lasting
    /// `period` seconds.
    #[must_use]
    pub fn at(&self, k: usize, period: f64) -> (Vec<f64>, Vec<f64>) {
        #[allow(clippy::cast_precision_loss)] // step counts are small
        let frac = (k as f64 / self.substeps.max(1) as f64).min(1.0);
        let q: Vec<f64> = self.start.iter().zip(&self.target).map(|(s, t)| s + frac * (t - s)).collect();
        let dq: Vec<f64> = self.start.iter().zip(&self.target).map(|(s, t)| (t - s) / period.max(f64::EPSILON)).collect();
        (q, dq)
    }
}

/// Arm torques towards `(q_goal, dq_goal)` for the current state (before clipping to the
/// actuators' ranges). `data` must hold the current mass matrix and bias forces (after
/// `mj_step1` or `mj_forward`); `full_m` is scratch of `nv * nv` values.
#[must_use]
pub fn joint_torques(
    data: &MjData<Arc<MjModel>>,
    robot: &RobotIndices,
    q_goal: &[f64],
    dq_goal: &[f64],
    full_m: &mut Vec<f64>,
) -> Vec<f64> {
    let model = data.model();
    let nv = usize::try_from(model.ffi().nv).unwrap_or_default();
    full_m.resize(nv * nv, 0.0);
    #[allow(unsafe_code)]
    // SAFETY: the buffer holds nv*nv values as mj_fullM writes, and `data` belongs to `model`.
    unsafe {
        mujoco_rs::mujoco_c::mj_fullM(model.ffi(), data.ffi(), full_m.as_mut_ptr());
    }
    let dof = &robot.arm_dof;
    let kd = 2.0 * JOINT_KP.sqrt();
    let (qpos, qvel, bias) = (data.qpos(), data.qvel(), data.qfrc_bias());
    let accel: Vec<f64> =
        (0..dof.len()).map(|i| JOINT_KP * (q_goal[i] - qpos[robot.arm_qpos[i]]) + kd * (dq_goal[i] - qvel[dof[i]])).collect();
    (0..dof.len()).map(|r| (0..dof.len()).map(|c| full_m[dof[r] * nv + dof[c]] * accel[c]).sum::<f64>() + bias[dof[r]]).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_goal_moves_linearly_to_the_target_over_the_step() {
        let goal = JointGoal { start: vec![0.0, 1.0], target: vec![0.5, 0.0], substeps: 25 };
        let (q, dq) = goal.at(5, 0.05);
        assert!((q[0] - 0.1).abs() < 1e-12 && (q[1] - 0.8).abs() < 1e-12, "{q:?}");
        assert!((dq[0] - 10.0).abs() < 1e-9 && (dq[1] + 20.0).abs() < 1e-9, "{dq:?}");
        assert_eq!(goal.at(25, 0.05).0, goal.target);
        assert_eq!(goal.at(40, 0.05).0, goal.target, "past the step, the target holds");
    }
}
