//! The pipeline end to end on the MuJoCo backend: workers, observations, outputs, cancel, inputs.
#![allow(clippy::indexing_slicing, reason = "test helpers: an index out of range fails the test, as it should")]
#![allow(clippy::unwrap_used)] // tests fail loudly by design

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};

use mimicgen_engine::segment::Segmentation;
use mimicgen_engine::{SubtaskMarks, TaskSpec};
use mimicgen_io::RobomimicDataset;
use mimicgen_io::tree::{Array, Node};
use mimicgen_pipeline::{Event, FrontEnd, Outcome, Pipeline, PipelineError, RunConfig};

fn data(path: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(path)
}

fn config(out: &Path, attempts: usize, workers: usize) -> RunConfig {
    RunConfig { num_demos: Some(attempts), workers, out: out.to_path_buf(), seed: Some(3), ..RunConfig::default() }
}

fn run(config: &RunConfig) -> Result<(mimicgen_pipeline::Report, Vec<Event>), PipelineError> {
    let pipeline = Pipeline::prepare(config)?;
    let mut events = Vec::new();
    let report = pipeline.run(&AtomicBool::new(false), |e| events.push(e.clone()))?;
    Ok((report, events))
}

/// Every `file="..."` path of an MJCF string.
fn file_paths(xml: &str) -> Vec<&str> {
    xml.split("file=\"").skip(1).filter_map(|rest| rest.split('"').next()).collect()
}

#[test]
fn workers_compute_observations_and_the_dataset_does_not_depend_on_their_number() {
    let dir = tempfile::tempdir().unwrap();
    let one = dir.path().join("one.hdf5");
    let two = dir.path().join("two.hdf5");
    let mut with_failed = config(&one, 6, 1);
    with_failed.keep_failed = true;
    let (report, events) = run(&with_failed).unwrap();
    let (report2, _) = run(&RunConfig { keep_failed: true, ..config(&two, 6, 2) }).unwrap();
    assert_eq!((report.attempts, report.successes), (report2.attempts, report2.successes));
    assert!(report.successes >= 4, "{report:?}");
    assert!(matches!(events.first(), Some(Event::Started(_))) && matches!(events.last(), Some(Event::Finished(_))));
    let attempts: Vec<_> = events.iter().filter_map(|e| if let Event::Attempt(a) = e { Some(a) } else { None }).collect();
    assert_eq!(attempts.iter().map(|a| a.attempt.index).collect::<Vec<_>>(), (0..6).collect::<Vec<_>>());
    assert_eq!(attempts.iter().filter(|a| matches!(a.outcome, Outcome::Written { .. })).count(), report.successes);
    let a = RobomimicDataset::open(&one).unwrap();
    let b = RobomimicDataset::open(&two).unwrap();
    assert_eq!(a.demo_names().len(), report.successes);
    assert_eq!(a.data(), b.data(), "1 and 2 workers wrote different data");
    let demo = a.demo("demo_0").unwrap();
    for key in ["obs/robot0_eef_pos", "obs/object", "obs/robot0_joint_pos", "states", "actions"] {
        assert!(demo.dataset_at(key).is_some(), "demo_0 lacks {key}");
    }
    // No asset path we write may have a `mimicgen` component: MimicGen's envs would re-point it
    // into their own package and fail to load the robot's meshes.
    let failed = RobomimicDataset::open(dir.path().join("one_failed.hdf5")).unwrap();
    for file in [&a, &failed] {
        for name in file.demo_names() {
            let xml = file.demo(name).unwrap().attrs["model_file"].as_str().unwrap().to_owned();
            let paths = file_paths(&xml);
            assert!(paths.len() > 10, "{name}: {} asset paths", paths.len());
            for path in paths {
                assert!(!path.split('/').any(|c| c == "mimicgen"), "{name}: {path}");
            }
        }
    }
    // The outputs say which controller generation used.
    let env_args: serde_json::Value = serde_json::from_str(a.env_args().unwrap()).unwrap();
    assert_eq!(env_args["env_name"], "Stack_D0");
    assert_eq!(env_args["env_kwargs"]["controller_configs"]["kp"], 150);
}

#[test]
fn existing_outputs_are_never_replaced_silently() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("d.hdf5");
    run(&config(&out, 1, 1)).unwrap();
    let err = run(&config(&out, 1, 1)).unwrap_err();
    assert!(err.is_user_error() && matches!(err, PipelineError::Exists { resumable: false, .. }), "{err}");
    // The library names no front end's option; each front end words the choice its own way.
    assert!(!err.to_string().contains("--"), "{err}");
    assert!(err.worded(FrontEnd::Cli).ends_with("exists; pass --overwrite to replace it, or choose another output"), "{err}");
    assert!(err.worded(FrontEnd::Python).contains("pass overwrite=True"), "{err}");
    run(&RunConfig { overwrite: true, ..config(&out, 2, 1) }).unwrap();
    assert_eq!(RobomimicDataset::open(&out).unwrap().demo_names().len(), {
        let r: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(dir.path().join("d.json")).unwrap()).unwrap();
        usize::try_from(r["successes"].as_u64().unwrap()).unwrap()
    });
    // A run with no .partial to resume says so.
    let err = run(&RunConfig { resume: true, ..config(&dir.path().join("none.hdf5"), 1, 1) }).unwrap_err();
    assert!(err.to_string().contains("no interrupted run"), "{err}");
}

#[test]
fn cancel_stops_cleanly_with_a_valid_dataset() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("c.hdf5");
    let pipeline = Pipeline::prepare(&config(&out, 40, 2)).unwrap();
    let cancel = AtomicBool::new(false);
    let mut seen = 0;
    let report = pipeline
        .run(&cancel, |e| {
            if let Event::Attempt(_) = e {
                seen += 1;
                if seen == 3 {
                    cancel.store(true, Ordering::Relaxed);
                }
            }
        })
        .unwrap();
    assert!(report.cancelled);
    assert_eq!(report.attempts, 3);
    let file = RobomimicDataset::open(&out).unwrap();
    assert_eq!(file.demo_names().len(), report.successes);
    assert!(!mimicgen_io::DatasetWriter::partial_path(&out).exists());
}

