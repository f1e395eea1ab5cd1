//! Transforming source segments into a new scene and bridging to them (paper Sec. 3.2 and the
//! appendices "Derivation of Subtask Segment Transform" and "Details on Interpolation Segments").

use crate::pose::{Pose, pose_from_parts};

/// Re-expresses a source segment relative to the object's pose in the new scene, keeping every
/// `obj_from_eef` the same:
/// `world_from_eef_new = world_from_obj_new * world_from_obj_src^-1 * world_from_eef_src`.
#[must_use]
pub fn transform_segment(world_from_obj_new: &Pose, world_from_obj_src: &Pose, world_from_eef_src: &[Pose]) -> Vec<Pose> {
    let world_new_from_world_src = world_from_obj_new * world_from_obj_src.inverse();
    world_from_eef_src.iter().map(|world_from_eef| world_new_from_world_src * world_from_eef).collect()
}

/// `num_steps + 2` poses from `start` to `end` inclusive: positions linear, rotations slerped.
#[must_use]
pub fn interpolate_poses(start: &Pose, end: &Pose, num_steps: usize) -> Vec<Pose> {
    let n = num_steps + 1;
    (0..=n)
        .map(|i| {
            #[allow(clippy::cast_precision_loss)] // step counts are far below 2^52
            let s = i as f64 / n as f64;
            let position = start.translation.vector.lerp(&end.translation.vector, s);
            // Antipodal rotations have no unique geodesic: fall back to the end rotation.
            let rotation = start.rotation.try_slerp(&end.rotation, s, 1e-12).unwrap_or(end.rotation);
            pose_from_parts(position, rotation)
        })
        .collect()
}

/// One controller target to execute: a pose, the gripper command, and the action noise scale.
#[derive(Debug, Clone, PartialEq)]
pub struct Waypoint {
    /// Controller target `world_from_target`.
    pub pose: Pose,
    /// Gripper part of the action.
    pub gripper: Vec<f64>,
    /// Standard deviation of Gaussian noise on the pose part of the action.
    pub noise: f64,
    /// The mobile base's part of the action ([`crate::base`]); empty: the base stands still.
    pub base: Vec<f64>,
}

/// What kind of step a waypoint is, for labelling and visualisation.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub enum WaypointKind {
    /// Part of the interpolation segment (including held steps).
    Interpolation,
    /// Part of the transformed source segment.
    Transformed,
    /// Part of a planned collision-free transit ([`crate::transit`]).
    Transit,
    /// Part of a mobile base's drive copied from the source, the arm holding still on the base
    /// ([`crate::base`]).
    Base,
}

/// Builds the waypoints of one subtask as MimicGen does: `num_interp` interpolated poses from
/// `start` towards the first transformed pose, that pose itself, `num_fixed` more copies of it, then
/// the rest of the transformed segment. With no interpolation and no fixed steps the transformed
/// segment is executed as is. `gripper[t]` belongs to `transformed[t]`; interpolation steps use
/// `gripper[0]`.
#[must_use]
pub fn subtask_waypoints(
    start: &Pose,
    transformed: &[Pose],
    gripper: &[Vec<f64>],
    num_interp: usize,
    num_fixed: usize,
    noise: f64,
    interp_noise: f64,
) -> Vec<(Waypoint, WaypointKind)> {
    let Some(first) = transformed.first() else { return Vec::new() };
    let mut out = Vec::with_capacity(num_interp + num_fixed + transformed.len());
    let transformed_from = if num_interp > 0 || num_fixed > 0 {
        let bridge = interpolate_poses(start, first, num_interp);
        for pose in bridge.into_iter().skip(1).chain(std::iter::repeat_n(*first, num_fixed)) {
            out.push((
                Waypoint { pose, gripper: gripper.first().cloned().unwrap_or_default(), noise: interp_noise, base: Vec::new() },
                WaypointKind::Interpolation,
            ));
        }
        1
    } else {
        0
    };
    for (pose, g) in transformed.iter().zip(gripper).skip(transformed_from) {
        out.push((Waypoint { pose: *pose, gripper: g.clone(), noise, base: Vec::new() }, WaypointKind::Transformed));
    }
    out
}

