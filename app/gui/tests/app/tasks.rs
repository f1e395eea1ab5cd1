//! Tasks beyond Stack through the same views: a long-horizon one, a Factory one, object
//! transfer, two arms, and a mobile base.

use egui_kittest::kittest::Queryable as _;
use mimicgen_gui::Command;

use crate::common::{bundled, harness, settle, until_run_ends};

/// A long-horizon task with articulated parts, described only by its task file, goes through the
/// same views: its bundled demos open with their four signals, the preview plans all five
/// object-centric subtasks, and the tried attempt runs every one of them in MuJoCo.
#[test]
fn coffee_preparation_opens_previews_its_five_subtasks_and_is_tried() {
    let source = bundled("coffee_preparation_D0_source.hdf5");
    let mut h = harness(Some(source));
    settle(&mut h);
    let file = h.state().model.file.as_ref().unwrap();
    assert_eq!((file.task.as_str(), file.demos.len()), ("coffee_preparation", 10));
    assert_eq!(file.signal_names, ["mug_grasp", "mug_place", "drawer_open", "pod_grasp"]);
    h.get_by_label("Preview").click();
    h.step();
    settle(&mut h);
    let view = h.state().model.preview.view.clone().unwrap();
    let objects: Vec<_> = view.subtasks.iter().map(|s| s.object.clone().unwrap()).collect();
    assert_eq!(objects, ["mug", "coffee_machine", "drawer", "coffee_pod", "coffee_machine"]);
    h.get_by_label_contains("Subtask 2 (relative to drawer)");
    h.get_by_label("Try it").click();
    h.step();
    settle(&mut h);
    let tried = h.state().model.preview.view.clone().unwrap();
    let executed = tried.executed.as_ref().unwrap();
    assert_eq!(executed.diagnostics.len(), 5, "every subtask ran: {:?}", executed.failure);
    assert_eq!(executed.success, executed.failure.is_none());
    h.get_by_label_contains("Tried: ");
}

/// A Factory task (Nut-and-Bolt Assembly, a task file like every other) opens, previews its two
/// subtasks relative to the nut and the bolt, and is tried in simulation.
#[test]
fn nut_bolt_assembly_opens_previews_and_is_tried() {
    let mut h = harness(Some(bundled("nut_bolt_assembly_D0_source.hdf5")));
    settle(&mut h);
    let file = h.state().model.file.as_ref().unwrap();
    assert_eq!((file.task.as_str(), file.demos.len()), ("nut_bolt_assembly", 10));
    assert_eq!(file.signal_names, ["grasp"]);
    h.get_by_label("Preview").click();
    h.step();
    settle(&mut h);
    let view = h.state().model.preview.view.clone().unwrap();
    let objects: Vec<_> = view.subtasks.iter().map(|s| s.object.clone().unwrap()).collect();
    assert_eq!(objects, ["nut", "bolt"]);
    h.get_by_label_contains("Subtask 1 (relative to bolt)");
    h.get_by_label("Try it").click();
    h.step();
    settle(&mut h);
    let tried = h.state().model.preview.view.clone().unwrap();
    let executed = tried.executed.as_ref().unwrap();
    assert_eq!(executed.diagnostics.len(), 2, "both subtasks ran: {:?}", executed.failure);
    assert_eq!(executed.success, executed.failure.is_none());
    h.get_by_label_contains("Tried: ");
}

