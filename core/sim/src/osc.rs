//! robosuite's OSC_POSE controller (operational-space control, Khatib 1987), step for step:
//! the goal is set once per control step from a delta action, and torques are recomputed at every
//! physics step from the current state.

use std::sync::Arc;

use mimicgen_engine::action::DeltaPoseScale;
use mimicgen_engine::pose::{Rot, Vec3, rot_from_axis_angle};
use mujoco_rs::prelude::*;
use nalgebra::{DMatrix, DVector, Matrix3};

use crate::scene::RobotIndices;

/// Gains and limits of the controller (robosuite's OSC_POSE defaults, as in the reference configs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OscConfig {
    /// Stiffness on position and orientation errors.
    pub kp: f64,
    /// Damping ratio (1 = critical).
    pub damping_ratio: f64,
    /// Stiffness of the null-space posture term.
    pub kp_null: f64,
    /// Action scaling (`output_max`).
    pub scale: DeltaPoseScale,
}

impl Default for OscConfig {
    fn default() -> Self {
        Self { kp: 150.0, damping_ratio: 1.0, kp_null: 10.0, scale: DeltaPoseScale::default() }
    }
}

/// Panda's home posture, robosuite's `init_qpos`; the null-space term pulls towards it.
pub const PANDA_INIT_QPOS: [f64; 7] = [
    0.0,
    std::f64::consts::PI / 16.0,
    0.0,
    -std::f64::consts::PI / 2.0 - std::f64::consts::PI / 3.0,
    0.0,
    std::f64::consts::PI - 0.2,
    std::f64::consts::PI / 4.0,
];

/// The controller's goal and posture.
#[derive(Debug, Clone)]
pub struct Osc {
    config: OscConfig,
    /// Posture the null-space term pulls towards.
    pub initial_joint: Vec<f64>,
    goal_pos: Vec3,
    goal_rot: Matrix3<f64>,
    jacp: Vec<f64>,
    jacr: Vec<f64>,
    full_m: Vec<f64>,
}

/// robosuite's orientation error between two rotation matrices (half the sum of column crosses).
#[must_use]
pub fn orientation_error(desired: &Matrix3<f64>, current: &Matrix3<f64>) -> Vec3 {
    let mut e = Vec3::zeros();
    for c in 0..3 {
        e += current.column(c).cross(&desired.column(c));
    }
    0.5 * e
}

impl Osc {
    /// A controller with `config`, pulling towards `initial_joint` in the null space.
    #[must_use]
    pub fn new(config: OscConfig, initial_joint: Vec<f64>, nv: usize) -> Self {
        Self {
            config,
            initial_joint,
            goal_pos: Vec3::zeros(),
            goal_rot: Matrix3::identity(),
            jacp: vec![0.0; 3 * nv],
            jacr: vec![0.0; 3 * nv],
            full_m: vec![0.0; nv * nv],
        }
    }

    /// The action scaling.
    #[must_use]
    pub fn scale(&self) -> DeltaPoseScale {
        self.config.scale
    }

    /// Sets the goal from the pose part of an action (clipped to `[-1, 1]`), relative to the
    /// current end-effector pose. `data` must be forwarded.
    pub fn set_goal(&mut self, data: &MjData<Arc<MjModel>>, robot: &RobotIndices, action: &[f64]) {
        let a: Vec<f64> = action.iter().take(6).map(|v| v.clamp(-1.0, 1.0)).collect();
        let xpos = data.site_xpos()[robot.eef_site];
        let rot = Matrix3::from_row_slice(&data.site_xmat()[robot.eef_site]);
        let s = self.config.scale;
        self.goal_pos = Vec3::new(xpos[0], xpos[1], xpos[2]) + Vec3::new(a[0], a[1], a[2]) * s.max_dpos_m;
        let delta: Rot = rot_from_axis_angle(&(Vec3::new(a[3], a[4], a[5]) * s.max_drot_rad));
        self.goal_rot = delta.to_rotation_matrix().into_inner() * rot;
    }