#[test]
fn bad_inputs_name_the_file_and_field() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("x.hdf5");
    let err = Pipeline::prepare(&RunConfig { valid_fraction: Some(1.5), ..config(&out, 1, 1) }).unwrap_err();
    assert!(err.to_string().contains("--valid-fraction"), "{err}");
    // A NaN gripper action in a source file.
    let source = mimicgen_pipeline::bundled::source_demos("stack").unwrap();
    let mut file = RobomimicDataset::open(&source).unwrap();
    let Some(Node::Group(demo)) = file.root.members.get_mut("data").and_then(|d| match d {
        Node::Group(g) => g.members.get_mut("demo_3"),
        Node::Dataset(_) => None,
    }) else {
        panic!("no demo_3")
    };
    let Some(Node::Group(info)) = demo.members.get_mut("datagen_info") else { panic!("no datagen_info") };
    let Some(Node::Dataset(grip)) = info.members.get_mut("gripper_action") else { panic!("no gripper_action") };
    let mut values = grip.array.values.to_f64().unwrap();
    values[7] = f64::NAN;
    grip.array = Array::f64(grip.array.shape.clone(), values);
    let bad = dir.path().join("nan_source.hdf5");
    file.write(&bad).unwrap();
    let err = Pipeline::prepare(&RunConfig { source: Some(bad), ..config(&out, 1, 1) }).unwrap_err().to_string();
    assert!(err.contains("nan_source.hdf5") && err.contains("demo_3") && err.contains("gripper_action"), "{err}");
}

#[test]
fn a_mimicgen_config_selects_its_env_and_the_reference_sources_pass_the_controller_check() {
    let mut json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(data("../engine/tests/data/config_D0.json")).unwrap()).unwrap();
    json["experiment"]["task"]["name"] = "Stack_D1".into();
    let dir = tempfile::tempdir().unwrap();
    let cfg = dir.path().join("config_D1.json");
    std::fs::write(&cfg, json.to_string()).unwrap();
    let source = data("../io/tests/data/source_D0_prepared.hdf5");
    let base = RunConfig { config: Some(cfg.clone()), source: Some(source.clone()), ..config(&dir.path().join("o.hdf5"), 1, 1) };
    let pipeline = Pipeline::prepare(&base).unwrap();
    assert_eq!((pipeline.task().name(), pipeline.variant()), ("stack", "D1"));
    let env_args: serde_json::Value = serde_json::from_str(pipeline.env_args()).unwrap();
    assert_eq!(env_args["env_name"], "Stack_D1");
    // Explicit arguments win over the inputs; a different task is a contradiction.
    let explicit = Pipeline::prepare(&RunConfig { variant: Some("D0".into()), ..base.clone() }).unwrap();
    assert_eq!(explicit.variant(), "D0");
    let err = Pipeline::prepare(&RunConfig { task: Some("square".into()), ..base }).unwrap_err().to_string();
    assert!(err.contains("config_D1.json") && err.contains("square"), "{err}");
}

/// MimicGen's `parse_source_dataset`, written out from its numpy: the end of subtask `i` is
/// `t + 2` for the first `t` with `signal[t + 1] != signal[t]` and `t + 1 >= previous end`.
fn reference_spans(signals: &[&[i64]], len: usize) -> Vec<(usize, usize)> {
    let mut spans = Vec::new();
    let mut prev = 0;
    for signal in signals {
        let end_ind = (0..signal.len() - 1).find(|&t| signal[t + 1] != signal[t] && t + 1 >= prev).unwrap() + 1;
        spans.push((prev, end_ind + 1));
        prev = end_ind + 1;
    }
    spans.push((prev, len));
    spans
}

#[test]
fn nominal_segments_equal_the_references_on_its_own_source_file() {
    let spec = TaskSpec::load(&data("../engine/tests/data/config_D0.json")).unwrap();
    let sources = mimicgen_io::read_source_dataset(data("../io/tests/data/source_D0_prepared.hdf5"), &spec.source).unwrap();
    assert_eq!(sources.demos.len(), 10);
    let segmentation = Segmentation::new(&sources.demos, &spec).unwrap();
    let names: Vec<&str> = spec.subtasks.iter().filter_map(|s| s.term_signal.as_deref()).collect();
    for (d, demo) in sources.demos.iter().enumerate() {
        let signals: Vec<&[i64]> = names.iter().map(|n| demo.subtask_term_signals[*n].as_slice()).collect();
        assert_eq!(segmentation.nominal_spans(d), reference_spans(&signals, demo.len()), "{}", demo.name);
    }
}

/// The Stack D0 rate on the reference's own source demos and config, held against the same engine
/// driving robosuite itself (BENCHMARKS.md, "Physics fidelity": 484 of 500, 96.8 %). These
/// attempts are the first 200 of the seed-11 run BENCHMARKS.md reports (477 of 500 on our backend,
/// 187 of these 200): a fixed, deterministic sample. A change to the physics, the controller or
/// the engine that costs 5 points turns about 10 of its successes into failures, under the bound
/// (183).
#[test]
fn the_stack_d0_rate_on_the_references_files_stays_near_robosuites() {
    const ROBOSUITE_RATE: f64 = 0.968;
    const ATTEMPTS: usize = 200;
    let dir = tempfile::tempdir().unwrap();
    let config = RunConfig {
        seed: Some(11),
        source: Some(data("../io/tests/data/source_D0_prepared.hdf5")),
        config: Some(data("../engine/tests/data/config_D0.json")),
        ..config(&dir.path().join("rate.hdf5"), ATTEMPTS, 2)
    };
    let (report, _) = run(&config).unwrap();
    #[allow(clippy::cast_precision_loss, clippy::cast_possible_truncation, clippy::cast_sign_loss)]
    let bound = ((ROBOSUITE_RATE - 0.05) * ATTEMPTS as f64).floor() as usize;
    println!("Stack D0 from the reference's files: {} of {ATTEMPTS} (bound {bound})", report.successes);
    assert!(report.successes >= bound, "{} of {ATTEMPTS} succeeded; robosuite: {ROBOSUITE_RATE}", report.successes);
}

