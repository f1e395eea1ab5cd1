//! MimicGen generation on the MuJoCo backend from the reference's own source demos and config.
#![allow(clippy::unwrap_used)] // tests fail loudly by design

use std::ops::ControlFlow;
use std::sync::Arc;

use mimicgen_engine::{Generator, TaskSpec};
use mimicgen_sim::{Scene, SimEnv, Stack};

fn data(path: &str) -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(path)
}

#[test]
fn reference_sources_generate_stack_demos() {
    let mut spec = TaskSpec::load(&data("../engine/tests/data/config_D0.json")).unwrap();
    spec.generation.num_trials = 6;
    let sources = mimicgen_io::read_source_dataset(data("../io/tests/data/source_D0_prepared.hdf5"), &spec.source).unwrap();
    let xml = sources.demos[0].sim.model_xml.clone().unwrap();
    let task = Arc::new(Stack::variant("D0").unwrap());
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
    let task = Arc::new(Stack::variant("D0").unwrap());
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
    let task = Arc::new(Stack::variant("D0").unwrap());
    let scene = Arc::new(Scene::for_task(task.as_ref()).unwrap());
    let mut env = SimEnv::new(scene, task);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
    let script = Stack::script();
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
