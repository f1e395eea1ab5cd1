//! The paper's tasks added as task files (Threading, Three Piece Assembly, Coffee, the drawer
//! tasks, Kitchen and Coffee Preparation from primitive geoms; Pick Place with robosuite's object
//! meshes), described only by their task files: scenes compose and rest, nothing succeeds at
//! reset, the bundled scripted demos end in success with their signals in order, and generation
//! from them succeeds.
#![allow(clippy::indexing_slicing, reason = "test helpers: an index out of range fails the test, as it should")]
#![allow(clippy::unwrap_used)] // tests fail loudly by design

use std::ops::ControlFlow;
use std::sync::Arc;

use mimicgen_engine::{Environment as _, Generator, TaskSpec};
use mimicgen_sim::{Scene, SimEnv, registry};
use rand::SeedableRng as _;

/// Resets `task` / `variant` a few times, lets the scene settle, and returns how far each object
/// moved while settling (m) and whether the task was ever achieved.
fn settle(task: &str, variant: &str) -> (f64, bool) {
    let task = registry::task(task, variant).unwrap();
    let scene = Arc::new(Scene::for_task(task.as_ref()).unwrap());
    let mut env = SimEnv::new(scene, Arc::clone(&task));
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    let (mut moved, mut success) = (0.0_f64, false);
    for _ in 0..5 {
        env.reset(&mut rng).unwrap();
        let before = env.object_poses();
        for _ in 0..10 {
            env.step(&[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, -1.0]).unwrap();
        }
        for (name, pose) in env.object_poses() {
            moved = moved.max((pose.translation.vector - before[&name].translation.vector).norm());
        }
        success |= task.is_success(env.physics());
    }
    (moved, success)
}

/// `task`'s reset scenes in every one of `variants` rest (no object moves 1 cm in 10 steps) and
/// are not solved.
fn rests_unsolved(task: &str, variants: &[&str]) {
    for variant in variants {
        let (moved, success) = settle(task, variant);
        assert!(moved < 0.01 && !success, "{task} {variant}: moved {moved:.4} m, success {success}");
    }
}

/// `task`'s D0 scene after a reset (seed 1) and 20 steps with the arm still: what its movable
/// parts rest at.
fn settled(task: &str) -> (Arc<dyn mimicgen_sim::Task>, SimEnv) {
    let task = registry::task(task, "D0").unwrap();
    let scene = Arc::new(Scene::for_task(task.as_ref()).unwrap());
    let mut env = SimEnv::new(scene, Arc::clone(&task));
    env.reset(&mut rand_chacha::ChaCha8Rng::seed_from_u64(1)).unwrap();
    for _ in 0..20 {
        env.step(&[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, -1.0]).unwrap();
    }
    (task, env)
}