/// Auto-detected subtask ends against the ends the stored signals give, on the reference's own
/// source demos (human teleoperation on robosuite) and on our bundled Square demos: the goal is
/// 90 % of boundaries within 5 steps (BENCHMARKS.md has every task). The Square demos re-recorded
/// with robosuite's round nut in the scene reach 8 of 10: in two, the fingers stop on the nut 7
/// and 12 steps before both pads touch it.
#[test]
fn detected_subtask_ends_land_within_five_steps_of_the_signals() {
    use mimicgen_pipeline::annotate;
    let square = mimicgen_pipeline::bundled::source_demos("square").unwrap();
    for (path, least) in [(data("../io/tests/data/source_D0_prepared.hdf5"), 9), (square, 8)] {
        let found = annotate::propose(&path, None, None).unwrap();
        let distances = found.distances();
        assert_eq!(distances.len(), 10, "{}", path.display());
        let within = distances.iter().filter(|&&d| d <= 5).count();
        println!("{}: distances {distances:?}", path.display());
        assert!(within >= least, "{}: only {within} of 10 within 5 steps: {distances:?}", path.display());
        assert!(found.demos.iter().flat_map(|d| &d.proposals).all(|p| p.confidence > 0.0 && !p.reason.is_empty()));
    }
}

/// Ends written by `write_annotations` are where MimicGen's annotation script puts them (0 before
/// the marked step, 1 from it) and read back as the same segments, replacing the old signals.
#[test]
fn written_annotations_read_back_as_the_same_segments() {
    use mimicgen_pipeline::annotate;
    let source = data("../io/tests/data/source_D0_prepared.hdf5");
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("annotated.hdf5");
    let spec = TaskSpec::load(&data("../engine/tests/data/config_D0.json")).unwrap();
    let ends = std::collections::BTreeMap::from([("demo_0".to_owned(), vec![40]), ("demo_3".to_owned(), vec![77])]);
    annotate::write_annotations(&source, &out, &spec, &ends, &std::collections::BTreeMap::new()).unwrap();
    let back = mimicgen_io::read_source_dataset(&out, &spec.source).unwrap();
    let segmentation = Segmentation::new(&back.demos, &spec).unwrap();
    assert_eq!(segmentation.nominal_spans(0)[0], (0, 40));
    assert_eq!(segmentation.nominal_spans(3)[0], (0, 77));
    let grasp = &back.demos[0].subtask_term_signals["grasp"];
    assert_eq!((grasp[38], grasp[39], grasp[grasp.len() - 1]), (0, 1, 1));
    // Other demos are untouched.
    let original = mimicgen_io::read_source_dataset(&source, &spec.source).unwrap();
    assert_eq!(back.demos[1], original.demos[1]);
    // Bad ends name the demo.
    let err = annotate::write_annotations(
        &source,
        &out,
        &spec,
        &std::collections::BTreeMap::from([("demo_0".to_owned(), vec![500])]),
        &std::collections::BTreeMap::new(),
    )
    .unwrap_err()
    .to_string();
    assert!(err.contains("demo_0") && err.contains("500"), "{err}");
}

/// Hand-marked segment starts are written beside the ends, read back, and replace the detected
/// approach of a planned subtask; a start past the demo is refused naming the demo.
#[test]
fn marked_segment_starts_read_back_and_start_planned_segments() {
    use std::collections::BTreeMap;

    use mimicgen_engine::spec::Transit;
    use mimicgen_pipeline::annotate;
    let source = data("../io/tests/data/source_D0_prepared.hdf5");
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("marked.hdf5");
    let mut spec = TaskSpec::load(&data("../engine/tests/data/config_D0.json")).unwrap();
    let original = mimicgen_io::read_source_dataset(&source, &spec.source).unwrap();
    // Three steps into demo_2's place (which runs to the demo's end).
    let (place_start, place_end) = Segmentation::new(&original.demos, &spec).unwrap().nominal_spans(2)[1];
    let mark = place_start + 3;
    assert!(mark + 2 < place_end);
    let starts = BTreeMap::from([("demo_2".to_owned(), vec![None, Some(mark)])]);
    annotate::write_annotations(&source, &out, &spec, &BTreeMap::new(), &starts).unwrap();
    let back = mimicgen_io::read_source_dataset(&out, &spec.source).unwrap();
    assert_eq!(back.demos[2].manual_subtask_starts, Some(vec![None, Some(mark)]));
    assert_eq!(back.demos[1].manual_subtask_starts, None);
    for subtask in &mut spec.subtasks {
        subtask.transit = Transit::Plan;
    }
    let detected = Segmentation::new(&original.demos, &spec).unwrap();
    let marked = Segmentation::new(&back.demos, &spec).unwrap();
    assert_eq!(marked.approach_starts(2)[1], Some(mark));
    assert_ne!(detected.approach_starts(2)[1], Some(mark));
    assert_eq!(marked.approach_starts(2)[0], detected.approach_starts(2)[0]);
    let err = annotate::write_annotations(
        &source,
        &out,
        &spec,
        &BTreeMap::new(),
        &BTreeMap::from([("demo_0".to_owned(), vec![None, Some(5000)])]),
    )
    .unwrap_err()
    .to_string();
    assert!(err.contains("demo_0") && err.contains("5000"), "{err}");
}

