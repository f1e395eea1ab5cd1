//! The run doctor on the MuJoCo backend: suggestions from a run's causes, tested on the attempts
//! after the run's, the same in every arm.
#![allow(clippy::indexing_slicing, reason = "test helpers: an index out of range fails the test, as it should")]
#![allow(clippy::unwrap_used)] // tests fail loudly by design

use std::path::Path;
use std::sync::atomic::AtomicBool;

use mimicgen_pipeline::doctor::{DoctorConfig, DoctorEvent, doctor};
use mimicgen_pipeline::{Event, Pipeline, PipelineError, RunConfig, Scoped, SpecOverrides};

/// Stack D0 with so much action noise that grasps miss: seed 3, `attempts` attempts.
fn noisy(out: &Path, attempts: usize) -> RunConfig {
    RunConfig {
        num_demos: Some(attempts),
        workers: 2,
        out: out.to_path_buf(),
        seed: Some(3),
        spec: SpecOverrides { action_noise: vec![Scoped::all(0.3)], ..SpecOverrides::default() },
        ..RunConfig::default()
    }
}

/// Successes of each attempt of a run, by index.
fn outcomes(config: &RunConfig) -> Vec<bool> {
    let pipeline = Pipeline::prepare(config).unwrap();
    let mut out = Vec::new();
    pipeline
        .run(&AtomicBool::new(false), |e| {
            if let Event::Attempt(a) = e {
                out.push(a.attempt.success);
            }
        })
        .unwrap();
    out
}

#[test]
fn the_doctor_tests_what_the_causes_point_at_on_the_attempts_after_the_run() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("noisy.hdf5");
    let (run, tested) = (24, 20);
    let run_outcomes = outcomes(&noisy(&out, run));
    let report = mimicgen_pipeline::doctor::read_report(&out).unwrap().0;
    assert!(report.generation_rate < 0.9, "the test needs failures: {report:?}");
    let missed = report.causes.iter().find(|c| c.subtask == 0 && c.cause == "grasp_missed").map_or(0, |c| c.count);
    assert!(report.causes.iter().all(|c| c.count <= missed), "grasps should miss most with this much noise: {:?}", report.causes);

    let config = DoctorConfig { run: out.clone(), budget: 2 * tested, top: 1, workers: 2, check: 12 };
    let mut events = Vec::new();
    let d = doctor(&config, &AtomicBool::new(false), |e| events.push(e.clone())).unwrap();
    // The most frequent cause's change first: half the noise where the grasps missed.
    let top = &d.suggestions[0];
    assert_eq!(top.change.action_noise, [Scoped { subtask: Some(0), value: 0.15 }], "{:?}", d.suggestions);
    assert!(top.addresses >= missed && d.suggestions.windows(2).all(|w| w[0].addresses >= w[1].addresses));
    assert_eq!((d.first_attempt, d.attempts, d.trials.len()), (run, tested, 1));
    assert!(matches!(events.first(), Some(DoctorEvent::Started { arms: 2, attempts, .. }) if *attempts == tested));
    let checking = events.iter().position(|e| matches!(e, DoctorEvent::Checking { .. })).unwrap();
    let last = |arm: usize| {
        events[..checking].iter().rev().find_map(|e| match e {
            DoctorEvent::Attempt { arm: a, done, successes } if *a == arm => Some((*done, *successes)),
            _ => None,
        })
    };
    assert_eq!(last(0), Some((tested, d.base_successes)));
    assert_eq!(last(1), Some((tested, d.trials[0].paired.changed_successes)));

    // The run's own spec on the tested attempts is the run continued: attempts 24..44 of the same
    // command, so each change meets the same scenes.
    let longer = outcomes(&noisy(&dir.path().join("longer.hdf5"), run + tested));
    assert_eq!(longer[..run], run_outcomes[..], "a longer run starts as the run");
    let base = longer[run..].iter().filter(|&&s| s).count();
    assert_eq!(d.base_successes, base);
    let t = &d.trials[0];
    assert_eq!(t.paired.changed_successes - t.paired.gained + t.paired.lost, base, "paired counts: {:?}", t.paired);
    assert!(t.command.contains("--seed 3") && t.command.contains("--action-noise 0.3 --action-noise 0:0.15"), "{}", t.command);

    // Checked on 12 fresh attempts: the run's next seed from its first attempt.
    let check = d.check.as_ref().unwrap();
    assert_eq!((check.trial, check.seed, check.paired.attempts), (0, 4, 12));
    let fresh = outcomes(&RunConfig { seed: Some(4), ..noisy(&dir.path().join("fresh.hdf5"), 12) });
    assert_eq!(check.paired.base_successes, fresh.iter().filter(|&&s| s).count());
    assert!(events.iter().any(|e| matches!(e, DoctorEvent::Checking { trial: 0, attempts: 12 })));

    // The same diagnosis on one worker.
    let again = doctor(&DoctorConfig { workers: 1, ..config }, &AtomicBool::new(false), |_| {}).unwrap();
    assert_eq!(again, d);
}

#[test]
fn the_doctor_names_what_it_cannot_read() {
    let dir = tempfile::tempdir().unwrap();
    let cancel = AtomicBool::new(false);
    let run =
        |path: &Path, budget| doctor(&DoctorConfig { run: path.to_path_buf(), budget, top: 3, workers: 1, check: 0 }, &cancel, |_| {});
    let missing = dir.path().join("gone.hdf5");
    let e = run(&missing, 100).unwrap_err().to_string();
    assert!(e.contains("gone.json") && e.contains("beside"), "{e}");
    let bad = dir.path().join("bad.json");
    std::fs::write(&bad, "{\"task\": 3}").unwrap();
    let e = run(&bad, 100).unwrap_err();
    assert!(
        matches!(&e, PipelineError::Input { file, .. } if file.ends_with("bad.json"))
            && e.to_string().contains("not a `mimicgen generate` report"),
        "{e}"
    );
    // A real run, and a budget below one attempt per arm.
    let out = dir.path().join("run.hdf5");
    outcomes(&noisy(&out, 8));
    let e = run(&out, 1).unwrap_err().to_string();
    assert!(e.contains("--budget"), "{e}");
}