/// The bundled demos of `task` end in success with `signals` turning on in this order, and a few
/// generated attempts in `variant` succeed.
fn bundled_demos_succeed_and_generate(task_name: &str, signals: &[&str], variant: &str) {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("data/{task_name}_D0_source.hdf5"));
    let sources = mimicgen_io::read_source_dataset(&path, &Default::default()).unwrap();
    assert_eq!(sources.demos.len(), 10);
    let task = registry::task(task_name, "D0").unwrap();
    let scene = Arc::new(Scene::for_task(task.as_ref()).unwrap());
    let mut env = SimEnv::new(Arc::clone(&scene), Arc::clone(&task));
    for demo in &sources.demos {
        let first: Vec<usize> = signals.iter().map(|s| demo.subtask_term_signals[*s].iter().position(|&v| v != 0).unwrap()).collect();
        assert!(first.windows(2).all(|w| w[0] < w[1]), "{}: signals {signals:?} first on at {first:?}", demo.name);
        // Fixed objects (the tripod) are not in robosuite's state: put them where the demo had them.
        env.place_fixed_objects(&mimicgen_engine::demo::initial_object_poses(&demo.object_poses));
        env.reset_to_state(demo.sim.states.row(0)).unwrap();
        assert!(!task.is_success(env.physics()), "{} starts unsolved", demo.name);
        assert!(task.unmet_success(env.physics()).is_some(), "{}: an unsolved state names what is unmet", demo.name);
        env.reset_to_state(demo.sim.states.row(demo.len() - 1)).unwrap();
        let poses = env.object_poses();
        let rel: Vec<_> = poses.values().map(|p| p.translation.vector).collect();
        assert!(task.is_success(env.physics()), "{} ends in success: {rel:?} obs {:?}", demo.name, task.object_obs(env.physics()));
        assert_eq!(task.unmet_success(env.physics()), None, "{}", demo.name);
    }
    let spec = TaskSpec::from_toml_str(registry::default_spec_toml(task_name).unwrap(), "spec").unwrap();
    let generator = Generator::new(spec, sources).unwrap().with_seed(1);
    let task = registry::task(task_name, variant).unwrap();
    let mut envs = vec![SimEnv::new(Arc::new(Scene::for_task(task.as_ref()).unwrap()), task)];
    let (mut successes, mut attempts) = (0, 0);
    mimicgen_engine::run_with(
        &generator,
        &mut envs,
        mimicgen_engine::RunControl::default(),
        |_, _| Ok(()),
        |a, (), _| {
            attempts += 1;
            successes += usize::from(a.success);
            if attempts < 8 { ControlFlow::Continue(()) } else { ControlFlow::Break(Ok(())) }
        },
    )
    .unwrap();
    assert!(successes >= 2, "{task_name} {variant}: {successes} of {attempts} generated attempts succeeded");
}

#[test]
fn nut_assembly_demos_put_both_nuts_on_their_pegs() {
    bundled_demos_succeed_and_generate("nut_assembly", &["grasp_square_nut", "insert_square_nut", "grasp_round_nut"], "D0");
}

#[test]
fn threading_scenes_rest_and_its_demos_thread_the_needle() {
    rests_unsolved("threading", &["D0", "D1", "D2"]);
    let task = registry::task("threading", "D0").unwrap();
    let scene = Scene::for_task(task.as_ref()).unwrap();
    assert!(scene.objects[1].mocap.is_some(), "the tripod is fixed in the world");
    bundled_demos_succeed_and_generate("threading", &["grasp"], "D0");
}

#[test]
fn three_piece_assembly_scenes_rest_and_its_demos_assemble() {
    rests_unsolved("three_piece_assembly", &["D0", "D1", "D2"]);
    bundled_demos_succeed_and_generate("three_piece_assembly", &["grasp_1", "insert_1", "grasp_2"], "D0");
}

#[test]
fn three_piece_assembly_counts_the_post_in_the_tube_not_lying_across_it() {
    use mimicgen_engine::pose::{Rot, Vec3, pose_from_parts};
    let task = registry::task("three_piece_assembly", "D0").unwrap();
    let scene = Arc::new(Scene::for_task(task.as_ref()).unwrap());
    let mut env = SimEnv::new(scene, Arc::clone(&task));
    let assembled = |env: &mut SimEnv, post: Rot, dz: f64| {
        env.reset(&mut rand_chacha::ChaCha8Rng::seed_from_u64(2)).unwrap();
        let base = env.physics().object_pose(0).translation.vector;
        let tube = base + Vec3::new(0.0, 0.0, 0.019);
        env.place_object(1, &pose_from_parts(tube, Rot::identity()));
        env.place_object(2, &pose_from_parts(tube + Vec3::new(0.0, 0.0, dz), post));
        for _ in 0..10 {
            env.step(&[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, -1.0]).unwrap();
        }
        task.is_success(env.physics())
    };
    assert!(assembled(&mut env, Rot::identity(), 0.034), "the post down in the tube");
    let lying = Rot::from_axis_angle(&Vec3::x_axis(), std::f64::consts::FRAC_PI_2);
    assert!(!assembled(&mut env, lying, 0.038 + 0.0125), "the post lying across the tube's top");
    // Turned 45 deg, the post's diagonal (3.4 cm) does not fit the 3 cm hole: it stands on the rim.
    let turned = Rot::from_axis_angle(&Vec3::z_axis(), std::f64::consts::FRAC_PI_4);
    assert!(!assembled(&mut env, turned, 0.038 + 0.026), "the post standing on the tube's rim");
}

