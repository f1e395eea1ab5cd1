//! MimicGen generation on the MuJoCo backend from the reference's own source demos and config.
#![allow(clippy::unwrap_used)] // tests fail loudly by design

use std::ops::ControlFlow;
use std::sync::Arc;

use mimicgen_engine::{Generator, TaskSpec};
use mimicgen_sim::{Scene, SimEnv, registry};

fn data(path: &str) -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(path)
}

#[test]
fn reference_sources_generate_stack_demos() {
    let mut spec = TaskSpec::load(&data("../engine/tests/data/config_D0.json")).unwrap();
    spec.generation.num_trials = 6;
    let sources = mimicgen_io::read_source_dataset(data("../io/tests/data/source_D0_prepared.hdf5"), &spec.source).unwrap();
    let xml = sources.demos[0].sim.model_xml.clone().unwrap();
    let task = registry::task("stack", "D0").unwrap();
    let scene = Arc::new(Scene::from_model_file(&xml, "source_D0_prepared.hdf5", task.as_ref()).unwrap());
    let generator = Generator::new(spec, sources).unwrap();
    let mut envs = vec![SimEnv::new(Arc::clone(&scene), task.clone()), SimEnv::new(scene, task)];
    let started = std::time::Instant::now();
    let mut failures = Vec::new();
    let stats = mimicgen_engine::run(&generator, &mut envs, |a, _| {
        failures.extend(a.failure);
        ControlFlow::Continue(())
    })
    .unwrap();
    println!("{} / {} succeeded in {:.1} s; failures {failures:?}", stats.successes, stats.attempts, started.elapsed().as_secs_f64());
    assert_eq!(stats.attempts, 6);
    assert!(stats.successes >= 4, "{stats:?}");
}

#[test]
fn composed_stack_scene_matches_the_reference_scene() {
    let task = registry::task("stack", "D0").unwrap();
    let composed = Scene::for_task(task.as_ref()).unwrap();
    let sources = mimicgen_io::read_source_dataset(data("../io/tests/data/source_D0_prepared.hdf5"), &Default::default()).unwrap();
    let reference = Scene::from_model_file(sources.demos[0].sim.model_xml.as_ref().unwrap(), "model_file", task.as_ref()).unwrap();
    assert_eq!(composed.state_dim(), reference.state_dim());
    // The same recorded state gives the same poses in both scenes.
    let mut a = SimEnv::new(Arc::new(composed), task.clone());
    let mut b = SimEnv::new(Arc::new(reference), task);
    for state in sources.demos[0].sim.states.iter().step_by(10) {
        a.reset_to_state(state).unwrap();
        b.reset_to_state(state).unwrap();
        use mimicgen_engine::Environment as _;
        assert!((a.eef_pose().translation.vector - b.eef_pose().translation.vector).norm() < 1e-12);
        assert_eq!(a.object_poses(), b.object_poses());
    }
}

#[test]
fn scripted_demonstrator_stacks_in_mujoco() {
    use mimicgen_engine::Environment as _;
    use rand::SeedableRng;
    let task = registry::task("stack", "D0").unwrap();
    let scene = Arc::new(Scene::for_task(task.as_ref()).unwrap());
    let script = task.scripts().remove(0);
    let mut env = SimEnv::new(scene, task);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
    let mut successes = 0;
    for i in 0..10 {
        env.reset(&mut rng).unwrap();
        let demo = script.record(&mut env, &format!("demo_{i}"), &mut rng).unwrap();
        let grasped = demo.subtask_term_signals["grasp"].iter().any(|&v| v != 0);
        println!("demo_{i}: {} steps, grasped {grasped}, success {}", demo.len(), env.is_success());
        successes += usize::from(env.is_success());
    }
    assert!(successes >= 8, "{successes} of 10");
}

#[test]
fn same_seed_same_demos_with_one_or_two_workers_and_blowups_are_failures() {
    use mimicgen_engine::{EnvError, Environment as _};
    let task: Arc<dyn mimicgen_sim::Task> = registry::task("stack", "D1").unwrap();
    let mut spec = TaskSpec::from_toml_str(mimicgen_sim::registry::default_spec_toml("stack").unwrap(), "stack.toml").unwrap();
    spec.generation.num_trials = 4;
    let sources = mimicgen_io::read_source_dataset(data("data/stack_D0_source.hdf5"), &spec.source).unwrap();
    let scene = Arc::new(Scene::for_task(task.as_ref()).unwrap());
    let generator = Generator::new(spec, sources).unwrap();
    let collect = |workers: usize| {
        let mut envs: Vec<SimEnv> = (0..workers).map(|_| SimEnv::new(Arc::clone(&scene), Arc::clone(&task))).collect();
        let mut attempts = Vec::new();
        mimicgen_engine::run(&generator, &mut envs, |a, _| {
            attempts.push(a);
            ControlFlow::Continue(())
        })
        .unwrap();
        attempts
    };
    let one = collect(1);
    let two = collect(2);
    assert_eq!(one.len(), 4);
    for (a, b) in one.iter().zip(&two) {
        assert_eq!(a.trajectory.states, b.trajectory.states, "attempt {}", a.index);
        assert_eq!(a.trajectory.actions, b.trajectory.actions);
        assert_eq!(a.success, b.success);
    }
    // A non-finite action is reported as an unstable simulation, which fails only that attempt.
    let mut env = SimEnv::new(Arc::clone(&scene), Arc::clone(&task));
    let mut rng = <rand_chacha::ChaCha8Rng as rand::SeedableRng>::seed_from_u64(0);
    env.reset(&mut rng).unwrap();
    assert!(matches!(env.step(&[f64::NAN, 0.0, 0.0, 0.0, 0.0, 0.0, -1.0]), Err(EnvError::Unstable { .. })));
    // So is a real blow-up: absurd joint velocities make MuJoCo flag bad accelerations.
    let mut state = env.state();
    let n = state.len();
    state[n - 21..].fill(1e30);
    env.set_state(&state).unwrap();
    let err = env.step(&[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, -1.0]).unwrap_err();
    assert!(matches!(&err, EnvError::Unstable { reason } if reason.contains("MuJoCo") || reason.contains("non-finite")), "{err}");
}

#[test]
fn bad_scenes_name_the_file_and_what_is_missing() {
    let task = registry::task("stack", "D0").unwrap();
    let err = Scene::compile("<mujoco><worldbody><body><geom type='box'/></body>", "broken.xml", &[], 20.0).unwrap_err().to_string();
    assert!(err.contains("broken.xml") && err.contains("cannot compile"), "{err}");
    // A valid scene without the task's objects (the composed scene with no objects at all).
    let assets = mimicgen_sim::assets::robosuite_assets_dir().unwrap();
    let empty = mimicgen_sim::compose::compose_scene(&assets, &[], mimicgen_sim::compose::BASE_TABLE_TOP_Z);
    let err = Scene::compile(&empty, "empty.xml", &task.objects(), 20.0).unwrap_err().to_string();
    assert!(err.contains("empty.xml") && err.contains("cubeA_main"), "{err}");
    assert!(registry::task("stack", "D7").err().unwrap_or_default().contains("D0, D1 and C0"));
}