/// An object-transfer run (Mug Cleanup O2: one of twelve mugs per episode) opened in the app
/// splits its attempts by the mug each episode drew.
#[test]
fn an_object_transfer_run_is_split_by_mug() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("mugs.hdf5");
    let config = mimicgen_pipeline::RunConfig {
        task: Some("mug_cleanup".to_owned()),
        variant: Some("O2".to_owned()),
        num_demos: Some(4),
        workers: 2,
        keep_failed: true,
        seed: Some(3),
        out: out.clone(),
        ..Default::default()
    };
    let pipeline = mimicgen_pipeline::Pipeline::prepare(&config).unwrap();
    let report = pipeline.run(&std::sync::atomic::AtomicBool::new(false), |_| {}).unwrap();
    let mugs = bundled("mug_cleanup_D0_source.hdf5");
    let mut h = harness(Some(mugs));
    settle(&mut h);
    h.get_by_label("Generate").click();
    h.step();
    h.state_mut().command(Command::OpenRun(out));
    settle(&mut h);
    let run = h.state().model.run.as_ref().unwrap();
    assert_eq!(run.rows.len(), report.attempts, "every attempt was kept");
    let rates = mimicgen_gui::run_ui::instance_rates(&run.rows);
    assert_eq!(rates.iter().map(|(_, _, tried)| tried).sum::<usize>(), 4, "{rates:?}");
    assert_eq!(rates.iter().map(|(_, ok, _)| ok).sum::<usize>(), report.successes);
    h.get_by_label("Success by object instance");
    let (label, ok, tried) = &rates[0];
    h.get_by_label(label.as_str());
    h.get_all_by_label(&format!("{ok} of {tried}")).next().unwrap();
}

/// A two-arm source file: a row per arm; clicking an arm annotates it (its signals, its ends, the
/// keys move its end), the other arm keeps its own, and saving writes both arms' signals where the
/// two-arm generator reads them. The preview tries an attempt with both arms and draws the ties;
/// the 3D view is refused by name (one-arm only so far).
#[test]
fn a_two_arm_file_is_annotated_arm_by_arm_and_saved() {
    let source = bundled("two_arm_lift_D0_source.hdf5");
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("two_arm_annotated.hdf5");
    let mut h = harness(Some(source));
    settle(&mut h);
    let file = h.state().model.file.as_ref().unwrap();
    assert_eq!(file.arms.len(), 2, "{:?}", h.state().model.error);
    assert_eq!(file.signal_names, ["grasp_handle0"]);
    let arm0_before = h.state().model.demo_ends();
    h.get_by_label_contains("arm 1 (robot1)").click();
    h.run_steps(2);
    assert_eq!(h.state().model.arm, 1);
    assert_eq!(h.state().model.file.as_ref().unwrap().signal_names, ["grasp_handle1"]);
    h.get_by_label_contains("grasp_handle1) ends at step");
    for _ in 0..30 {
        h.key_press(egui::Key::ArrowRight);
        h.step();
    }
    h.key_press(egui::Key::E);
    h.run_steps(2);
    assert_eq!(h.state().model.demo_ends(), vec![31], "E puts arm 1's end at the cursor");
    h.get_by_label_contains("arm 0 (robot0)").click();
    h.run_steps(2);
    assert_eq!(h.state().model.demo_ends(), arm0_before, "arm 0 keeps its own ends");
    h.get_by_role_and_label(egui::accesskit::Role::TextInput, "Save to:").click();
    h.run_steps(2);
    h.get_by_role_and_label(egui::accesskit::Role::TextInput, "Save to:").type_text(&out.display().to_string());
    h.run_steps(2);
    h.get_by_label("Save as").click();
    h.step();
    settle(&mut h);
    assert!(h.state().model.error.is_none(), "{:?}", h.state().model.error);
    // The preview tries an attempt with both arms' ends: each arm's segments, its path, and the
    // lift's coordination drawn between the hands.
    h.state_mut().command(Command::Show(mimicgen_gui::Screen::Preview));
    settle(&mut h);
    let model = &h.state().model;
    assert!(model.error.is_none(), "{:?}", model.error);
    let view = model.preview.view.as_ref().unwrap();
    assert_eq!(view.arms.len(), 2);
    assert!(
        view.arms.iter().all(|a| a.segments.len() == 2 && !a.path.is_empty()),
        "{:?}",
        view.arms.iter().map(|a| a.segments.len()).collect::<Vec<_>>()
    );
    assert!(view.ties.iter().any(|t| t.coordination && t.from == (0, 1) && t.to == (1, 1)), "{:?}", view.ties);
    assert!(view.executed.is_some());
    h.run_steps(2);
    assert_eq!(h.get_all_by_label_contains("coordination: robot0 subtask 1 with robot1 subtask 1").count(), 2, "in both views");
    // The 3D view is one-arm only: refused by name.
    h.state_mut().command(Command::Open3d(mimicgen_gui::protocol::ViewerSink::Save(dir.path().join("x.rrd"))));
    settle(&mut h);
    let error = h.state().model.error.clone().unwrap_or_default();
    assert!(error.contains("two-arm"), "{error}");
    // The saved file: arm 1's signal turns on at its subtask's last step where it was put, arm 0's
    // where it was.
    let views = mimicgen_io::RobomimicDataset::open(&out)
        .unwrap()
        .to_arm_source_datasets(&mimicgen_engine::spec::SourceSelection::default(), &["robot0", "robot1"])
        .unwrap();
    let first_on = |signal: &[i64]| signal.iter().position(|&v| v != 0).unwrap();
    assert_eq!(first_on(&views[1].demos[0].subtask_term_signals["grasp_handle1"]), 30);
    assert_eq!(first_on(&views[0].demos[0].subtask_term_signals["grasp_handle0"]), arm0_before[0] - 1);
}