#[test]
fn coffee_starts_open_and_its_demos_insert_the_pod_and_shut_the_lid() {
    rests_unsolved("coffee", &["D0", "D1", "D2"]);
    // The lid starts open (hinge at 0), resting against its stop, and the hinge is observed.
    let (task, env) = settled("coffee");
    let obs = task.object_obs(env.physics());
    assert_eq!(obs.len(), 7 + 7 + 7 + 7 + 1);
    assert!(obs[28].abs() < 0.05, "hinge at {:.3} rad", obs[28]);
    // A failed attempt says which parts of the success condition are unmet: both, at the start.
    assert_eq!(task.unmet_success(env.physics()).as_deref(), Some("pod in machine and machine_hinge in [85, inf]"));
    bundled_demos_succeed_and_generate("coffee", &["grasp"], "D0");
}

#[test]
fn pick_place_objects_rest_on_the_table_and_its_demos_fill_the_bin() {
    rests_unsolved("pick_place", &["D0"]);
    let task = registry::task("pick_place", "D0").unwrap();
    let names: Vec<String> = task.objects().into_iter().map(|(o, _)| o).collect();
    assert_eq!(names, ["milk", "bread", "cereal", "can", "bin"]);
    let signals = ["grasp_milk", "place_milk", "grasp_bread", "place_bread", "grasp_cereal", "place_cereal", "grasp_can"];
    bundled_demos_succeed_and_generate("pick_place", &signals, "D0");
}

#[test]
fn mug_cleanup_drawer_starts_shut_and_its_demos_open_it_put_the_mug_in_and_shut_it() {
    use mimicgen_engine::pose::{Rot, Vec3, pose_from_parts};
    rests_unsolved("mug_cleanup", &["D0", "D1"]);
    let task = registry::task("mug_cleanup", "D0").unwrap();
    let scene = Arc::new(Scene::for_task(task.as_ref()).unwrap());
    assert!(scene.objects[1].mocap.is_some(), "the cabinet is fixed in the world");
    let mut env = SimEnv::new(Arc::clone(&scene), Arc::clone(&task));
    env.reset(&mut rand_chacha::ChaCha8Rng::seed_from_u64(1)).unwrap();
    let obs = task.object_obs(env.physics());
    assert_eq!(obs.len(), 7 + 7 + 7 + 7 + 1);
    assert!(obs[28].abs() < 1e-6, "the drawer starts shut: slide at {:.4} m", obs[28]);
    assert_eq!(task.unmet_success(env.physics()).as_deref(), Some("mug in drawer"));

    // Along a bundled demo: whenever the drawer is out, the task is not done; it ends done.
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("data/mug_cleanup_D0_source.hdf5");
    let demo = mimicgen_io::read_source_dataset(&path, &Default::default()).unwrap().demos.remove(0);
    env.place_fixed_objects(&mimicgen_engine::demo::initial_object_poses(&demo.object_poses));
    let mut furthest = 0.0_f64;
    for t in (0..demo.len()).step_by(5) {
        env.reset_to_state(demo.sim.states.row(t)).unwrap();
        let out = task.object_obs(env.physics())[28];
        furthest = furthest.max(out);
        if out > 0.02 {
            assert!(!task.is_success(env.physics()), "step {t}: the drawer is {out:.3} m out");
        }
    }
    assert!(furthest > 0.15, "the demo pulls the drawer out: at most {furthest:.3} m");
    env.reset_to_state(demo.sim.states.row(demo.len() - 1)).unwrap();
    assert!(task.is_success(env.physics()));
    // The same mug in the shut drawer, lying on its side, is not put away.
    let mug = env.physics().object_pose(0).translation.vector;
    env.place_object(0, &pose_from_parts(mug + Vec3::new(0.0, 0.0, 0.04), Rot::from_axis_angle(&Vec3::x_axis(), 1.4)));
    env.step(&[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, -1.0]).unwrap();
    assert!(task.unmet_success(env.physics()).unwrap().contains("mug upright"), "{:?}", task.unmet_success(env.physics()));

    bundled_demos_succeed_and_generate("mug_cleanup", &["open", "grasp"], "D0");
}

