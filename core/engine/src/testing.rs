//! Strategies and hand-built demos for the engine's unit tests.

use std::collections::BTreeMap;

use proptest::prelude::*;

use crate::demo::{Rows, SourceDemo};
use crate::pose::{Pose, Rot, Vec3, pose_from_parts};

/// Random rigid poses within a 2 m cube, any rotation.
pub fn arb_pose() -> impl Strategy<Value = Pose> {
    (prop::array::uniform3(-1.0f64..1.0), prop::array::uniform3(-3.2f64..3.2))
        .prop_map(|(p, r)| pose_from_parts(Vec3::new(p[0], p[1], p[2]), Rot::from_scaled_axis(Vec3::new(r[0], r[1], r[2]))))
}

/// Random segments of 1..max poses.
pub fn arb_segment(max: usize) -> impl Strategy<Value = Vec<Pose>> {
    prop::collection::vec(arb_pose(), 1..max)
}

/// Random pose parts of an action, in `[-1, 1]`.
pub fn arb_unit_action() -> impl Strategy<Value = [f64; 6]> {
    prop::array::uniform6(-1.0f64..1.0)
}

/// A 10-step demo whose object sits at `(x, 0, 0)` and whose signal `on` rises at step 4.
pub fn demo_with_object_at(object: &str, x: f64) -> SourceDemo {
    let n = 10;
    let obj = pose_from_parts(Vec3::new(x, 0.0, 0.0), Rot::identity());
    let eef: Vec<Pose> = (0..n).map(|t| pose_from_parts(Vec3::new(x, 0.0, 0.1 - 0.01 * f64::from(t)), Rot::identity())).collect();
    SourceDemo {
        name: format!("demo_x{x}"),
        eef_poses: eef.clone(),
        target_poses: eef,
        gripper_actions: Rows::from_vec(1, vec![-1.0; 10], "gripper").unwrap_or_default(),
        object_poses: BTreeMap::from([(object.to_owned(), vec![obj; 10])]),
        subtask_term_signals: BTreeMap::from([("on".to_owned(), (0..10).map(|t| i64::from(t >= 4)).collect())]),
        ..SourceDemo::default()
    }
}