/// "Try it" in the app is the attempt a run makes: same seed and index, same actions step for
/// step; the plan's first subtask is that attempt's; hand-set ends equal to the signals' change
/// nothing, other ends change the segment the attempt executes.
#[test]
fn a_tried_attempt_is_the_attempt_a_run_makes() {
    use mimicgen_engine::Overrides;
    use mimicgen_pipeline::preview::Previewer;
    let dir = tempfile::tempdir().unwrap();
    let cfg = config(&dir.path().join("run.hdf5"), 3, 1);
    let (_, events) = run(&cfg).unwrap();
    let attempts: Vec<_> = events
        .iter()
        .filter_map(|e| match e {
            Event::Attempt(a) => Some(a.attempt.clone()),
            _ => None,
        })
        .collect();
    let mut preview = Previewer::new(&cfg, &SubtaskMarks::default()).unwrap();
    let signal_ends: std::collections::BTreeMap<String, Vec<usize>> = preview
        .generator()
        .dataset()
        .demos
        .iter()
        .enumerate()
        .map(|(d, demo)| (demo.name.clone(), vec![preview.generator().segmentation().nominal_spans(d)[0].1]))
        .collect();
    let marks = |ends: &std::collections::BTreeMap<String, Vec<usize>>| SubtaskMarks { ends: ends.clone(), ..SubtaskMarks::default() };
    preview.configure(&marks(&signal_ends), 3).unwrap();
    for ran in &attempts {
        let tried = preview.try_attempt(ran.index, &Overrides::default()).unwrap();
        assert_eq!(tried.trajectory.actions, ran.trajectory.actions, "attempt {}", ran.index);
        assert_eq!(tried.success, ran.success);
        let plan = preview.plan(ran.index, &Overrides::default()).unwrap();
        assert_eq!(plan.subtasks[0].waypoints, ran.plans[0].waypoints);
    }
    let demo = attempts[0].plans[0].src_demo;
    let mut moved = signal_ends.clone();
    let name = preview.generator().dataset().demos[demo].name.clone();
    moved.insert(name.clone(), vec![signal_ends[&name][0] - 12]);
    preview.configure(&marks(&moved), 3).unwrap();
    let plan = preview.plan(attempts[0].index, &Overrides { sources: vec![Some(demo)], ..Overrides::default() }).unwrap();
    assert_eq!(plan.subtasks[0].src_span.1 + 12, attempts[0].plans[0].src_span.1);
    // Ends that do not fit name the demo.
    let bad = std::collections::BTreeMap::from([(name.clone(), vec![100_000])]);
    let err = preview.configure(&marks(&bad), 3).unwrap_err().to_string();
    assert!(err.contains(&name), "{err}");
    // So do starts of a demo the file does not have.
    let unknown = SubtaskMarks { starts: std::collections::BTreeMap::from([("demo_99".to_owned(), vec![None, Some(3)])]), ..marks(&moved) };
    let err = preview.configure(&unknown, 3).unwrap_err().to_string();
    assert!(err.contains("demo_99") && err.contains("segment starts"), "{err}");
}

/// Spec fields given for a run (`--action-noise 1:0.2`, the app's form) change the spec the run
/// uses, and its report's description; the same run without them does not have them.
#[test]
fn spec_overrides_reach_the_generator_and_the_report() {
    use mimicgen_pipeline::{Scoped, SpecOverrides};
    let dir = tempfile::tempdir().unwrap();
    let overrides = SpecOverrides {
        action_noise: vec![Scoped { subtask: Some(1), value: 0.2 }],
        interpolation_steps: vec![Scoped::all(9)],
        ..SpecOverrides::default()
    };
    let plain = Pipeline::prepare(&config(&dir.path().join("a.hdf5"), 2, 1)).unwrap();
    let changed = Pipeline::prepare(&RunConfig { spec: overrides.clone(), ..config(&dir.path().join("a.hdf5"), 2, 1) }).unwrap();
    let noise =
        |p: &Pipeline| p.generator().spec().subtasks.iter().map(|s| (s.action_noise, s.num_interpolation_steps)).collect::<Vec<_>>();
    assert_eq!(noise(&plain), [(0.05, 5), (0.05, 5)]);
    assert_eq!(noise(&changed), [(0.05, 9), (0.2, 9)]);
    let (report, _) = run(&RunConfig { spec: overrides, ..config(&dir.path().join("b.hdf5"), 1, 1) }).unwrap();
    assert_eq!(report.attempts, 1);
    let written = std::fs::read_to_string(dir.path().join("b.json")).unwrap();
    let read: mimicgen_pipeline::Report = serde_json::from_str(&written).unwrap();
    assert!((read.spec_overrides.action_noise[0].value - 0.2).abs() < 1e-12, "the report keeps the spec fields the run set");
    let bad = SpecOverrides { fixed_steps: vec![Scoped { subtask: Some(5), value: 1 }], ..SpecOverrides::default() };
    let err = Pipeline::prepare(&RunConfig { spec: bad, ..config(&dir.path().join("c.hdf5"), 1, 1) }).unwrap_err().to_string();
    assert!(err.contains("--fixed-steps") && err.contains("subtask 5"), "{err}");
}

