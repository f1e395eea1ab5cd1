//! Square (robosuite's square nut and peg): the peg moves between episodes and not within one,
//! the bundled scripted demos succeed, and demos generated around a moved peg are written with a
//! `model_file` that puts the peg where it was.
#![allow(clippy::unwrap_used)] // tests fail loudly by design

use std::collections::BTreeMap;
use std::ops::ControlFlow;
use std::sync::Arc;

use mimicgen_engine::pose::{Rot, Vec3, pose_from_parts, yaw_of};
use mimicgen_engine::{Environment as _, Generator, TaskSpec};
use mimicgen_sim::{Scene, SimEnv, Task, registry};
use rand::SeedableRng as _;

fn data(path: &str) -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(path)
}

#[test]
fn the_peg_moves_between_episodes_and_stays_put_within_one() {
    let task: Arc<dyn Task> = registry::task("square", "D2").unwrap();
    let scene = Arc::new(Scene::for_task(task.as_ref()).unwrap());
    assert!(scene.objects[1].mocap.is_some() && scene.objects[0].qpos_adr.is_some());
    let mut env = SimEnv::new(Arc::clone(&scene), Arc::clone(&task));
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    let mut pegs = Vec::new();
    for _ in 0..3 {
        env.reset(&mut rng).unwrap();
        let peg = env.physics().object_pose(1);
        let yaw = yaw_of(&peg);
        assert!((-1e-9..=std::f64::consts::FRAC_PI_2 + 1e-9).contains(&yaw), "peg yaw {yaw}");
        for _ in 0..10 {
            env.step(&[0.0; 7]).unwrap();
        }
        // Fixed during the episode; the nut has dropped onto the table (top at 0.82 m), clear of it.
        assert!((env.physics().object_pose(1).translation.vector - peg.translation.vector).norm() < 1e-12);
        let nut = env.physics().object_pose(0).translation.vector;
        assert!((nut.z - 0.83).abs() < 0.003, "nut at {nut:?}");
        assert!((nut - peg.translation.vector).xy().norm() > 0.14, "nut {nut:?} on the peg {peg:?}");
        pegs.push(peg.translation.vector);
    }
    assert!((pegs[0] - pegs[1]).norm() > 1e-3 && (pegs[1] - pegs[2]).norm() > 1e-3, "{pegs:?}");

    // A robosuite scene's peg has no joint and is no mocap body; compiling makes it one.
    let xml = mimicgen_sim::compose::compose_scene(
        &mimicgen_sim::assets::robosuite_assets_dir().unwrap(),
        &task.object_models(),
        task.table_top_z(),
    );
    // (Both pegs: robosuite's NutAssemblySquare builds the round one too.)
    let plain = mimicgen_sim::mjcf_edit::edit_body(&xml, "peg1", &[], &["mocap"]).unwrap();
    let plain = mimicgen_sim::mjcf_edit::edit_body(&plain, "peg2", &[], &["mocap"]).unwrap();
    assert!(!plain.contains("mocap"));
    let scene = Scene::compile(&plain, "robosuite-like", &task.objects(), 20.0).unwrap();
    let names: Vec<&str> = scene.objects.iter().map(|o| o.name.as_str()).collect();
    assert_eq!(names, ["square_nut", "square_peg", "round_nut", "round_peg"]);
    assert!(scene.objects[1].mocap.is_some() && scene.objects[3].mocap.is_some());
}

#[test]
fn success_is_robosuites_on_peg_check() {
    let task: Arc<dyn Task> = registry::task("square", "D0").unwrap();
    let scene = Arc::new(Scene::for_task(task.as_ref()).unwrap());
    let mut env = SimEnv::new(scene, task);
    env.reset(&mut rand_chacha::ChaCha8Rng::seed_from_u64(1)).unwrap();
    let peg = env.physics().object_pose(1).translation.vector;
    let mut check = |offset: Vec3| {
        env.place_object(0, &pose_from_parts(peg + offset, Rot::identity()));
        env.place_fixed_objects(&BTreeMap::new());
        env.is_success()
    };
    assert!(check(Vec3::new(0.0, 0.0, 0.83 - 0.85)), "resting round the peg");
    assert!(check(Vec3::new(0.025, -0.025, 0.0)), "low enough and within 3 cm");
    assert!(!check(Vec3::new(0.0, 0.0, 0.03)), "still high on the peg");
    assert!(!check(Vec3::new(0.035, 0.0, -0.02)), "beside the peg");
}