#[test]
fn hammer_cleanup_demos_open_the_drawer_put_the_hammer_in_and_shut_it() {
    rests_unsolved("hammer_cleanup", &["D0", "D1"]);
    let task = registry::task("hammer_cleanup", "D0").unwrap();
    let names: Vec<String> = task.objects().into_iter().map(|(o, _)| o).collect();
    assert_eq!(names, ["hammer", "drawer"]);
    bundled_demos_succeed_and_generate("hammer_cleanup", &["open", "grasp"], "D0");
}

#[test]
fn kitchen_switch_starts_off_and_its_demos_cook_serve_and_switch_off() {
    rests_unsolved("kitchen", &["D0", "D1"]);
    let (task, env) = settled("kitchen");
    // The switch rests against its off stop (the last observation term, radians).
    let obs = task.object_obs(env.physics());
    assert_eq!(obs.len(), 5 * 7 + 1);
    assert!(obs[35].abs() < 0.02, "switch at {:.3} rad", obs[35]);
    assert_eq!(task.signals(env.physics())["stove_on"], 0);
    let signals = ["stove_on", "grasp_pot", "place_pot_on_stove", "grasp_bread", "place_bread_in_pot", "serve"];
    bundled_demos_succeed_and_generate("kitchen", &signals, "D0");
}

#[test]
fn coffee_preparation_starts_shut_and_its_demos_open_lid_and_drawer_then_shut_the_lid_on_the_pod() {
    rests_unsolved("coffee_preparation", &["D0", "D1"]);
    let (task, mut env) = settled("coffee_preparation");
    // Six 7-number terms (mug, pod, machine, drawer poses; mug and pod relative to the gripper),
    // then the lid's hinge and the drawer's slide: both rest shut.
    let obs = task.object_obs(env.physics());
    assert_eq!(obs.len(), 6 * 7 + 2);
    assert!(obs[42].abs() < 0.02, "lid hinge at {:.3} rad", obs[42]);
    assert!(obs[43].abs() < 1e-3, "drawer slide at {:.4} m", obs[43]);
    assert_eq!(task.unmet_success(env.physics()).as_deref(), Some("mug in machine and pod in machine"));

    // Along a bundled demo the lid opens past 95 deg and the drawer past 12 cm, and while the lid
    // is open the task is not done (the drawer may stay out at the end, as in the reference).
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("data/coffee_preparation_D0_source.hdf5");
    let demo = mimicgen_io::read_source_dataset(&path, &Default::default()).unwrap().demos.remove(0);
    env.place_fixed_objects(&mimicgen_engine::demo::initial_object_poses(&demo.object_poses));
    let (mut widest, mut furthest) = (0.0_f64, 0.0_f64);
    for t in (0..demo.len()).step_by(5) {
        env.reset_to_state(demo.sim.states.row(t)).unwrap();
        let obs = task.object_obs(env.physics());
        (widest, furthest) = (widest.min(obs[42]), furthest.max(obs[43]));
        if obs[42] < -0.1 {
            assert!(!task.is_success(env.physics()), "step {t}: the lid is open at {:.2} rad", obs[42]);
        }
    }
    assert!(widest < -95_f64.to_radians(), "the demo opens the lid: at most {widest:.3} rad");
    assert!(furthest > 0.12, "the demo pulls the drawer out: at most {furthest:.3} m");
    bundled_demos_succeed_and_generate("coffee_preparation", &["mug_grasp", "mug_place", "drawer_open", "pod_grasp"], "D0");
}