/// A two-arm run from the app: the form without what two-arm runs lack, Start, the attempts with
/// their subtasks named by arm, the report (`<out>.json`, as `mimicgen generate` writes it), and a
/// failed attempt re-run in the preview with both arms' ends fails as the run's did.
#[test]
fn a_two_arm_run_is_started_from_the_app_and_a_failure_re_run() {
    let source = bundled("two_arm_handover_D0_source.hdf5");
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("two_arm_run.hdf5");
    let mut h = harness(Some(source));
    settle(&mut h);
    assert_eq!(h.state().model.file.as_ref().unwrap().arms.len(), 2);
    h.get_by_label("Generate").click();
    h.step();
    // Seed 1: one of the first 8 attempts misses arm 0's grasp of the hammer.
    let form = mimicgen_gui::model::RunForm { attempts: 8, seed: 1, workers: 2, out: out.display().to_string(), ..Default::default() };
    h.state_mut().command(Command::SetRunForm(Box::new(form)));
    h.run_steps(2);
    h.get_by_label_contains("mimicgen generate --task two_arm_handover --source");
    assert!(h.query_by_label("keep failed attempts").is_none() && h.query_by_label("Spec fields").is_none());
    h.get_by_label("Start").click();
    h.step();
    until_run_ends(&mut h);
    let run = h.state().model.run.clone().unwrap();
    assert!(run.error.is_none(), "{:?}", run.error);
    let report = run.report.as_ref().unwrap();
    assert_eq!((run.rows.len(), report.attempts, report.task.as_str()), (8, 8, "two_arm_handover"));
    assert_eq!(report.successes, run.rows.iter().filter(|r| r.success).count());
    assert_eq!(mimicgen_io::RobomimicDataset::open(&out).unwrap().demo_names().len(), report.successes);
    let written: mimicgen_pipeline::Report =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("two_arm_run.json")).unwrap()).unwrap();
    assert_eq!((written.attempts, written.successes), (report.attempts, report.successes));
    // Every subtask of both arms has its row in the success matrix, named by its arm.
    let spec = mimicgen_sim::two_arm::TwoArmTask::Handover.spec().unwrap();
    let counts: Vec<usize> = spec.arms.iter().map(|a| a.subtasks.len()).collect();
    assert_eq!(report.per_subtask_source.len(), counts.iter().sum::<usize>());
    let failed = run.rows.iter().find(|r| !r.success).expect("seed 1 has a failed attempt among the first 8").clone();
    assert!(run.rows.iter().all(|r| r.sources.len() == counts.iter().sum::<usize>() || !r.success), "every success planned every subtask");
    let k = failed.failed_subtask.unwrap();
    let (arm, subtask) = if k < counts[0] { (0, k) } else { (1, k - counts[0]) };
    h.get_by_label_contains(&format!("{:>5}  failure", failed.index)).click();
    h.run_steps(2);
    h.get_by_label_contains(&format!("failed in robot{arm} subtask {subtask}: {}", failed.reason.as_ref().unwrap()));
    assert!(h.query_by_label("Side by side").is_none(), "side by side is one-arm only");
    h.get_by_label("Re-run in preview").click();
    h.step();
    settle(&mut h);
    let model = &h.state().model;
    assert!(model.error.is_none(), "{:?}", model.error);
    assert_eq!(model.screen, mimicgen_gui::Screen::Preview);
    let view = model.preview.view.as_ref().unwrap();
    assert_eq!((view.seed, view.index, view.arms.len()), (1, failed.index, 2));
    let executed = view.executed.as_ref().unwrap();
    assert!(!executed.success);
    assert_eq!(executed.failure, Some(format!("arm {arm}: subtask {subtask}: {}", failed.reason.as_ref().unwrap())));
    assert_eq!(executed.path.len(), failed.steps, "the re-run takes the run's steps");
}