#[test]
fn bundled_demos_succeed_and_generated_demos_carry_their_peg() {
    let sources = mimicgen_io::read_source_dataset(data("data/square_D0_source.hdf5"), &Default::default()).unwrap();
    assert_eq!(sources.demos.len(), 10);
    let (task, variant) = registry::task_from_env_args(sources.env_args.as_deref()).unwrap();
    assert_eq!((task.name(), variant.as_str()), ("square", "D0"));
    let xml = sources.demos[0].sim.model_xml.clone().unwrap();
    let d0_scene = Arc::new(Scene::from_model_file(&xml, "square_D0_source.hdf5", task.as_ref()).unwrap());
    let mut check = SimEnv::new(Arc::clone(&d0_scene), Arc::clone(&task));
    for demo in &sources.demos {
        // States are recorded before each action: the nut is on the peg by the last few.
        let on_peg = (demo.len() - 5..demo.len()).any(|t| {
            check.reset_to_state(demo.sim.states.row(t)).unwrap();
            check.is_success()
        });
        assert!(on_peg, "{} does not end on the peg", demo.name);
        assert!(demo.subtask_term_signals["grasp"].contains(&1), "{} never grasps", demo.name);
    }

    let d0_scene_peg = check.physics().object_pose(1).translation.vector;
    assert!((d0_scene_peg - Vec3::new(0.23, 0.1, 0.85)).norm() < 1e-12, "robosuite's default peg, {d0_scene_peg:?}");

    // Generate on D1 (the peg moves) from the D0 demos, as `mimicgen generate` does.
    let d1: Arc<dyn Task> = registry::task("square", "D1").unwrap();
    let mut spec = TaskSpec::from_toml_str(registry::default_spec_toml("square").unwrap(), "square.toml").unwrap();
    spec.generation.num_trials = 6;
    let generator = Generator::new(spec, sources).unwrap();
    let mut envs = vec![SimEnv::new(Arc::clone(&d0_scene), Arc::clone(&d1))];
    let mut written = Vec::new();
    let stats = mimicgen_engine::run(&generator, &mut envs, |attempt, _| {
        if attempt.success {
            let initial = mimicgen_engine::demo::initial_object_poses(&attempt.trajectory.object_poses);
            written.push((d0_scene.xml_with_fixed_objects(&xml, &initial).unwrap(), attempt.trajectory.states.clone(), initial));
        }
        ControlFlow::Continue(())
    })
    .unwrap();
    println!("{} of {} attempts succeeded", stats.successes, stats.attempts);
    assert!(stats.successes >= 2, "{stats:?}");
    for (model_xml, states, initial) in &written {
        let last = states.row(states.len() - 1);
        // The written model_file alone puts the peg back where the attempt had it ...
        let scene = Arc::new(Scene::from_model_file(model_xml, "generated model_file", d1.as_ref()).unwrap());
        let mut replay = SimEnv::new(scene, Arc::clone(&d1));
        replay.reset_to_state(last).unwrap();
        let peg = replay.physics().object_pose(1).translation.vector;
        assert!((peg - initial["square_peg"].translation.vector).norm() < 1e-9, "{peg:?} vs {initial:?}");
        // ... so the recorded states put the nut on it there, and not on the D0 scene's peg.
        let ends_on_peg = |env: &mut SimEnv| {
            (states.len().saturating_sub(20)..states.len()).any(|t| {
                env.reset_to_state(states.row(t)).unwrap();
                env.is_success()
            })
        };
        assert!(ends_on_peg(&mut replay));
        if (peg - d0_scene_peg).xy().norm() > 0.03 {
            assert!(!ends_on_peg(&mut check));
        }
    }
}

/// robosuite's NutAssemblySquare builds Nut Assembly's whole scene and clears the round nut to
/// (10, 10, 10) at every reset (`clear_objects`); MimicGen's D1 and D2 move the round peg to
/// x = -10. Ours does the same, so our states carry the round nut's free joint and robosuite loads
/// our `model_file`s (`scripts/test.sh` replays generated Square D0 demos there).
#[test]
fn the_round_nut_and_peg_are_where_robosuite_leaves_them() {
    for variant in ["D0", "D1", "D2"] {
        let task: Arc<dyn Task> = registry::task("square", variant).unwrap();
        let scene = Arc::new(Scene::for_task(task.as_ref()).unwrap());
        let mut env = SimEnv::new(Arc::clone(&scene), Arc::clone(&task));
        env.reset(&mut rand_chacha::ChaCha8Rng::seed_from_u64(1)).unwrap();
        let index = |name: &str| scene.objects.iter().position(|o| o.name == name).unwrap();
        let nut = index("round_nut");
        assert!(scene.objects[nut].qpos_adr.is_some(), "{variant}: the round nut has a free joint");
        let at = env.physics().object_pose(nut).translation.vector;
        assert!((at - Vec3::new(10.0, 10.0, 10.0)).norm() < 1e-9, "{variant}: round nut at {at:?}");
        let x = env.physics().object_pose(index("round_peg")).translation.vector.x;
        let want = if variant == "D0" { 0.23 } else { -10.0 };
        assert!((x - want).abs() < 1e-9, "{variant}: round peg at x {x}, want {want}");
    }
}
