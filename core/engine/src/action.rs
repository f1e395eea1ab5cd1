//! The delta-pose action space (paper, "Equivalence between delta-pose actions and controller
//! target poses"), in robosuite's OSC_POSE convention.
//!
//! An action is `[dx, dy, dz, rx, ry, rz, gripper...]` in `[-1, 1]`: the position delta is
//! `max_dpos * a[0..3]` added to the current position, the rotation delta is the axis-angle
//! `max_drot * a[3..6]` applied on the left of the current rotation.

use serde::{Deserialize, Serialize};

use crate::pose::{Pose, Vec3, pose_from_parts, rot_from_axis_angle, rot_to_axis_angle};

/// Number of pose dimensions at the front of an action (the rest is gripper).
pub const POSE_ACTION_DIM: usize = 6;

/// Scales of a delta-pose action space.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct DeltaPoseScale {
    /// Metres of translation per unit action.
    pub max_dpos_m: f64,
    /// Radians of rotation per unit action.
    pub max_drot_rad: f64,
}

impl Default for DeltaPoseScale {
    /// robosuite's OSC_POSE `output_max`: 0.05 m and 0.5 rad.
    fn default() -> Self {
        Self { max_dpos_m: 0.05, max_drot_rad: 0.5 }
    }
}

impl DeltaPoseScale {
    /// Controller target pose implied by the pose part of `action` at the current end-effector pose.
    #[must_use]
    pub fn target_from_action(&self, world_from_eef: &Pose, action: &[f64; POSE_ACTION_DIM]) -> Pose {
        let position = world_from_eef.translation.vector + Vec3::new(action[0], action[1], action[2]) * self.max_dpos_m;
        let delta = rot_from_axis_angle(&(Vec3::new(action[3], action[4], action[5]) * self.max_drot_rad));
        pose_from_parts(position, delta * world_from_eef.rotation)
    }

    /// Pose part of the action that moves the controller target from the current end-effector pose
    /// to `world_from_target`, each component clipped to `[-1, 1]`.
    #[must_use]
    pub fn action_from_target(&self, world_from_eef: &Pose, world_from_target: &Pose) -> [f64; POSE_ACTION_DIM] {
        let dpos = (world_from_target.translation.vector - world_from_eef.translation.vector) / self.max_dpos_m;
        let drot = rot_to_axis_angle(&(world_from_target.rotation * world_from_eef.rotation.inverse())) / self.max_drot_rad;
        let mut action = [dpos.x, dpos.y, dpos.z, drot.x, drot.y, drot.z];
        for a in &mut action {
            *a = a.clamp(-1.0, 1.0);
        }
        action
    }
}

#[cfg(test)]
mod tests {
    use proptest::prelude::*;

    use super::*;
    use crate::testing::{arb_pose, arb_unit_action};

    proptest! {
        #[test]
        fn action_target_action_round_trips(eef in arb_pose(), action in arb_unit_action()) {
            let scale = DeltaPoseScale::default();
            let target = scale.target_from_action(&eef, &action);
            let back = scale.action_from_target(&eef, &target);
            // Rotations of norm above pi wrap around, so compare only where the rotation is unique.
            let rot_norm = (action[3].powi(2) + action[4].powi(2) + action[5].powi(2)).sqrt() * scale.max_drot_rad;
            prop_assume!(rot_norm < std::f64::consts::PI - 1e-6);
            for (a, b) in action.iter().zip(back.iter()) {
                prop_assert!((a - b).abs() < 1e-9, "{action:?} -> {back:?}");
            }
        }

        #[test]
        fn far_targets_are_clipped(eef in arb_pose(), offset in 0.06f64..1.0) {
            let scale = DeltaPoseScale::default();
            let target = pose_from_parts(eef.translation.vector + Vec3::new(offset, -offset, 0.0), eef.rotation);
            let action = scale.action_from_target(&eef, &target);
            prop_assert!((action[0] - 1.0).abs() < 1e-12 && (action[1] + 1.0).abs() < 1e-12);
            prop_assert!(action[2].abs() < 1e-9);
        }
    }
}