/// Mobile Kitchen (a Panda on a mobile base) opens with its 25 demos, previews its four subtasks
/// with the base's drives drawn (the stove's, the sink's, back to the stove) and is tried in
/// simulation, every subtask running.
#[test]
fn mobile_kitchen_previews_its_drives_and_is_tried() {
    let mut h = harness(Some(bundled("mobile_kitchen_D0_source.hdf5")));
    settle(&mut h);
    let file = h.state().model.file.as_ref().unwrap();
    assert_eq!((file.task.as_str(), file.demos.len()), ("mobile_kitchen", 25));
    assert_eq!(file.signal_names, ["grasp_pan", "pan_on_stove", "grasp_carrot"], "in the order they first turn on");
    h.get_by_label("Preview").click();
    h.step();
    settle(&mut h);
    let view = h.state().model.preview.view.clone().unwrap();
    let objects: Vec<_> = view.subtasks.iter().map(|s| s.object.clone().unwrap()).collect();
    assert_eq!(objects, ["pan", "stove", "carrot", "pan"]);
    // How far along the counters (the world's y) each subtask's drive takes the hand.
    let span = |k: usize| {
        let ys: Vec<f64> = view.subtasks[k].drive.iter().map(|p| p[1]).collect();
        ys.iter().copied().fold(f64::NEG_INFINITY, f64::max) - ys.iter().copied().fold(f64::INFINITY, f64::min)
    };
    // The pan is grasped where the base starts (its end offset may cut a few steps into the
    // first drive, which the next subtask goes on with); each later subtask drives 0.85 m.
    assert!(view.subtasks[0].drive.is_empty() || span(0) < 0.2, "subtask 0 drives {} m", span(0));
    for k in 1..4 {
        assert!(span(k) > 0.5, "subtask {k}'s drive spans {} m of y", span(k));
    }
    h.get_by_label_contains("Subtask 3 (relative to pan)");
    h.get_by_label("Try it").click();
    h.step();
    settle(&mut h);
    let tried = h.state().model.preview.view.clone().unwrap();
    let executed = tried.executed.as_ref().unwrap();
    assert_eq!(executed.diagnostics.len(), 4, "every subtask ran: {:?}", executed.failure);
    assert_eq!(executed.success, executed.failure.is_none());
    // The hand went where the base took it: to the sink's counter and back.
    let far = executed.path.iter().map(|p| p[1]).fold(f64::NEG_INFINITY, f64::max);
    assert!(far > 1.5, "the hand reached y {far} (the sink is at 1.7)");
    h.get_by_label_contains("Tried: ");
}
