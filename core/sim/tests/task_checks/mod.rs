//! Checks the paper's task files share: scenes rest unsolved, bundled demos succeed with their
//! signals in order, generation from them succeeds; and the task files' parts.

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
    // Hold still, open (and a mobile base's part of the action at rest).
    let mut hold = vec![0.0; env.action_dim()];
    hold[6] = -1.0;
    for _ in 0..5 {
        env.reset(&mut rng).unwrap();
        let before = env.object_poses();
        for _ in 0..10 {
            env.step(&hold).unwrap();
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
pub fn rests_unsolved(task: &str, variants: &[&str]) {
    for variant in variants {
        let (moved, success) = settle(task, variant);
        assert!(moved < 0.01 && !success, "{task} {variant}: moved {moved:.4} m, success {success}");
    }
}

/// `task`'s task file from `core/sim/tasks`, parsed.
pub fn task_file(task: &str) -> mimicgen_sim::TaskFile {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("tasks/{task}.task.toml"));
    mimicgen_sim::TaskFile::from_toml_str(&std::fs::read_to_string(&path).unwrap(), task).unwrap()
}

/// The geoms of `file`'s compound object `name`.
pub fn compound_geoms(file: &mimicgen_sim::TaskFile, name: &str) -> Vec<mimicgen_sim::compose::Part> {
    match &file.objects.iter().find(|o| o.name == name).unwrap().model {
        mimicgen_sim::compose::ObjectModel::Compound { geoms, .. } => geoms.clone(),
        other => panic!("{name}: not a compound: {other:?}"),
    }
}

/// Restores `demo`'s stored states at `steps` in order, each noted as a step would note it (the
/// task's `ever` conditions: Kitchen remembers the stove being on with the pot and bread on it).
pub fn restore_in_order(env: &mut SimEnv, demo: &mimicgen_engine::demo::SourceDemo, steps: std::ops::Range<usize>) {
    for t in steps {
        env.set_state(demo.sim.states.row(t)).unwrap();
        env.record_history();
    }
}

/// The 10 bundled demos of `task` end in success with `signals` turning on in this order, and
/// generated attempts in `variant` succeed: two within the first 16 (the run stops at the second).
pub fn bundled_demos_succeed_and_generate(task_name: &str, signals: &[&str], variant: &str) {
    bundled_demos_succeed_and_generate_n(task_name, signals, variant, 10);
}

/// [`bundled_demos_succeed_and_generate`] for a task with `demos` bundled demos.
pub fn bundled_demos_succeed_and_generate_n(task_name: &str, signals: &[&str], variant: &str, demos: usize) {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("data/{task_name}_D0_source.hdf5"));
    let sources = mimicgen_io::read_source_dataset(&path, &Default::default()).unwrap();
    assert_eq!(sources.demos.len(), demos);
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
        restore_in_order(&mut env, demo, 1..demo.len());
        let poses = env.object_poses();
        let rel: Vec<_> = poses.values().map(|p| p.translation.vector).collect();
        assert!(task.is_success(env.physics()), "{} ends in success: {rel:?} obs {:?}", demo.name, task.object_obs(env.physics()));
        assert_eq!(task.unmet_success(env.physics()), None, "{}", demo.name);
    }
    let spec = TaskSpec::from_toml_str(registry::default_spec_toml(task_name).unwrap(), "spec").unwrap();
    let generator = Generator::new(spec, sources).unwrap().with_seed(1);
    let (successes, attempts) = crate::common::generate_until(&generator, task_name, variant, 2, 16);
    assert!(successes >= 2, "{task_name} {variant}: {successes} of {attempts} generated attempts succeeded");
}