/// `--shard i/K` runs joined by `merge` give the single run's files: the same root tree (demos,
/// arrays, attributes, masks, progress), the same failed attempts, the same report counts; with a
/// fixed number of attempts and with `guarantee`. Bad shard sets are refused, naming the file.
#[test]
fn merged_shards_equal_the_single_process_run() {
    use mimicgen_engine::Shard;
    use mimicgen_pipeline::merge::merge;
    use mimicgen_pipeline::{Scoped, SpecOverrides};
    let dir = tempfile::tempdir().unwrap();
    // Noisier than the spec, so that some attempts fail and the failed file has something to join.
    let noisy = SpecOverrides { action_noise: vec![Scoped { subtask: Some(0), value: 0.3 }], ..SpecOverrides::default() };
    let base = |out: PathBuf, guarantee: bool| RunConfig {
        keep_failed: true,
        guarantee,
        valid_fraction: Some(0.25),
        spec: noisy.clone(),
        ..config(&out, if guarantee { 5 } else { 9 }, 2)
    };
    let tree = |p: &Path| RobomimicDataset::open(p).unwrap().root;
    let timeless = |r: &mimicgen_pipeline::Report| mimicgen_pipeline::Report {
        wall_time_s: 0.0,
        attempts_per_s: 0.0,
        peak_rss_mib: None,
        workers: 0,
        output: String::new(),
        failed_output: None,
        // The merged run's quality report sums its demos' figures from the shards' logs: the same
        // report as the single process's, but for the file it names.
        quality: r.quality.clone().map(|q| mimicgen_pipeline::DatasetQuality { dataset: String::new(), ..q }),
        ..r.clone()
    };
    for guarantee in [false, true] {
        let single = dir.path().join(format!("single_{guarantee}.hdf5"));
        let (whole, _) = run(&base(single.clone(), guarantee)).unwrap();
        assert!(whole.successes < whole.attempts, "the test needs failures: {whole:?}");
        // Each failure's cause counted once, and each kept failure carrying its own.
        let count = |counts: &mut dyn Iterator<Item = usize>| counts.sum::<usize>();
        assert_eq!(count(&mut whole.causes.iter().map(|c| c.count)), whole.attempts - whole.successes, "{:?}", whole.causes);
        let failed = RobomimicDataset::open(dir.path().join(format!("single_{guarantee}_failed.hdf5"))).unwrap();
        assert!(!failed.demo_names().is_empty());
        for name in failed.demo_names() {
            let json = failed.demo(name).unwrap().attrs[mimicgen_io::CAUSE_ATTR].as_str().unwrap().to_owned();
            let cause: mimicgen_engine::diagnose::Cause = serde_json::from_str(&json).unwrap();
            assert!(whole.causes.iter().any(|c| c.cause == cause.class()), "{name}: {cause:?} not in {:?}", whole.causes);
        }
        for count in [2, 3] {
            let mut shards = Vec::new();
            for part in 0..count {
                let out = dir.path().join(format!("shard_{guarantee}_{part}of{count}.hdf5"));
                let shard = Shard::new(part, count).unwrap();
                let (report, _) = run(&RunConfig { shard: Some(shard), workers: 1, ..base(out.clone(), guarantee) }).unwrap();
                assert_eq!(report.shard, Some(shard));
                shards.push(out);
            }
            let merged = dir.path().join(format!("merged_{guarantee}_{count}.hdf5"));
            let report = merge(&shards, &merged, false, |_, _| {}).unwrap();
            assert_eq!(tree(&merged), tree(&single), "guarantee {guarantee}, {count} shards");
            let failed = |p: &Path| tree(&mimicgen_pipeline::sibling(p, "_failed", "hdf5"));
            assert_eq!(failed(&merged), failed(&single));
            assert_eq!(timeless(&report), timeless(&whole));
            assert!(report.quality.as_ref().is_some_and(|q| q.quality.attempts == report.successes), "{:?}", report.quality);
            assert!(mimicgen_pipeline::quality_path(&merged).is_file());
            // A shard left out, or given twice, is refused.
            let err = merge(&shards[1..], &dir.path().join("x.hdf5"), false, |_, _| {}).unwrap_err().to_string();
            assert!(err.contains(&format!("shards 0/{count} are missing")), "{err}");
            let twice = [shards.clone(), vec![shards[0].clone()]].concat();
            let err = merge(&twice, &dir.path().join("x.hdf5"), false, |_, _| {}).unwrap_err().to_string();
            assert!(err.contains("given twice"), "{err}");
            let err = merge(&shards, &merged, false, |_, _| {}).unwrap_err().to_string();
            assert!(err.contains("exists"), "{err}");
        }
    }
    // A shard of another run (another seed) is refused, naming the file and what differs.
    let other = dir.path().join("other.hdf5");
    run(&RunConfig { shard: Some(Shard::new(1, 2).unwrap()), seed: Some(4), ..base(other.clone(), false) }).unwrap();
    let first = dir.path().join("shard_false_0of2.hdf5");
    let err = merge(&[first.clone(), other], &dir.path().join("y.hdf5"), false, |_, _| {}).unwrap_err().to_string();
    assert!(err.contains("other.hdf5") && err.contains("spec"), "{err}");
    // An attempt log naming a source demo the run does not have is refused, naming the log.
    let log = mimicgen_pipeline::attempt_log_path(&first);
    let text = std::fs::read_to_string(&log).unwrap();
    assert!(text.contains("\"sources\":["), "{text}");
    std::fs::write(&log, text.replacen("\"sources\":[", "\"sources\":[99999999999,", 1)).unwrap();
    let second = dir.path().join("shard_false_1of2.hdf5");
    let err = merge(&[first, second], &dir.path().join("z.hdf5"), false, |_, _| {}).unwrap_err().to_string();
    assert!(err.contains("attempts.jsonl") && err.contains("source demo 99999999999"), "{err}");
}

