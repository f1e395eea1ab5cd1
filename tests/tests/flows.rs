//! Flows across crates: a reference config drives generation, and what comes out is usable again.
#![allow(clippy::unwrap_used)] // tests fail loudly by design

use std::ops::ControlFlow;

use mimicgen_engine::kinematic::{self, PickPlace};
use mimicgen_engine::segment::Segmentation;
use mimicgen_engine::{Generator, SourceDataset, TaskSpec, run};
use mimicgen_tests::repo_path;

#[test]
fn reference_config_drives_generation_and_generated_demos_are_valid_sources() {
    // The reference Stack config names cubeA/cubeB and the `grasp` signal, as the kinematic
    // pick-and-place environment does, so it drives that environment unchanged.
    let mut spec = TaskSpec::load(&repo_path("core/engine/tests/data/config_D0.json")).unwrap();
    spec.generation.num_trials = 12;
    let generator = Generator::new(spec.clone(), kinematic::scripted_dataset(5, 3).unwrap()).unwrap();
    let mut envs = vec![PickPlace::new(0.08), PickPlace::new(0.08)];
    let mut generated = Vec::new();
    let stats = run(&generator, &mut envs, |attempt, _| {
        if attempt.success {
            generated.push(attempt.trajectory.to_source_demo(&format!("demo_{}", generated.len())));
        }
        ControlFlow::Continue(())
    })
    .unwrap();
    assert_eq!(stats.attempts, 12);
    assert!(generated.len() >= 10, "{} of 12", generated.len());
    // Every generated demo segments cleanly with the same spec (offsets included) ...
    let dataset = SourceDataset { demos: generated, env_args: None };
    dataset.validate().unwrap();
    let segmentation = Segmentation::new(&dataset.demos, &spec).unwrap();
    assert_eq!(segmentation.num_demos(), dataset.demos.len());
    // ... and can seed a second round of generation.
    spec.generation.num_trials = 5;
    let second = Generator::new(spec, dataset).unwrap();
    let stats = run(&second, &mut envs, |_, _| ControlFlow::Continue(())).unwrap();
    assert!(stats.successes >= 4, "{stats:?}");
}

/// The whole product path on the real backend: read bundled source demos, annotate subtask ends
/// by hand, generate in MuJoCo, write a robomimic dataset, read it back as sources again.
#[test]
fn load_annotate_generate_write_reread_in_mujoco() {
    use std::sync::Arc;

    use mimicgen_io::{DatasetWriter, WriterOptions};
    use mimicgen_sim::{Scene, SimEnv, registry};

    let task = registry::task("stack", "D0").unwrap();
    let mut spec = TaskSpec::from_toml_str(registry::default_spec_toml("stack").unwrap(), "stack.toml").unwrap();
    spec.generation.num_trials = 3;
    let mut sources = mimicgen_io::read_source_dataset(repo_path("core/sim/data/stack_D0_source.hdf5"), &spec.source).unwrap();
    // Annotate by hand: end the grasp subtask where the signal says, so generation is unchanged,
    // but through the manual-boundary path.
    for demo in &mut sources.demos {
        let end = mimicgen_engine::segment::subtask_end_from_signal(&demo.subtask_term_signals["grasp"], 0).unwrap();
        demo.manual_subtask_ends = Some(vec![end]);
    }
    let scene = Arc::new(Scene::for_task(task.as_ref()).unwrap());
    let generator = Generator::new(spec.clone(), sources).unwrap();
    let mut envs = vec![SimEnv::new(Arc::clone(&scene), Arc::clone(&task))];
    let mut obs_env = SimEnv::new(Arc::clone(&scene), Arc::clone(&task));
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("generated.hdf5");
    let mut writer =
        DatasetWriter::create(&out, WriterOptions { env_args: Some(registry::env_args("stack", "D0")), ..WriterOptions::default() })
            .unwrap();
    let mut written = Vec::new();
    let stats = run(&generator, &mut envs, |attempt, _| {
        if attempt.success {
            let obs = obs_env.observations_for_states(&attempt.trajectory.states).unwrap();
            writer.append_attempt(&attempt, obs, None).unwrap();
            written.push(attempt);
        }
        ControlFlow::Continue(())
    })
    .unwrap();
    writer.finish().unwrap();
    assert_eq!(stats.attempts, 3);
    assert!(!written.is_empty(), "{stats:?}");
    let reread = mimicgen_io::read_source_dataset(&out, &spec.source).unwrap();
    assert_eq!(reread.demos.len(), written.len());
    for (demo, attempt) in reread.demos.iter().zip(&written) {
        assert_eq!(demo.sim.actions, attempt.trajectory.actions);
        assert_eq!(demo.sim.states, attempt.trajectory.states);
        assert_eq!(demo.eef_poses.len(), attempt.trajectory.len());
    }
    // The generated demos are valid sources themselves.
    Segmentation::new(&reread.demos, &spec).unwrap();
}
