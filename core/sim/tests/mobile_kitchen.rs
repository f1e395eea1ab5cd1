//! The paper's Mobile Kitchen, ours: the scene rests unsolved, the 25 bundled demos set up the pan
//! with their signals in order and generate; the mobile base drives in its own frame with the
//! arm riding along, and its arm's deltas turn with it; every pan and carrot is drawn.
#![allow(clippy::indexing_slicing, reason = "test helpers: an index out of range fails the test, as it should")]
#![allow(clippy::unwrap_used)] // tests fail loudly by design

mod common;
#[allow(dead_code, reason = "the checks other task tests share; this one uses some")]
mod task_checks;

use std::collections::BTreeSet;
use std::sync::Arc;

use mimicgen_engine::Environment as _;
use mimicgen_engine::pose::{Vec3, pose_from_parts, yaw_of};
use mimicgen_sim::{Scene, SimEnv, registry};
use rand::SeedableRng as _;
use task_checks::{bundled_demos_succeed_and_generate_n, rests_unsolved};

fn env() -> SimEnv {
    let task = registry::task("mobile_kitchen", "D0").unwrap();
    let scene = Arc::new(Scene::for_task(task.as_ref()).unwrap());
    let instances = Scene::instances_for_task(task.as_ref(), &mimicgen_sim::robot::PANDA).unwrap();
    SimEnv::new(scene, task).with_instances(instances.into_iter().map(|(label, s)| (label, Arc::new(s))).collect())
}

/// An action: the arm's six, the gripper open, the base's three.
fn action(arm: [f64; 6], base: [f64; 3]) -> Vec<f64> {
    let mut a = arm.to_vec();
    a.push(-1.0);
    a.extend(base);
    a
}

#[test]
fn mobile_kitchen_scene_rests_and_its_demos_set_up_the_pan() {
    rests_unsolved("mobile_kitchen", &["D0"]);
    bundled_demos_succeed_and_generate_n("mobile_kitchen", &["grasp_pan", "pan_on_stove", "grasp_carrot"], "D0", 25);
}

/// A full sideways command moves the base along its own y at its top speed (0.3 m/s, 1.5 cm a
/// control step), the hand riding along; after a quarter turn the same command and an arm delta
/// along the base's x both move things along the world's -x and +y: the base's frame turned.
#[test]
fn the_base_drives_in_its_own_frame_and_the_arm_rides_along() {
    let mut env = env();
    env.reset(&mut rand_chacha::ChaCha8Rng::seed_from_u64(1)).unwrap();
    assert_eq!(env.action_dim(), 10);
    let base = env.mobile_base().unwrap();
    assert!((base.max_step_m - 0.015).abs() < 1e-9, "{}", base.max_step_m);
    let (base0, eef0) = (base.world_from_base, env.eef_pose());
    for _ in 0..20 {
        env.step(&action([0.0; 6], [0.0, 1.0, 0.0])).unwrap();
    }
    let moved = env.mobile_base().unwrap().world_from_base.translation.vector - base0.translation.vector;
    assert!((moved.y - 0.3).abs() < 0.02 && moved.x.abs() < 0.005, "the base moved {moved:?}");
    let hand = env.eef_pose().translation.vector - eef0.translation.vector;
    assert!((hand - moved).norm() < 0.01, "the hand moved {hand:?} with the base's {moved:?}");

    // A quarter turn to the left (45 deg/s: 40 steps at a full command, then at rest).
    for _ in 0..40 {
        env.step(&action([0.0; 6], [0.0, 0.0, 1.0])).unwrap();
    }
    for _ in 0..10 {
        env.step(&action([0.0; 6], [0.0; 3])).unwrap();
    }
    let turned = env.mobile_base().unwrap().world_from_base;
    assert!((yaw_of(&turned).to_degrees() - 90.0).abs() < 3.0, "yaw {}", yaw_of(&turned).to_degrees());
    let (base1, eef1) = (turned.translation.vector, env.eef_pose().translation.vector);
    // Sideways (the base's +y) is now the world's -x.
    for _ in 0..10 {
        env.step(&action([0.0; 6], [0.0, 1.0, 0.0])).unwrap();
    }
    let moved = env.mobile_base().unwrap().world_from_base.translation.vector - base1;
    assert!(moved.x < -0.12 && moved.y.abs() < 0.02, "sideways after the turn moved {moved:?}");
    for _ in 0..10 {
        env.step(&action([0.0; 6], [0.0; 3])).unwrap();
    }
    // The arm's +x (the base's forward) is now the world's +y.
    let (base2, eef2) = (env.mobile_base().unwrap().world_from_base.translation.vector, env.eef_pose().translation.vector);
    assert!((eef2 - eef1 - (base2 - base1)).norm() < 0.02, "the hand kept its place on the base");
    for _ in 0..5 {
        env.step(&action([0.5, 0.0, 0.0, 0.0, 0.0, 0.0], [0.0; 3])).unwrap();
    }
    let reach = env.eef_pose().translation.vector - eef2;
    assert!(reach.y > 0.015 && reach.x.abs() < 0.1 * reach.y, "an arm delta along the base's x moved the hand {reach:?}");
    // And the engine's conversion agrees: the action that reaches a target is in the base's frame.
    let hand = env.eef_pose();
    let target = pose_from_parts(hand.translation.vector + Vec3::new(0.0, 0.02, 0.0), hand.rotation);
    let a = env.target_pose_to_action(&target);
    // (The turn stopped within 3 deg of a quarter: the base's y part is at most sin 3 deg of it.)
    assert!((a[0] - 0.4).abs() < 1e-3 && a[1].abs() < 0.021, "2 cm along the world's +y is the base's +x: {a:?}");
    let back = env.action_to_target_pose(&action([a[0], a[1], a[2], a[3], a[4], a[5]], [0.0; 3]));
    assert!((back.translation.vector - target.translation.vector).norm() < 1e-9);
}

/// Every episode draws one of the three pans and one of the three carrots; each of the nine
/// pairs is a scene of its own whose pan and carrot have their own sizes.
#[test]
fn every_pan_and_carrot_is_drawn() {
    let mut env = env();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(2);
    let (mut labels, mut pan_radii) = (BTreeSet::new(), BTreeSet::new());
    for _ in 0..40 {
        env.reset(&mut rng).unwrap();
        let label = env.object_instance().unwrap();
        let (pan, carrot) = label.split_once('+').unwrap();
        assert!(pan.ends_with("_pan") && carrot.ends_with("_carrot"), "{label}");
        labels.insert(label);
        // The pan's bottom plate is its first geom: a cylinder of the pan's radius.
        let scene = env.physics().scene();
        let bottom = scene.objects.iter().find(|o| o.name == "pan").unwrap().geoms[0];
        #[allow(clippy::cast_possible_truncation)]
        pan_radii.insert((scene.model.geom_size()[bottom][0] * 1000.0).round() as i64);
    }
    assert_eq!(labels.len(), 9, "{labels:?}");
    assert_eq!(pan_radii, BTreeSet::from([80, 90, 100]));
}