/// robosuite's own human demonstrations (its raw collection format, no `env_args`) read like a
/// robomimic file, prepare into MimicGen source demos (what the bundled Lift demos are), and
/// generate Lift in both variants.
#[test]
fn robosuite_human_lift_demos_prepare_and_generate() {
    use mimicgen_engine::Environment as _;
    let raw = data("../io/tests/data/robosuite_lift_demo.hdf5");
    let file = RobomimicDataset::open(&raw).unwrap();
    let env_args: serde_json::Value = serde_json::from_str(file.env_args().unwrap()).unwrap();
    assert_eq!(
        (env_args["env_name"].as_str(), env_args["env_kwargs"]["controller_configs"]["type"].as_str()),
        (Some("Lift"), Some("OSC_POSE"))
    );
    assert!(env_args["env_kwargs"].get("env_name").is_none(), "robomimic's conversion drops env_info's env_name");
    let dir = tempfile::tempdir().unwrap();
    let prepared = dir.path().join("lift_source.hdf5");
    assert_eq!(mimicgen_pipeline::prepare::prepare(&raw, &prepared, None, |_, _, _| {}).unwrap(), 3);
    // What is bundled is this file (the same demos, ends and poses).
    let bundled = mimicgen_pipeline::bundled::source_demos("lift").unwrap();
    let read = |p: &Path| mimicgen_io::read_source_dataset(p, &Default::default()).unwrap();
    let (ours, shipped) = (read(&prepared), read(&bundled));
    assert_eq!(ours.demos.len(), 3);
    for (a, b) in ours.demos.iter().zip(&shipped.demos) {
        assert_eq!((a.len(), &a.eef_poses, &a.object_poses), (b.len(), &b.eef_poses, &b.object_poses));
    }
    // The teleoperated actions go beyond [-1, 1]; the target is where the clipped action points.
    let task = mimicgen_sim::registry::task("lift", "D0").unwrap();
    let xml = file.demo("demo_1").unwrap().attrs["model_file"].as_str().unwrap().to_owned();
    let scene = std::sync::Arc::new(mimicgen_sim::Scene::from_model_file(&xml, "lift model_file", task.as_ref()).unwrap());
    let env = mimicgen_sim::SimEnv::new(scene, task);
    let far = env.action_to_target_pose(&[3.75, -3.75, 0.0, 0.0, 0.0, 0.15, 1.0]);
    let near = env.action_to_target_pose(&[1.0, -1.0, 0.0, 0.0, 0.0, 0.15, 1.0]);
    assert!((far.translation.vector - near.translation.vector).norm() < 1e-12);
    for variant in ["D0", "D1"] {
        let out = dir.path().join(format!("lift_{variant}.hdf5"));
        let config = RunConfig { task: Some("lift".into()), variant: Some(variant.into()), ..config(&out, 6, 2) };
        let (report, _) = run(&config).unwrap();
        assert_eq!((report.task.as_str(), report.attempts), ("lift", 6));
        assert!(report.successes >= 3, "{variant}: {} of 6 from the human demos", report.successes);
    }
}

#[test]
fn cameras_render_into_the_dataset_as_robomimic_reads_them() {
    use mimicgen_io::tree::Values;
    use mimicgen_sim::camera::CameraConfig;
    let dir = tempfile::tempdir().unwrap();
    let cameras = Some(CameraConfig { height: 24, width: 32, ..CameraConfig::default() });
    let one = dir.path().join("one.hdf5");
    let two = dir.path().join("two.hdf5");
    let (report, _) = run(&RunConfig { cameras: cameras.clone(), ..config(&one, 2, 1) }).unwrap();
    run(&RunConfig { cameras: cameras.clone(), ..config(&two, 2, 2) }).unwrap();
    assert!(report.successes >= 1, "{report:?}");
    let a = RobomimicDataset::open(&one).unwrap();
    assert_eq!(a.data(), RobomimicDataset::open(&two).unwrap().data(), "images depend on the worker count");
    let demo = a.demo("demo_0").unwrap();
    let steps = demo.dataset("actions").unwrap().array.shape[0];
    for key in ["agentview_image", "robot0_eye_in_hand_image"] {
        let d = demo.dataset_at(&format!("obs/{key}")).unwrap();
        assert_eq!(d.array.shape, [steps, 24, 32, 3], "{key}");
        assert!(matches!(d.array.values, Values::U8(_)), "{key} is {}", d.array.values.dtype_name());
        assert_eq!((d.chunks.as_deref(), d.deflate), (Some(&[1, 24, 32, 3][..]), Some(4)), "{key}: a gzip chunk per frame");
    }
    // The low-dim observations are still there, and env_args tells robomimic about the cameras.
    assert!(demo.dataset_at("obs/robot0_eef_pos").is_some());
    let env_args: serde_json::Value = serde_json::from_str(a.env_args().unwrap()).unwrap();
    assert_eq!(env_args["env_kwargs"]["use_camera_obs"], true);
    assert_eq!(env_args["env_kwargs"]["camera_names"], serde_json::json!(["agentview", "robot0_eye_in_hand"]));
    assert_eq!((env_args["env_kwargs"]["camera_heights"].as_u64(), env_args["env_kwargs"]["camera_widths"].as_u64()), (Some(24), Some(32)));
    // A camera the scene lacks is refused before anything runs.
    let bad = Some(CameraConfig { names: vec!["wristcam".into()], ..CameraConfig::default() });
    let err = Pipeline::prepare(&RunConfig { cameras: bad, ..config(&dir.path().join("bad.hdf5"), 1, 1) }).unwrap_err().to_string();
    assert!(err.contains("\"wristcam\"") && err.contains("robot0_eye_in_hand"), "{err}");
}

#[test]
fn the_ur5e_generates_from_the_panda_demos_and_its_files_keep_robosuite_s_gripper() {
    // The transformed end-effector poses do not depend on the arm. With its Robotiq 85 as
    // robosuite's MuJoCo 2.3 moves it (the simulation's patch), the UR5e generates Stack (86 % over
    // 50 attempts; robosuite 1.4.1 replays 20 of 20 of those demos).
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("ur5e.hdf5");
    let (report, _) = run(&RunConfig { robot: Some("ur5e".into()), ..config(&out, 6, 1) }).unwrap();
    assert!(report.successes >= 3, "{} of {} UR5e attempts succeeded", report.successes, report.attempts);
    // The file keeps robosuite's model: the patch's couplings and exclusions are the simulation's.
    let file = RobomimicDataset::open(&out).unwrap();
    let xml = file.demo("demo_0").unwrap().attrs["model_file"].as_str().unwrap().to_owned();
    assert!(xml.contains("robotiq_85") && xml.contains("gripper0_finger1_12_cpl"), "robosuite's Robotiq 85");
    assert!(!xml.contains("joint1=\"gripper0_") && !xml.contains("limited=\"false\""), "the simulation's patch leaked into model_file");
}

