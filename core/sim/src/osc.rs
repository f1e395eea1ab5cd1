//! robosuite's OSC_POSE controller (operational-space control, Khatib 1987), step for step:
//! the goal is set once per control step from a delta action, and torques are recomputed at every
//! physics step from the current state.
#![allow(
    clippy::indexing_slicing,
    reason = "MuJoCo ids and addresses come from the compiled model (name_to_id, a Scene's names resolved once) and index that model's own arrays; the action is taken as its first six numbers, padded (step checks 7)"
)]

use std::sync::Arc;

use mimicgen_engine::action::DeltaPoseScale;
use mimicgen_engine::pose::{Rot, Vec3, rot_from_axis_angle};
use mujoco_rs::prelude::*;
use nalgebra::{Matrix3, SMatrix, SVector};

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
        // The first six numbers (0 for any the action lacks; `step` checks it has seven).
        let a: [f64; 6] = std::array::from_fn(|i| action.get(i).map_or(0.0, |v| v.clamp(-1.0, 1.0)));
        let xpos = data.site_xpos()[robot.eef_site];
        let rot = Matrix3::from_row_slice(&data.site_xmat()[robot.eef_site]);
        let s = self.config.scale;
        self.goal_pos = Vec3::new(xpos[0], xpos[1], xpos[2]) + Vec3::new(a[0], a[1], a[2]) * s.max_dpos_m;
        let delta: Rot = rot_from_axis_angle(&(Vec3::new(a[3], a[4], a[5]) * s.max_drot_rad));
        self.goal_rot = delta.to_rotation_matrix().into_inner() * rot;
    }

    /// [`Osc::set_goal`] for an arm on a mobile base: the action's deltas are in the frame turned
    /// by `world_from_base` from the world's (robosuite's mobile arms take them in the base's).
    pub fn set_goal_in(&mut self, data: &MjData<Arc<MjModel>>, robot: &RobotIndices, action: &[f64], world_from_base: &Rot) {
        let a: [f64; 6] = std::array::from_fn(|i| action.get(i).map_or(0.0, |v| v.clamp(-1.0, 1.0)));
        let xpos = data.site_xpos()[robot.eef_site];
        let rot = Matrix3::from_row_slice(&data.site_xmat()[robot.eef_site]);
        let s = self.config.scale;
        self.goal_pos = Vec3::new(xpos[0], xpos[1], xpos[2]) + world_from_base * (Vec3::new(a[0], a[1], a[2]) * s.max_dpos_m);
        let delta: Rot = world_from_base * rot_from_axis_angle(&(Vec3::new(a[3], a[4], a[5]) * s.max_drot_rad)) * world_from_base.inverse();
        self.goal_rot = delta.to_rotation_matrix().into_inner() * rot;
    }

    /// Moves the goal rigidly by `moved` (a world-frame motion: the base's since the goal was set).
    pub fn move_goal(&mut self, moved: &mimicgen_engine::pose::Pose) {
        self.goal_pos = (moved * nalgebra::Point3::from(self.goal_pos)).coords;
        self.goal_rot = moved.rotation.to_rotation_matrix().into_inner() * self.goal_rot;
    }

    /// Arm torques for the current state (before clipping to the actuators' ranges), one per arm
    /// joint. `data` must hold the current kinematics, mass matrix and bias forces (after
    /// `mj_forward` or `mj_step1`).
    pub fn torques(&mut self, data: &MjData<Arc<MjModel>>, robot: &RobotIndices) -> Vec<f64> {
        // Fixed-size matrices (no allocation per physics step) for the arms there are.
        match robot.arm_dof.len() {
            6 => self.torques_n::<6>(data, robot).to_vec(),
            _ => self.torques_n::<7>(data, robot).to_vec(),
        }
    }

    fn torques_n<const ARM_DOF: usize>(&mut self, data: &MjData<Arc<MjModel>>, robot: &RobotIndices) -> [f64; ARM_DOF] {
        let model = data.model();
        let nv = usize::try_from(model.ffi().nv).unwrap_or_default();
        let site = i32::try_from(robot.eef_site).unwrap_or_default();
        #[allow(unsafe_code)]
        // SAFETY: the buffers hold 3*nv and nv*nv values as mj_jacSite and mj_fullM write, and
        // `data` belongs to `model`.
        unsafe {
            mujoco_rs::mujoco_c::mj_jacSite(model.ffi(), data.ffi(), self.jacp.as_mut_ptr(), self.jacr.as_mut_ptr(), site);
            mujoco_rs::mujoco_c::mj_fullM(model.ffi(), data.ffi(), self.full_m.as_mut_ptr());
        }
        let dof = &robot.arm_dof;
        let j_pos = SMatrix::<f64, 3, ARM_DOF>::from_fn(|r, c| self.jacp[r * nv + dof[c]]);
        let j_ori = SMatrix::<f64, 3, ARM_DOF>::from_fn(|r, c| self.jacr[r * nv + dof[c]]);
        let j = SMatrix::<f64, 6, ARM_DOF>::from_fn(|r, c| if r < 3 { j_pos[(r, c)] } else { j_ori[(r - 3, c)] });
        let m = SMatrix::<f64, ARM_DOF, ARM_DOF>::from_fn(|r, c| self.full_m[dof[r] * nv + dof[c]]);
        let (qpos, qvel, bias) = (data.qpos(), data.qvel(), data.qfrc_bias());
        let dq = SVector::<f64, ARM_DOF>::from_fn(|i, _| qvel[dof[i]]);
        let q = SVector::<f64, ARM_DOF>::from_fn(|i, _| qpos[robot.arm_qpos[i]]);
        let bias = SVector::<f64, ARM_DOF>::from_fn(|i, _| bias[dof[i]]);

        let xpos = data.site_xpos()[robot.eef_site];
        let rot = Matrix3::from_row_slice(&data.site_xmat()[robot.eef_site]);
        let (kp, kd) = (self.config.kp, 2.0 * self.config.kp.sqrt() * self.config.damping_ratio);
        let force = (self.goal_pos - Vec3::new(xpos[0], xpos[1], xpos[2])) * kp - (j_pos * dq) * kd;
        let torque = orientation_error(&self.goal_rot, &rot) * kp - (j_ori * dq) * kd;

        // robosuite inverts the arm's block of the mass matrix and takes pseudo-inverses of the
        // operational-space inertias; these are symmetric positive definite away from
        // singularities, where a Cholesky inverse equals the pseudo-inverse and costs far less.
        let m_inv = spd_inverse(&m);
        let lambda_full = spd_inverse(&(j * m_inv * j.transpose()));
        let lambda_pos = spd_inverse(&(j_pos * m_inv * j_pos.transpose()));
        let lambda_ori = spd_inverse(&(j_ori * m_inv * j_ori.transpose()));
        let mut tau = j_pos.transpose() * (lambda_pos * force) + j_ori.transpose() * (lambda_ori * torque) + bias;

        let j_bar = m_inv * j.transpose() * lambda_full;
        let nullspace = SMatrix::<f64, ARM_DOF, ARM_DOF>::identity() - j_bar * j;
        let kv_null = self.config.kp_null.sqrt() * 2.0;
        let q0 = SVector::<f64, ARM_DOF>::from_column_slice(&self.initial_joint);
        let posture = m * ((q0 - q) * self.config.kp_null - dq * kv_null);
        tau += nullspace.transpose() * posture;
        tau.into()
    }
}

/// Inverse of a symmetric positive definite matrix by Cholesky, falling back to the SVD
/// pseudo-inverse (as robosuite's `np.linalg.pinv`) when it is singular.
fn spd_inverse<const N: usize>(a: &SMatrix<f64, N, N>) -> SMatrix<f64, N, N> {
    match a.cholesky() {
        Some(c) => c.inverse(),
        None => {
            let dynamic = nalgebra::DMatrix::from_column_slice(N, N, a.as_slice());
            dynamic.pseudo_inverse(1e-15).map_or_else(|_| SMatrix::zeros(), |p| SMatrix::from_column_slice(p.as_slice()))
        }
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