#[cfg(test)]
mod tests {
    use proptest::prelude::*;

    use super::*;
    use crate::testing::{arb_pose, arb_segment};

    fn close(a: &Pose, b: &Pose, eps: f64) -> bool {
        (a.translation.vector - b.translation.vector).norm() < eps && a.rotation.angle_to(&b.rotation) < eps
    }

    proptest! {
        #[test]
        fn transformed_segment_keeps_every_obj_from_eef(obj_src in arb_pose(), obj_new in arb_pose(), segment in arb_segment(20)) {
            let out = transform_segment(&obj_new, &obj_src, &segment);
            prop_assert_eq!(out.len(), segment.len());
            for (src, new) in segment.iter().zip(&out) {
                let obj_from_eef_src = obj_src.inverse() * src;
                let obj_from_eef_new = obj_new.inverse() * new;
                prop_assert!(close(&obj_from_eef_src, &obj_from_eef_new, 1e-9));
            }
        }

        #[test]
        fn transform_into_the_same_scene_is_identity(obj in arb_pose(), segment in arb_segment(10)) {
            let out = transform_segment(&obj, &obj, &segment);
            for (a, b) in segment.iter().zip(&out) {
                prop_assert!(close(a, b, 1e-9));
            }
        }

        #[test]
        fn interpolation_hits_endpoints_and_stays_on_the_geodesic(a in arb_pose(), b in arb_pose(), n in 0usize..12) {
            let poses = interpolate_poses(&a, &b, n);
            prop_assert_eq!(poses.len(), n + 2);
            prop_assert!(close(&poses[0], &a, 1e-9));
            prop_assert!(close(&poses[n + 1], &b, 1e-9));
            let total = a.rotation.angle_to(&b.rotation);
            prop_assume!(total < std::f64::consts::PI - 1e-3);
            for (i, p) in poses.iter().enumerate() {
                #[allow(clippy::cast_precision_loss)]
                let s = i as f64 / (n + 1) as f64;
                // On the geodesic: the angles to both ends add up to the whole, split as s : 1 - s.
                let to_a = a.rotation.angle_to(&p.rotation);
                let to_b = p.rotation.angle_to(&b.rotation);
                prop_assert!((to_a + to_b - total).abs() < 1e-7, "off geodesic: {to_a} + {to_b} != {total}");
                prop_assert!((to_a - s * total).abs() < 1e-7);
                let expected = a.translation.vector * (1.0 - s) + b.translation.vector * s;
                prop_assert!((p.translation.vector - expected).norm() < 1e-9);
            }
        }

        #[test]
        fn waypoint_counts_follow_mimicgen(start in arb_pose(), segment in arb_segment(15), n_interp in 0usize..6, n_fixed in 0usize..4) {
            let gripper: Vec<Vec<f64>> = (0..segment.len()).map(|i| vec![f64::from(u8::try_from(i % 2).unwrap_or(0))]).collect();
            let wps = subtask_waypoints(&start, &segment, &gripper, n_interp, n_fixed, 0.05, 0.0);
            let bridge = n_interp + n_fixed;
            let expected = if bridge > 0 { bridge + segment.len() } else { segment.len() };
            prop_assert_eq!(wps.len(), expected);
            let interp = wps.iter().filter(|(_, k)| *k == WaypointKind::Interpolation).count();
            prop_assert_eq!(interp, if bridge > 0 { bridge + 1 } else { 0 });
            // The transformed segment's last pose is the final target.
            prop_assert!(close(&wps[wps.len() - 1].0.pose, &segment[segment.len() - 1], 1e-12));
            if bridge > 0 {
                prop_assert!(wps[..=bridge].iter().all(|(w, _)| w.noise == 0.0));
                prop_assert!(close(&wps[n_interp].0.pose, &segment[0], 1e-9));
            }
        }
    }
}