#[test]
fn another_arm_runs_in_the_task_scene_composed_with_it() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("sawyer.hdf5");
    let pipeline = Pipeline::prepare(&RunConfig { robot: Some("sawyer".into()), ..config(&out, 1, 1) }).unwrap();
    assert_eq!(pipeline.scene().robot.model.name, "sawyer");
    let env_args: serde_json::Value = serde_json::from_str(pipeline.env_args()).unwrap();
    assert_eq!(env_args["env_kwargs"]["robots"], serde_json::json!(["Sawyer"]));
    // The sources' own arm keeps their scene; an unknown one is refused by name.
    let panda = Pipeline::prepare(&RunConfig { robot: Some("panda".into()), ..config(&out, 1, 1) }).unwrap();
    assert_eq!(panda.scene().robot.model.name, "panda");
    let err = Pipeline::prepare(&RunConfig { robot: Some("baxter".into()), ..config(&out, 1, 1) }).unwrap_err().to_string();
    assert!(err.contains("robot") && err.contains("baxter") && err.contains("sawyer"), "{err}");
}

#[test]
fn render_adds_camera_observations_to_a_dataset_and_keeps_the_rest() {
    use mimicgen_io::tree::{Dataset, Group, Values};
    use mimicgen_sim::camera::CameraConfig;
    let dir = tempfile::tempdir().unwrap();
    let mut file = RobomimicDataset::open(data("../io/tests/data/source_D0_prepared.hdf5")).unwrap();
    let Some(Node::Group(demos)) = file.root.members.get_mut("data") else { panic!("no data") };
    demos.members.retain(|name, _| name == "demo_0" || name == "demo_1");
    let mut mask = Group::default();
    let train = Array { shape: vec![1], values: Values::Fixed { len: 6, strings: vec!["demo_1".into()] } };
    mask.members.insert("train".into(), Node::Dataset(Dataset::new(train)));
    file.root.members.insert("mask".into(), Node::Group(mask));
    let input = dir.path().join("in.hdf5");
    mimicgen_io::write_tree(&input, &file.root).unwrap();
    let out = dir.path().join("out.hdf5");
    let cameras = CameraConfig { names: vec!["agentview".into()], height: 16, width: 16, depth: false, fast: true, reflection: false };
    let mut progress = Vec::new();
    assert_eq!(mimicgen_pipeline::render::render(&input, &out, &cameras, None, false, |d, t| progress.push((d, t))).unwrap(), 2);
    assert_eq!(progress, [(1, 2), (2, 2)]);
    let (a, b) = (RobomimicDataset::open(&input).unwrap(), RobomimicDataset::open(&out).unwrap());
    for name in ["demo_0", "demo_1"] {
        let (before, after) = (a.demo(name).unwrap(), b.demo(name).unwrap());
        assert_eq!(before.dataset("actions"), after.dataset("actions"));
        assert_eq!(before.dataset_at("obs/robot0_eef_pos"), after.dataset_at("obs/robot0_eef_pos"));
        let image = after.dataset_at("obs/agentview_image").unwrap();
        let steps = before.dataset("actions").unwrap().array.shape[0];
        assert_eq!(image.array.shape, [steps, 16, 16, 3]);
        assert!(matches!(image.array.values, Values::U8(_)));
    }
    assert_eq!(b.masks().unwrap()["train"], ["demo_1"]);
    let env_args: serde_json::Value = serde_json::from_str(b.env_args().unwrap()).unwrap();
    assert_eq!(env_args["env_kwargs"]["camera_names"], serde_json::json!(["agentview"]));
    // An existing output is kept; an unknown camera is named.
    let err = mimicgen_pipeline::render::render(&input, &out, &cameras, None, false, |_, _| ()).unwrap_err();
    assert!(matches!(&err, PipelineError::Exists { file, .. } if file.ends_with(".hdf5")), "{err}");
    let wrist = CameraConfig { names: vec!["wristcam".into()], ..cameras };
    let err = mimicgen_pipeline::render::render(&input, &out, &wrist, None, true, |_, _| ()).unwrap_err().to_string();
    assert!(err.contains("\"wristcam\""), "{err}");
}