    /// Arm torques for the current state (before clipping to the actuators' ranges). `data` must be
    /// forwarded.
    pub fn torques(&mut self, data: &MjData<Arc<MjModel>>, robot: &RobotIndices) -> Vec<f64> {
        let model = data.model();
        let nv = usize::try_from(model.ffi().nv).unwrap_or_default();
        let n = robot.arm_dof.len();
        let site = i32::try_from(robot.eef_site).unwrap_or_default();
        #[allow(unsafe_code)]
        // SAFETY: the buffers hold 3*nv and nv*nv values as mj_jacSite and mj_fullM write, and
        // `data` was forwarded for `model`.
        unsafe {
            mujoco_rs::mujoco_c::mj_jacSite(model.ffi(), data.ffi(), self.jacp.as_mut_ptr(), self.jacr.as_mut_ptr(), site);
            mujoco_rs::mujoco_c::mj_fullM(model.ffi(), data.ffi(), self.full_m.as_mut_ptr());
        }
        let j =
            DMatrix::from_fn(
                6,
                n,
                |r, c| if r < 3 { self.jacp[r * nv + robot.arm_dof[c]] } else { self.jacr[(r - 3) * nv + robot.arm_dof[c]] },
            );
        let m = DMatrix::from_fn(n, n, |r, c| self.full_m[robot.arm_dof[r] * nv + robot.arm_dof[c]]);
        let qvel = data.qvel();
        let qpos = data.qpos();
        let dq = DVector::from_fn(n, |i, _| qvel[robot.arm_dof[i]]);
        let q = DVector::from_fn(n, |i, _| qpos[robot.arm_qpos[i]]);
        let bias = DVector::from_fn(n, |i, _| data.qfrc_bias()[robot.arm_dof[i]]);

        let xpos = data.site_xpos()[robot.eef_site];
        let rot = Matrix3::from_row_slice(&data.site_xmat()[robot.eef_site]);
        let twist = &j * &dq;
        let kp = self.config.kp;
        let kd = 2.0 * kp.sqrt() * self.config.damping_ratio;
        let pos_err = self.goal_pos - Vec3::new(xpos[0], xpos[1], xpos[2]);
        let ori_err = orientation_error(&self.goal_rot, &rot);
        let force = pos_err * kp - Vec3::new(twist[0], twist[1], twist[2]) * kd;
        let torque = ori_err * kp - Vec3::new(twist[3], twist[4], twist[5]) * kd;

        let m_inv = m.clone().try_inverse().unwrap_or_else(|| m.clone().pseudo_inverse(1e-12).unwrap_or_else(|_| DMatrix::identity(n, n)));
        let pinv = |a: DMatrix<f64>| a.clone().pseudo_inverse(1e-15).unwrap_or_else(|_| DMatrix::zeros(a.nrows(), a.ncols()));
        let j_pos = j.rows(0, 3).into_owned();
        let j_ori = j.rows(3, 3).into_owned();
        let lambda_full = pinv(&j * &m_inv * j.transpose());
        let lambda_pos = pinv(&j_pos * &m_inv * j_pos.transpose());
        let lambda_ori = pinv(&j_ori * &m_inv * j_ori.transpose());
        let wrench_pos = &lambda_pos * DVector::from_column_slice(force.as_slice());
        let wrench_ori = &lambda_ori * DVector::from_column_slice(torque.as_slice());
        let wrench = DVector::from_iterator(6, wrench_pos.iter().chain(wrench_ori.iter()).copied());
        let mut tau = j.transpose() * wrench + bias;

        let j_bar = &m_inv * j.transpose() * &lambda_full;
        let nullspace = DMatrix::identity(n, n) - j_bar * &j;
        let kv_null = self.config.kp_null.sqrt() * 2.0;
        let q0 = DVector::from_column_slice(&self.initial_joint);
        let posture = &m * ((q0 - q) * self.config.kp_null - dq * kv_null);
        tau += nullspace.transpose() * posture;
        tau.iter().copied().collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn orientation_error_is_the_small_rotation_between() {
        let current = Matrix3::identity();
        let desired = Rot::from_axis_angle(&Vec3::z_axis(), 0.01).to_rotation_matrix().into_inner();
        let e = orientation_error(&desired, &current);
        assert!((e - Vec3::new(0.0, 0.0, 0.01)).norm() < 1e-6, "{e}");
    }
}
