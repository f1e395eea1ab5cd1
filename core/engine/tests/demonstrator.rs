//! The scripted demonstrator on the physics-free pick-and-place environment.
#![allow(clippy::unwrap_used, clippy::indexing_slicing)] // tests fail loudly by design

use mimicgen_engine::Environment as _;
use mimicgen_engine::demo::SourceDemo;
use mimicgen_engine::demonstrator::PickPlaceScript;
use mimicgen_engine::kinematic::PickPlace;
use mimicgen_engine::pose::{Pose, Vec3};
use rand::SeedableRng as _;
use rand_chacha::ChaCha8Rng;

/// A lean tilts the hand's top towards the picked object's +y by that angle at the grasp, and the
/// hand keeps it (relative to the object) until it lets go.
#[test]
fn a_grasp_lean_tilts_the_hands_top_towards_the_objects_y_until_the_release() {
    let record = |lean: f64| {
        let mut env = PickPlace::new(0.1);
        env.reset(&mut ChaCha8Rng::seed_from_u64(3)).unwrap();
        let script =
            PickPlaceScript { pick: "cubeA".to_owned(), place_on: "cubeB".to_owned(), grasp_lean_deg: lean, ..PickPlaceScript::default() };
        script.record(&mut env, "demo", &mut ChaCha8Rng::seed_from_u64(4)).unwrap()
    };
    let (upright, leaning) = (record(0.0), record(15.0));
    let closed = |demo: &SourceDemo| (0..demo.len()).filter(|&t| demo.gripper_actions.row(t)[0] > 0.0).collect::<Vec<_>>();
    let (held, held_leaning) = (closed(&upright), closed(&leaning));
    assert!(!held.is_empty() && held.len() == held_leaning.len(), "both grasp, for as long");
    let y = leaning.object_poses["cubeA"][0].rotation * Vec3::y();
    for (&t, &u) in held_leaning.iter().zip(&held) {
        let up = |p: &Pose| -(p.rotation * Vec3::z());
        // The tilt between the two hands is the lean, about the cube's x axis, towards its +y.
        let (a, b) = (up(&upright.target_poses[u]), up(&leaning.target_poses[t]));
        let angle = a.angle(&b).to_degrees();
        assert!((angle - 15.0).abs() < 1e-6, "step {t}: tilted {angle} deg from the upright hand");
        assert!((b - a).dot(&y) > 0.2, "step {t}: leans towards the cube's +y");
    }
}
