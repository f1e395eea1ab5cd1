//! Planned transit on the MuJoCo backend: the arm's configuration space, paths round the C0
//! variants' clutter, and generation with them.
#![allow(clippy::unwrap_used)] // tests fail loudly by design

use std::ops::ControlFlow;
use std::sync::Arc;

use mimicgen_engine::spec::Transit;
use mimicgen_engine::transit::{PlannerSettings, TransitSpace as _, plan_transit};
use mimicgen_engine::{Attempt, Environment as _, Generator, TaskSpec};
use mimicgen_sim::{Scene, SimEnv, registry};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

fn env(task: &str, variant: &str) -> SimEnv {
    let task = registry::task(task, variant).unwrap();
    let scene = Arc::new(Scene::for_task(task.as_ref()).unwrap());
    SimEnv::new(scene, task)
}

fn reset(env: &mut SimEnv, seed: u64) {
    env.reset(&mut ChaCha8Rng::seed_from_u64(seed)).unwrap();
}

#[test]
fn the_clutter_is_in_c0_only_and_is_an_obstacle() {
    for (task, obstacle) in [("stack", "wall"), ("square", "post")] {
        let d0 = registry::task(task, "D0").unwrap();
        assert!(d0.objects().iter().all(|(name, _)| name != obstacle), "{task} D0 has the {obstacle}");
        assert!(d0.obstacles().is_empty());
        let c0 = registry::task(task, "C0").unwrap();
        let index = c0.objects().iter().position(|(name, _)| name == obstacle).unwrap();
        assert_eq!(c0.obstacles(), vec![index]);
    }
    // Fresh scenes touch nothing: the robot starts clear of the clutter.
    for seed in 0..5 {
        let mut e = env("stack", "C0");
        reset(&mut e, seed);
        assert_eq!(e.obstacle_contacts(), 0, "seed {seed}");
    }
}

#[test]
fn inverse_kinematics_finds_poses_the_arm_reached() {
    let mut e = env("stack", "D0");
    reset(&mut e, 3);
    let mut space = e.arm_space();
    let home = space.joints();
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    for _ in 0..10 {
        use rand::Rng as _;
        let q: Vec<f64> = home.iter().map(|v| v + rng.random_range(-0.3..0.3)).collect();
        let pose = space.eef_pose_at(&q);
        let found = space.inverse_kinematics(&pose, &home).unwrap();
        let reached = space.eef_pose_at(&found);
        assert!((reached.translation.vector - pose.translation.vector).norm() < 1.5e-3);
        assert!(reached.rotation.angle_to(&pose.rotation) < 0.015);
    }
}

#[test]
fn a_path_over_the_wall_is_free_at_every_check_and_the_same_for_a_seed() {
    let mut e = env("stack", "C0");
    reset(&mut e, 1);
    let cube_b = e.object_poses()["cubeB"];
    // The gripper 8 cm above the green cube, pointing down as it starts.
    let mut goal = e.eef_pose();
    goal.translation.vector = cube_b.translation.vector + mimicgen_engine::pose::Vec3::new(0.0, 0.0, 0.08);
    let plan = |e: &mut SimEnv, seed| {
        let mut space = e.arm_space();
        plan_transit(&mut space, &goal, &PlannerSettings::default(), &mut ChaCha8Rng::seed_from_u64(seed)).unwrap()
    };
    let path = plan(&mut e, 4);
    assert_eq!(path.joints, plan(&mut e, 4).joints);
    let mut space = e.arm_space();
    assert!(space.collisions_at(&space.joints()).is_empty());
    let mut prev = space.joints();
    for q in &path.joints {
        for k in 0..=4 {
            let at: Vec<f64> = prev.iter().zip(q).map(|(a, b)| a + (b - a) * f64::from(k) / 4.0).collect();
            let hit = space.collisions_at(&at);
            assert!(hit.is_empty(), "the path touches {hit:?}");
        }
        prev.clone_from(q);
    }
    let end = space.eef_pose_at(path.joints.last().unwrap());
    assert!((end.translation.vector - goal.translation.vector).norm() < 2e-3);
}

fn generate(task: &str, transit: Transit, attempts: usize, workers: usize) -> Vec<Attempt> {
    let sources = mimicgen_io::read_source_dataset(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("data/{task}_D0_source.hdf5")),
        &Default::default(),
    )
    .unwrap();
    let text = std::fs::read_to_string(std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("tasks/{task}.toml"))).unwrap();
    let mut spec = TaskSpec::from_toml_str(&text, task).unwrap();
    spec.generation.num_trials = attempts;
    for subtask in &mut spec.subtasks {
        subtask.transit = transit;
    }
    let generator = Generator::new(spec, sources).unwrap();
    let mut envs: Vec<SimEnv> = (0..workers).map(|_| env(task, "C0")).collect();
    let mut out = Vec::new();
    mimicgen_engine::run(&generator, &mut envs, |a, _| {
        out.push(a);
        ControlFlow::Continue(())
    })
    .unwrap();
    out
}

#[test]
fn in_clutter_planned_transit_succeeds_where_interpolation_hits_the_wall() {
    let interpolated = generate("stack", Transit::Interpolate, 10, 2);
    let planned = generate("stack", Transit::Plan, 10, 2);
    let rate = |a: &[Attempt]| a.iter().filter(|a| a.success).count();
    let touched = |a: &[Attempt]| a.iter().filter(|a| a.obstacle_contact_steps > 0).count();
    println!(
        "interpolated {} ok, {} touched; planned {} ok, {} touched",
        rate(&interpolated),
        touched(&interpolated),
        rate(&planned),
        touched(&planned)
    );
    assert!(rate(&planned) >= rate(&interpolated) + 5, "planned {} against interpolated {}", rate(&planned), rate(&interpolated));
    assert!(touched(&interpolated) >= 8 && touched(&planned) < touched(&interpolated));
    // Every planned subtask starts with its transit, which ends at the segment's first pose.
    for attempt in planned.iter().filter(|a| a.success) {
        assert!(attempt.plans.iter().all(|p| p.transit.is_some_and(|t| t.checks > 0)));
    }
}

#[test]
fn planned_generation_is_the_same_with_one_worker_or_two() {
    let one = generate("stack", Transit::Plan, 3, 1);
    let two = generate("stack", Transit::Plan, 3, 2);
    for (a, b) in one.iter().zip(&two) {
        assert_eq!(a.trajectory.actions, b.trajectory.actions, "attempt {}", a.index);
        assert_eq!(a.trajectory.kinds, b.trajectory.kinds);
    }
}
