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