#[test]
fn object_transfer_draws_a_mug_per_episode_records_it_and_does_not_depend_on_the_worker_count() {
    let a_file = |path: &Path| RobomimicDataset::open(path).unwrap();
    let a_demo_instance =
        |file: &RobomimicDataset, demo: &str| file.demo(demo).unwrap().attrs[mimicgen_io::INSTANCE_ATTR].as_str().unwrap().to_owned();
    let dir = tempfile::tempdir().unwrap();
    let mug_cleanup = |out: &Path, workers: usize| RunConfig {
        task: Some("mug_cleanup".to_owned()),
        variant: Some("O2".to_owned()),
        keep_failed: true,
        ..config(out, 6, workers)
    };
    let (one, two) = (dir.path().join("one.hdf5"), dir.path().join("two.hdf5"));
    let (report, events) = run(&mug_cleanup(&one, 1)).unwrap();
    run(&mug_cleanup(&two, 2)).unwrap();
    assert!(report.successes >= 2, "{report:?}");
    let (a, b) = (RobomimicDataset::open(&one).unwrap(), RobomimicDataset::open(&two).unwrap());
    assert_eq!(a.data(), b.data(), "1 and 2 workers wrote different data");
    let env_args: serde_json::Value = serde_json::from_str(a.env_args().unwrap()).unwrap();
    assert_eq!(env_args["env_name"], "MugCleanup_O2");
    // Every episode, kept or failed, names its mug, and its model_file holds that mug: episodes
    // with different mugs have different scenes.
    let task = mimicgen_sim::registry::task("mug_cleanup", "O2").unwrap();
    let labels: Vec<String> = task.instances().into_iter().map(|(label, _)| label).collect();
    assert_eq!(labels.len(), 12);
    let failed = RobomimicDataset::open(dir.path().join("one_failed.hdf5")).unwrap();
    let mut scenes = std::collections::BTreeMap::new();
    for file in [&a, &failed] {
        for name in file.demo_names() {
            let attrs = &file.demo(name).unwrap().attrs;
            let label = attrs[mimicgen_io::INSTANCE_ATTR].as_str().unwrap().to_owned();
            assert!(labels.contains(&label), "{name}: {label}");
            let xml = attrs["model_file"].as_str().unwrap().to_owned();
            assert_eq!(scenes.entry(label).or_insert_with(|| xml.clone()), &xml, "{name}: one scene per mug");
        }
    }
    assert!(scenes.len() >= 2, "6 episodes drew only {:?}", scenes.keys());
    // Each attempt's event names the mug its episode drew (the app's split by instance), the
    // same as its kept demo says.
    for event in &events {
        let Event::Attempt(a) = event else { continue };
        let drawn = a.instance.as_deref().unwrap();
        assert!(labels.iter().any(|l| l == drawn), "attempt {}: {drawn}", a.attempt.index);
        let kept = match &a.outcome {
            mimicgen_pipeline::Outcome::Written { demo } => a_demo_instance(&a_file(&one), demo),
            mimicgen_pipeline::Outcome::KeptFailed { demo } => a_demo_instance(&failed, demo),
            mimicgen_pipeline::Outcome::Discarded => continue,
        };
        assert_eq!(kept, drawn, "attempt {}", a.attempt.index);
    }
    // The report's rates per mug: each mug's attempts and successes, as the events drew them.
    let mut per_mug: std::collections::BTreeMap<String, (usize, usize)> = std::collections::BTreeMap::new();
    for event in &events {
        let Event::Attempt(a) = event else { continue };
        let count = per_mug.entry(a.instance.clone().unwrap()).or_default();
        count.0 += 1;
        count.1 += usize::from(a.attempt.success);
    }
    let reported: std::collections::BTreeMap<String, (usize, usize)> =
        report.per_object_instance.iter().map(|i| (i.instance.clone(), (i.attempts, i.successes))).collect();
    assert_eq!(reported, per_mug);
    assert_eq!(reported.values().map(|c| c.0).sum::<usize>(), report.attempts);
    assert_eq!(reported.values().map(|c| c.1).sum::<usize>(), report.successes);
    // Coverage splits the demos by instance.
    let coverage = mimicgen_pipeline::coverage::dataset_coverage(&one, None, None, 3).unwrap();
    assert_eq!(coverage.variant, "O2");
    assert_eq!(coverage.instances.values().sum::<usize>(), a.demo_names().len());
    let distinct: std::collections::BTreeSet<&String> = scenes.values().collect();
    assert_eq!(distinct.len(), scenes.len(), "each mug's scene is its own");
}

/// Every run writes its quality report beside its dataset (and in its report): stitches per
/// subtask, actions against the limits, coverage of the successes, and written demos replayed to
/// success. A run made without a bridge into the place shows the jump there.
#[test]
fn a_run_writes_its_quality_report_and_a_missing_bridge_shows_as_a_jump() {
    use mimicgen_engine::quality::StitchAt;
    use mimicgen_pipeline::{Scoped, SpecOverrides};
    let dir = tempfile::tempdir().unwrap();
    let smooth_out = dir.path().join("smooth.hdf5");
    let (report, _) = run(&config(&smooth_out, 6, 2)).unwrap();
    let text = std::fs::read_to_string(mimicgen_pipeline::quality_path(&smooth_out)).unwrap();
    let written: mimicgen_pipeline::DatasetQuality = serde_json::from_str(&text).unwrap();
    let quality = report.quality.clone().unwrap();
    assert_eq!(written, quality, "the file and the report say the same");
    assert_eq!(quality.quality.attempts, report.successes);
    let coverage = quality.coverage.as_ref().unwrap();
    assert_eq!((coverage.scenes, coverage.bins), (report.successes, 3));
    // `mimicgen coverage`'s figure on the written dataset.
    let on_file = mimicgen_pipeline::coverage::dataset_coverage(&smooth_out, None, None, 3).unwrap();
    assert!((coverage.support_coverage - on_file.coverage.support_coverage()).abs() < 1e-12, "{coverage:?}");
    let replay = quality.replay.as_ref().unwrap();
    assert_eq!(replay.demos.len(), 3.min(report.successes));
    assert_eq!(replay.succeeded, replay.demos.len(), "the written demos replay to success from their first state");
    let actions = &quality.quality.actions;
    assert!(actions.steps > 0 && actions.max_abs.iter().all(|&a| a <= 1.0 + 1e-9), "{actions:?}");
    let stitch =
        |q: &mimicgen_pipeline::DatasetQuality, at| q.quality.stitches.iter().find(|s| s.subtask == 1 && s.at == at).cloned().unwrap();
    let smooth = stitch(&quality, StitchAt::InterpolationStart);
    assert_eq!(smooth.count, report.successes);
    // No interpolation into the place: the grasp's last target to the place segment's first.
    let jumpy_out = dir.path().join("jumpy.hdf5");
    let no_bridge = SpecOverrides { interpolation_steps: vec![Scoped { subtask: Some(1), value: 0 }], ..SpecOverrides::default() };
    let (jumpy_report, _) = run(&RunConfig { spec: no_bridge, ..config(&jumpy_out, 6, 2) }).unwrap();
    let jumpy = stitch(jumpy_report.quality.as_ref().unwrap(), StitchAt::InterpolationStart);
    assert!(jumpy.jump_m_max > 2.0 * smooth.jump_m_max, "jumpy {jumpy:?}, smooth {smooth:?}");
    assert!(jumpy.jump_m_p95 > 2.0 * jumpy.step_m_p95, "the jump stands out from the steps: {jumpy:?}");
}
