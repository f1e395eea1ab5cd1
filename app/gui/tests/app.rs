//! The app driven through its real UI with egui_kittest (no display): open files (source demos, a
//! broken file, a plain robomimic file, a large file), annotate (keyboard, mouse, undo and redo,
//! auto-detect, segment starts, save and reload), preview and try attempts (new scenes, forced
//! sources, dragged objects, planned transit), the 3D view's recording, and generation runs
//! (start, progress, cancel, re-run).
#![allow(clippy::unwrap_used)] // tests fail loudly by design
#![allow(clippy::float_cmp)] // positions pass through the backend unchanged: exact comparisons are the point

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use egui_kittest::Harness;
use egui_kittest::kittest::Queryable as _;
use mimicgen_gui::{Command, MimicgenApp};

fn fixture() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../core/io/tests/data/source_D0_prepared.hdf5")
}

/// A bundled source file (`core/sim/data/<name>`).
fn bundled(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../core/sim/data").join(name)
}

fn harness(file: Option<PathBuf>) -> Harness<'static, MimicgenApp> {
    let app = mimicgen_gui::desktop(|| {}, file, None, None);
    Harness::builder().with_size(egui::vec2(1280.0, 800.0)).build_ui_state(|ui, app: &mut MimicgenApp| app.show(ui), app)
}

/// Steps frames until the backend has answered (the UI never blocks on it). The deadline only
/// turns a hung backend into a failure; a slow machine just takes longer.
fn settle(h: &mut Harness<'static, MimicgenApp>) {
    let deadline = Instant::now() + Duration::from_secs(600);
    loop {
        h.step();
        if h.state().model.in_flight == 0 {
            break;
        }
        assert!(Instant::now() < deadline, "the backend did not answer");
        std::thread::sleep(Duration::from_millis(10));
    }
    h.run_steps(2);
}

/// Presses at `from`, moves to `to` over a few frames and releases there, as a hand drags.
fn drag(h: &mut Harness<'static, MimicgenApp>, from: egui::Pos2, to: egui::Pos2) {
    h.hover_at(from);
    h.step();
    h.drag_at(from);
    h.step();
    for i in 1..=8 {
        h.hover_at(from + (to - from) * (i as f32 / 8.0));
        h.step();
    }
    // egui_plot reports the pointer of the frame before: hold still one frame before releasing.
    h.step();
    h.drop_at(to);
}

#[test]
fn opens_a_source_file_and_shows_every_demo() {
    let mut h = harness(Some(fixture()));
    assert!(h.state().model.busy.is_some(), "opening happens in the background");
    settle(&mut h);
    let file = h.state().model.file.as_ref().unwrap();
    assert_eq!(file.demos.len(), 10);
    assert_eq!(file.signal_names, vec!["grasp".to_owned()]);
    h.get_by_label_contains("demo_7").click();
    h.run_steps(2);
    assert_eq!(h.state().model.selected, 7);
    // The boundary editor shows the stored signal and the proposal for the shown demo.
    h.get_by_label_contains("stored signal: step");
    h.get_by_label_contains("proposed: step");
}

#[test]
fn keyboard_moves_a_subtask_end_and_undo_redo_restore_it() {
    let mut h = harness(Some(fixture()));
    settle(&mut h);
    let before = h.state().model.demo_ends();
    for _ in 0..12 {
        h.key_press(egui::Key::ArrowRight);
        h.step();
    }
    assert_eq!(h.state().model.cursor, 12);
    h.key_press(egui::Key::E);
    h.run_steps(2);
    assert_eq!(h.state().model.demo_ends(), vec![13], "E puts the selected end at the cursor (its last step)");
    assert!(h.state().model.annotation.dirty);
    h.get_by_label("Undo").click();
    h.run_steps(2);
    assert_eq!(h.state().model.demo_ends(), before);
    h.get_by_label("Redo").click();
    h.run_steps(2);
    assert_eq!(h.state().model.demo_ends(), vec![13]);
}

/// SkillGen-style segment starts: marked by button and key, cleared, used by a preview whose
/// transit the run form plans (the segment starts at the mark, the teal path leads to it), and
/// saved where the generator reads them.
#[test]
fn segment_starts_are_marked_previewed_with_planned_transit_and_saved() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("starts.hdf5");
    let mut h = harness(Some(fixture()));
    settle(&mut h);
    let end = h.state().model.demo_ends()[0];
    h.state_mut().command(Command::SetCursor(6));
    h.run_steps(2);
    // One "start at cursor" per subtask: the first row's marks subtask 0.
    h.get_all_by_label("start at cursor").next().unwrap().click();
    h.run_steps(2);
    assert_eq!(h.state().model.demo_starts(), vec![Some(6), None]);
    h.get_by_label("segment starts at step 6 (marked)");
    // S marks the start of the subtask under the cursor: past the end, the second.
    h.state_mut().command(Command::SetCursor(end + 3));
    h.run_steps(2);
    h.key_press(egui::Key::S);
    h.run_steps(2);
    assert_eq!(h.state().model.demo_starts(), vec![Some(6), Some(end + 3)]);
    h.get_all_by_label("clear start").next().unwrap().click();
    h.run_steps(2);
    assert_eq!(h.state().model.demo_starts(), vec![None, Some(end + 3)]);
    h.get_by_label_contains("(detected)");
    h.get_by_label("Undo").click();
    h.run_steps(2);
    assert_eq!(h.state().model.demo_starts(), vec![Some(6), Some(end + 3)]);
    // The run form plans transit (clicked: the spec fields, the transit box, "plan").
    h.get_by_label("Generate").click();
    h.run_steps(2);
    h.get_by_label("Spec fields").click();
    h.run_steps(2);
    h.get_by_label("transit").click();
    h.run_steps(2);
    h.get_by_label("plan").click();
    h.run_steps(2);
    let transit = &h.state().model.run_form.spec.transit;
    assert!(
        matches!(transit[..], [mimicgen_pipeline::Scoped { subtask: None, value: mimicgen_engine::spec::Transit::Plan }]),
        "{transit:?}"
    );
    h.get_by_label_contains("--transit plan");
    // "continue an interrupted run" and "replace existing outputs" exclude each other.
    h.get_by_label("replace existing outputs").click();
    h.run_steps(2);
    assert!(h.state().model.run_form.overwrite);
    h.get_by_label("continue an interrupted run").click();
    h.run_steps(2);
    let form = &h.state().model.run_form;
    assert!(form.resume && !form.overwrite, "resume ticked, replace unticked");
    h.get_by_label_contains("--resume");
    h.get_by_label("continue an interrupted run").click();
    h.run_steps(2);
    assert!(!h.state().model.run_form.resume);
    // The preview of demo_0's first segment starts at the mark, reached by a planned path.
    h.get_by_label("Preview").click();
    h.step();
    settle(&mut h);
    h.state_mut().command(Command::SetPreviewSource { subtask: 0, demo: Some(0) });
    settle(&mut h);
    let view = h.state().model.preview.view.clone().unwrap();
    assert!(h.state().model.error.is_none(), "{:?}", h.state().model.error);
    assert_eq!(view.subtasks[0].src_span.0, 6, "the segment starts at the marked step");
    assert!(view.subtasks[0].transit.len() > 2, "a planned transit leads to it");
    h.get_by_label_contains("teal: planned");
    // Saved and reopened: the file holds the starts.
    h.get_by_label("Annotate").click();
    h.run_steps(2);
    h.state_mut().command(Command::Save(out.clone()));
    settle(&mut h);
    assert!(h.state().model.error.is_none(), "{:?}", h.state().model.error);
    h.state_mut().command(Command::Open(out));
    settle(&mut h);
    let reopened = h.state().model.file.as_ref().unwrap();
    assert_eq!(reopened.demos[0].stored_starts, Some(vec![Some(6), Some(end + 3)]));
    assert_eq!(reopened.demos[1].stored_starts, None, "demos without marks get none");
    assert_eq!(h.state().model.demo_starts(), vec![Some(6), Some(end + 3)]);
}

#[test]
fn accepted_proposals_are_saved_where_mimicgen_reads_them() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("annotated.hdf5");
    let mut h = harness(Some(fixture()));
    settle(&mut h);
    h.state_mut().command(Command::SetEnd { subtask: 0, end: 20 });
    h.get_by_label("Auto-detect all").click();
    h.run_steps(2);
    let expected = h.state().model.annotation.marks.ends.clone();
    assert_ne!(expected["demo_0"], vec![20], "auto-detect replaced the hand-set end");
    h.get_by_role_and_label(egui::accesskit::Role::TextInput, "Save to:").click();
    h.run_steps(2);
    h.get_by_role_and_label(egui::accesskit::Role::TextInput, "Save to:").type_text(&out.display().to_string());
    h.run_steps(2);
    assert_eq!(h.state().ui_save_path(), out.display().to_string());
    h.get_by_label("Save as").click();
    h.step();
    settle(&mut h);
    assert!(h.state().model.error.is_none(), "{:?}", h.state().model.error);
    assert!(!h.state().model.annotation.dirty, "{}", h.state().model.status);
    // Reload the saved file in the app: its stored signals are the saved ends.
    h.state_mut().command(Command::Open(out.clone()));
    settle(&mut h);
    let reloaded = h.state().model.file.as_ref().unwrap();
    for demo in &reloaded.demos {
        assert_eq!(demo.stored_ends.as_ref(), Some(&expected[&demo.name]), "{}", demo.name);
    }
}

#[test]
fn a_bad_file_is_reported_and_the_open_file_and_its_edits_are_kept() {
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("not_hdf5.hdf5");
    std::fs::write(&bad, b"this is not an HDF5 file").unwrap();
    let mut h = harness(Some(fixture()));
    settle(&mut h);
    h.state_mut().command(Command::SetEnd { subtask: 0, end: 25 });
    h.state_mut().command(Command::Open(bad.clone()));
    settle(&mut h);
    let model = &h.state().model;
    let error = model.error.as_deref().unwrap();
    assert!(error.contains("not_hdf5.hdf5"), "{error}");
    assert_eq!(model.file.as_ref().unwrap().demos.len(), 10);
    assert_eq!(model.demo_ends(), vec![25]);
    h.get_by_label_contains("Error:");
}

#[test]
fn dragging_a_boundary_marker_moves_the_subtask_end() {
    let mut h = harness(Some(fixture()));
    settle(&mut h);
    let end = h.state().model.demo_ends()[0];
    let memory = egui_plot::PlotMemory::load(&h.ctx, mimicgen_gui::ui::timeline_plot_id("gripper")).unwrap();
    #[allow(clippy::cast_precision_loss)]
    let at = |step: usize| memory.transform().position_from_point(&egui_plot::PlotPoint::new(step as f64, 0.0));
    drag(&mut h, at(end - 1), at(end - 16));
    h.run_steps(2);
    assert_eq!(h.state().model.demo_ends(), vec![end - 15], "the marker was dropped 15 steps earlier");
    h.get_by_label("Undo").click();
    h.run_steps(2);
    assert_eq!(h.state().model.demo_ends(), vec![end]);
}

#[test]
fn previews_a_new_scene_and_tries_the_attempt_in_simulation() {
    let mut h = harness(Some(fixture()));
    settle(&mut h);
    h.get_by_label("Preview").click();
    h.step();
    settle(&mut h);
    let first = h.state().model.preview.view.clone().unwrap();
    assert_eq!((first.seed, first.index), (1, 0));
    assert_eq!(first.subtasks.len(), 2);
    assert_eq!(first.subtasks[0].ranking.len(), 10, "nearest-neighbour ranking over every source demo");
    assert!(first.subtasks[0].ranking.windows(2).all(|w| w[0].distance <= w[1].distance));
    h.get_by_label_contains("Subtask 0 (relative to cubeA)");
    // A new scene: the next attempt's, with the objects elsewhere.
    h.get_by_label("New scene").click();
    h.step();
    settle(&mut h);
    let second = h.state().model.preview.view.clone().unwrap();
    assert_eq!(second.index, 1);
    assert_ne!(second.objects, first.objects);
    // Forcing a source demo changes the transformed segment, not the scene.
    let other = (second.subtasks[0].src_demo + 1) % 10;
    h.state_mut().command(Command::SetPreviewSource { subtask: 0, demo: Some(other) });
    settle(&mut h);
    let forced = h.state().model.preview.view.clone().unwrap();
    assert_eq!(forced.objects, second.objects);
    assert_eq!(forced.subtasks[0].src_demo, other);
    // Try it: the attempt runs in MuJoCo and comes back with its executed path and outcome.
    h.get_by_label("Try it").click();
    h.step();
    settle(&mut h);
    let tried = h.state().model.preview.view.clone().unwrap();
    let executed = tried.executed.as_ref().unwrap();
    assert_eq!(executed.sources[0], other);
    assert!(executed.path.len() > 50);
    assert_eq!(executed.success, executed.failure.is_none());
    h.get_by_label_contains("Tried: ");
    // The executed subtasks in numbers: contiguous steps, finite errors, the held cube's slip in
    // the second subtask.
    let d = &executed.diagnostics;
    assert_eq!(d.len(), 2);
    assert_eq!((d[0].steps.0, d[0].steps.1, d[1].steps.1), (0, d[1].steps.0, executed.path.len()));
    assert!(d.iter().all(|s| s.target_error_mm.is_finite() && s.target_error_mm < 100.0));
    assert!(d[0].object_moved_mm.is_some() && d[1].held_object_slip_mm.is_some() && d[0].held_object_slip_mm.is_none());
    h.get_by_label("held slip (mm)");
}

/// The 3D view gets the shown demo and every tried attempt; here it streams to a `.rrd` file, read
/// back with the viewer's own CLI.
#[test]
fn the_3d_view_streams_the_shown_demo_and_tried_attempts_to_rerun() {
    let dir = tempfile::tempdir().unwrap();
    let rrd = dir.path().join("app.rrd");
    let mut h = harness(Some(fixture()));
    settle(&mut h);
    h.state_mut().command(Command::Open3d(mimicgen_gui::protocol::ViewerSink::Save(rrd.clone())));
    settle(&mut h);
    assert!(h.state().model.viewer.is_some(), "{:?}", h.state().model.error);
    h.get_by_label_contains("demo_4").click();
    h.step();
    settle(&mut h);
    assert_eq!(h.state().model.status, "showing demo_4 in 3D");
    h.get_by_label("Preview").click();
    h.step();
    settle(&mut h);
    assert!(h.state().model.error.is_none(), "the plan goes to the 3D view too: {:?}", h.state().model.error);
    h.get_by_label("Try it").click();
    h.step();
    settle(&mut h);
    assert!(h.state().model.error.is_none(), "{:?}", h.state().model.error);
    let bin = mimicgen_viz::viewer_path();
    assert!(bin.is_file(), "no Rerun viewer at {} (run scripts/setup.sh)", bin.display());
    let out = std::process::Command::new(&bin).args(["rrd", "print", "-vv"]).arg(&rrd).output().unwrap();
    let print = String::from_utf8_lossy(&out.stdout);
    for entity in
        ["/world/scene/", "/world/demo/eef_path/subtask_0", "/world/attempt/executed_path", "/world/attempt/subtask_1/transformed_segment"]
    {
        assert!(print.contains(entity), "{entity} missing from the recording");
    }
    assert!(print.contains("LineStrips3D:show_labels"), "labels are hidden in the view (hover shows them)");
    // A run started with the 3D view open records its attempts too (beside the app's recording).
    h.get_by_label("Generate").click();
    h.run_steps(2);
    let out = dir.path().join("run.hdf5");
    h.state_mut().command(Command::SetRunForm(Box::new(mimicgen_gui::model::RunForm {
        attempts: 3,
        out: out.display().to_string(),
        ..Default::default()
    })));
    h.get_by_label("Start").click();
    h.step();
    until_run_ends(&mut h);
    let run_rrd = dir.path().join("app_run.rrd");
    let out = std::process::Command::new(&bin).args(["rrd", "print"]).arg(&run_rrd).output().unwrap();
    let print = String::from_utf8_lossy(&out.stdout);
    assert!(
        print.contains("/world/history/attempt_00002") && print.contains("/stats/generation_rate"),
        "the run's recording lacks its attempts"
    );
}

/// A plain robomimic file (no `datagen_info`) is prepared by replay in the background, with
/// progress, then opens like a source file.
#[test]
fn a_plain_robomimic_file_is_prepared_in_the_background_with_progress() {
    use mimicgen_io::tree::Node;
    let dir = tempfile::tempdir().unwrap();
    let mut plain = mimicgen_io::RobomimicDataset::open(fixture()).unwrap();
    let Some(Node::Group(data)) = plain.root.members.get_mut("data") else { panic!("no data group") };
    data.members.retain(|name, _| ["demo_0", "demo_1", "demo_2"].contains(&name.as_str()));
    for node in data.members.values_mut() {
        if let Node::Group(demo) = node {
            demo.members.remove("datagen_info");
        }
    }
    let path = dir.path().join("plain.hdf5");
    mimicgen_io::write_tree(&path, &plain.root).unwrap();
    let mut h = harness(Some(path.clone()));
    settle(&mut h);
    let model = &h.state().model;
    assert!(model.error.is_none(), "{:?}", model.error);
    let file = model.file.as_ref().unwrap();
    assert_eq!(file.prepared_from.as_deref(), Some(path.as_path()));
    assert_eq!(file.demos.len(), 3);
    // Replayed signals give the same subtask ends as the reference's own datagen_info.
    assert!(file.demos.iter().all(|d| d.stored_ends.is_some()));
    assert_eq!(file.path, mimicgen_pipeline::prepare::cached_prepared_path(&path));
    h.get_by_label_contains("prepared by replay");
    // The backend reports every replayed demo (a copy under another name is prepared afresh).
    let copy = dir.path().join("plain_copy.hdf5");
    std::fs::copy(&path, &copy).unwrap();
    let progress = std::cell::RefCell::new(Vec::new());
    mimicgen_gui::backend::open(&copy, &|reply| progress.borrow_mut().push(reply)).unwrap();
    let done: Vec<(usize, usize)> = progress
        .into_inner()
        .into_iter()
        .filter_map(|r| match r {
            mimicgen_gui::protocol::Reply::Progress { done, total, .. } => Some((done, total)),
            _ => None,
        })
        .collect();
    assert_eq!(done, vec![(1, 3), (2, 3), (3, 3)]);
}

/// A large file streams in: the first 64 demos open the file (the list is usable at once), the
/// rest follow, and the app's list grows to all of them.
#[test]
fn a_large_file_streams_in_and_is_browsable_before_it_is_read() {
    use mimicgen_io::tree::Node;
    let dir = tempfile::tempdir().unwrap();
    let mut big = mimicgen_io::RobomimicDataset::open(fixture()).unwrap();
    let Some(Node::Group(data)) = big.root.members.get_mut("data") else { panic!("no data group") };
    let originals: Vec<Node> = (0..10).map(|i| data.members[&format!("demo_{i}")].clone()).collect();
    for i in 10..90 {
        data.members.insert(format!("demo_{i}"), originals[i % 10].clone());
    }
    let path = dir.path().join("big.hdf5");
    mimicgen_io::write_tree(&path, &big.root).unwrap();
    let sent = std::cell::RefCell::new(Vec::new());
    let (last, found) = mimicgen_gui::backend::open(&path, &|reply| sent.borrow_mut().push(reply)).unwrap();
    let sent = sent.into_inner();
    let [mimicgen_gui::protocol::Reply::Opened(first)] = sent.as_slice() else {
        panic!("expected the first part alone, got {} replies", sent.len())
    };
    assert_eq!((first.demos.len(), first.total_demos), (64, 90));
    assert!(!sent[0].ends_request());
    let mimicgen_gui::protocol::Reply::MoreDemos { demos, last: true, .. } = &last else { panic!("expected the last part") };
    assert_eq!(demos.len(), 26);
    assert_eq!(demos[25].name, "demo_89");
    assert_eq!(found.sources.demos.len(), 90);
    // In the app: everything arrives and every demo gets its ends.
    let mut h = harness(Some(path));
    settle(&mut h);
    let model = &h.state().model;
    assert_eq!(model.file.as_ref().unwrap().demos.len(), 90);
    assert_eq!(model.annotation.marks.ends.len(), 90);
    assert_eq!(model.annotation.marks.ends["demo_83"], model.annotation.marks.ends["demo_3"], "copies of a demo get its ends");
    h.get_by_label("90 demos");
}

/// Objects dragged in the view from above make the scene the preview plans (and "try it" runs).
#[test]
fn dragging_an_object_from_above_moves_it_in_the_planned_scene() {
    let mut h = harness(Some(fixture()));
    settle(&mut h);
    h.get_by_label("Preview").click();
    h.step();
    settle(&mut h);
    let before = h.state().model.preview.view.clone().unwrap();
    let cube = before.objects.iter().find(|o| o.name == "cubeA").unwrap().clone();
    let memory = egui_plot::PlotMemory::load(&h.ctx, mimicgen_gui::preview_ui::preview_plot_id("top")).unwrap();
    let at = |x: f64, y: f64| memory.transform().position_from_point(&egui_plot::PlotPoint::new(x, y));
    drag(&mut h, at(cube.position[0], cube.position[1]), at(cube.position[0] + 0.03, cube.position[1] - 0.02));
    h.step();
    settle(&mut h);
    let moved = h.state().model.preview.moved.get("cubeA").copied().unwrap();
    assert!((moved[0] - (cube.position[0] + 0.03)).abs() < 0.003 && (moved[1] - (cube.position[1] - 0.02)).abs() < 0.003, "{moved:?}");
    let after = h.state().model.preview.view.clone().unwrap();
    let planned = after.objects.iter().find(|o| o.name == "cubeA").unwrap();
    assert_eq!([planned.position[0], planned.position[1]], moved, "the plan uses the moved cube");
    assert_eq!(planned.position[2], cube.position[2], "height as sampled");
    let other = |v: &mimicgen_gui::protocol::PreviewView| v.objects.iter().find(|o| o.name == "cubeB").unwrap().position;
    assert_eq!(other(&after), other(&before));
    assert_ne!(after.subtasks[0].transformed, before.subtasks[0].transformed, "the segment follows the cube");
    h.get_by_label("Try it").click();
    h.step();
    settle(&mut h);
    let tried = h.state().model.preview.view.clone().unwrap();
    assert!(tried.executed.is_some() && tried.objects == after.objects, "try it runs the moved scene");
    h.get_by_label("Reset objects").click();
    h.step();
    settle(&mut h);
    assert!(h.state().model.preview.moved.is_empty());
    assert_eq!(h.state().model.preview.view.as_ref().unwrap().objects, before.objects);
}

/// Waits (stepping frames) until the app's run has ended.
fn until_run_ends(h: &mut Harness<'static, MimicgenApp>) {
    let deadline = Instant::now() + Duration::from_secs(900);
    while h.state().model.run.as_ref().is_some_and(mimicgen_gui::model::RunState::running) {
        h.step();
        assert!(Instant::now() < deadline, "the run did not end");
        std::thread::sleep(Duration::from_millis(20));
    }
    h.run_steps(2);
}

/// A run from the app: the form, Start, live progress, the report and the outputs; a re-run of
/// one of its attempts in the preview has the same outcome; a long run cancelled leaves a valid
/// dataset.
#[test]
fn a_run_started_from_the_app_reports_live_and_can_be_cancelled() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("app_run.hdf5");
    let mut h = harness(Some(fixture()));
    settle(&mut h);
    h.get_by_label("Generate").click();
    h.step();
    // Seed 1: one of the first attempts misses its grasp, so the run has a failure to keep, open
    // and re-run.
    let form = mimicgen_gui::model::RunForm { attempts: 6, seed: 1, out: out.display().to_string(), ..Default::default() };
    h.state_mut().command(Command::SetRunForm(Box::new(form.clone())));
    h.run_steps(2);
    h.get_by_label_contains("mimicgen generate --source");
    // A spec field set in the form goes to the command line and the run (0.05 is the bundled
    // spec's noise, so the run is the one the comments below describe).
    h.get_by_label("Spec fields").click();
    h.run_steps(2);
    h.get_by_label("action noise").click();
    h.run_steps(2);
    assert_eq!(h.state().model.run_form.spec.to_args(), ["--action-noise", "0.05"]);
    h.get_by_label_contains("--num-demos 6 --seed 1 --workers 1");
    let line = mimicgen_gui::model::RunForm { spec: h.state().model.run_form.spec.clone(), ..form.clone() }
        .command_line(&h.state().model.file.as_ref().unwrap().path, None);
    assert!(line.ends_with("--keep-failed --action-noise 0.05"), "{line}");
    h.get_by_label("Start").click();
    h.step();
    until_run_ends(&mut h);
    let run = h.state().model.run.clone().unwrap();
    assert!(run.error.is_none(), "{:?}", run.error);
    assert_eq!(run.config.spec.action_noise.len(), 1);
    let report = run.report.as_ref().unwrap();
    assert_eq!((run.rows.len(), report.attempts), (6, 6));
    assert_eq!(report.successes, run.rows.iter().filter(|r| r.success).count());
    assert_eq!(run.rows.iter().map(|r| r.index).collect::<Vec<_>>(), (0..6).collect::<Vec<_>>());
    assert!(out.is_file() && !report.cancelled);
    h.get_by_label_contains("6 attempts,");
    // The coverage view's numbers are `mimicgen coverage`'s on the written dataset (one function).
    let written = mimicgen_io::read_source_dataset(&out, &Default::default()).unwrap();
    let scenes: Vec<_> = written.demos.iter().map(|d| d.object_poses.iter().map(|(k, v)| (k.clone(), v[0])).collect()).collect();
    let dims = mimicgen_sim::registry::task("stack", "D0").unwrap().coverage_dimensions();
    let expected = mimicgen_engine::coverage::coverage(&scenes, &dims, 3).unwrap().support_coverage();
    h.get_by_label_contains(&format!("successes {:.1} %", 100.0 * expected));
    // The run's outputs opened afterwards give the same attempts (all kept: keep failed is on).
    h.get_by_role_and_label(egui::accesskit::Role::TextInput, "Dataset:").click();
    h.run_steps(2);
    h.get_by_role_and_label(egui::accesskit::Role::TextInput, "Dataset:").type_text(&out.display().to_string());
    h.run_steps(2);
    h.get_by_label("Open run").click();
    h.step();
    settle(&mut h);
    let opened = h.state().model.run.clone().unwrap();
    assert!(opened.error.is_none() && h.state().model.error.is_none(), "{:?}", h.state().model.error);
    let failed = run.rows.iter().find(|r| !r.success).expect("seed 1 has a failed attempt among the first 6").clone();
    assert!(failed.reason.as_deref().is_some_and(|r| r.contains("grasp")), "{failed:?}");
    assert!(failed.cause.is_some(), "a failure's cause: {failed:?}");
    // Object poses compared to 1e-9: the live run's come from the simulator's rotation, the opened
    // file's from the stored 4x4 matrix, and the yaw taken from either can differ in the last bit.
    let key = |r: &mimicgen_gui::protocol::AttemptRow| {
        let objects: Vec<String> = r.objects.iter().map(|o| format!("{} {:.9?} {:.9}", o.name, o.position, o.yaw)).collect();
        (r.index, r.success, r.steps, r.sources.clone(), r.reason.clone(), r.cause.clone(), objects)
    };
    assert_eq!(opened.rows.iter().map(key).collect::<Vec<_>>(), run.rows.iter().map(key).collect::<Vec<_>>());
    // The report read back from its JSON (floats parsed from text may differ in the last bit).
    let exact = |r: &mimicgen_pipeline::Report| mimicgen_pipeline::Report {
        wall_time_s: 0.0,
        attempts_per_s: 0.0,
        generation_rate: 0.0,
        peak_rss_mib: None,
        quality: None,
        ..r.clone()
    };
    assert_eq!(exact(opened.report.as_ref().unwrap()), exact(report));
    let replay = |r: &mimicgen_pipeline::Report| r.quality.as_ref().map(|q| q.replay.clone());
    assert_eq!(replay(opened.report.as_ref().unwrap()), replay(report), "the quality report read back");
    assert_eq!(opened.config.source, run.config.source, "the report names the source, so its attempts can be re-run");
    // Compared with itself, the second coverage row says the same as the first.
    h.get_by_label("Compare").click();
    h.step();
    settle(&mut h);
    assert_eq!(h.state().model.compare.as_ref().unwrap().rows.len(), 6);
    // Each row also says how many of its attempts succeeded.
    let successes = run.rows.iter().filter(|r| r.success).count();
    h.get_by_label_contains(&format!("this run: 6 scenes, {successes} successes ("));
    h.get_by_label_contains(&format!("app_run.hdf5 (stack D0): 6 scenes, {successes} successes ("));
    // Re-run the failed attempt in the preview: the same seed and index give the same outcome.
    h.get_by_label("Generate").click();
    h.run_steps(2);
    // Causes and the success matrix, folded until asked for.
    assert!(h.query_by_label("Failures by subtask and cause").is_none());
    h.get_by_label("Causes and the success matrix").click();
    h.run_steps(2);
    h.get_by_label("Failures by subtask and cause");
    // The success matrix: each subtask's row counts the attempts by the source of its segment.
    h.get_by_label("Successes by subtask and source demo");
    let first = failed.sources[0];
    let used = run.rows.iter().filter(|r| r.sources.first() == Some(&first)).collect::<Vec<_>>();
    let won = used.iter().filter(|r| r.success).count();
    assert!(h.query_all_by_label(&format!("{won}/{}", used.len())).count() > 0, "a cell {won}/{}", used.len());
    h.get_by_label("Causes and the success matrix").click();
    h.run_steps(2);
    h.get_by_label_contains(&format!("{:>5}  failure", failed.index)).click();
    h.run_steps(2);
    // What went wrong there, as the run found it.
    h.get_by_label_contains(&format!(
        "failed in subtask {}: {} ({})",
        failed.failed_subtask.unwrap(),
        failed.reason.as_ref().unwrap(),
        failed.cause.as_ref().unwrap()
    ));
    // The nearest success (by where the objects were) is offered for comparison.
    let (near, _) = mimicgen_gui::model::nearest_success(&run.rows, &failed).unwrap();
    assert!(near.success && near.index != failed.index);
    h.get_by_label_contains(&format!("attempt {} (objects", near.index));
    assert!(h.state().model.stay_on_selected, "selecting an attempt keeps the 3D view on it");
    // Side by side: both re-run, as the run had them, each with its numbers and views.
    h.get_by_label("Side by side").click();
    h.step();
    settle(&mut h);
    let pair = h.state().model.side_by_side.clone().unwrap();
    assert_eq!(pair.indices, [failed.index, near.index]);
    let views = pair.views.unwrap();
    let outcome = |v: &mimicgen_gui::protocol::PreviewView| v.executed.as_ref().map(|e| (e.success, e.path.len()));
    assert_eq!(outcome(&views[0]), Some((false, failed.steps)));
    assert_eq!(outcome(&views[1]), Some((true, near.steps)));
    h.get_by_label_contains(&format!("attempt {}: failed (subtask", failed.index));
    h.get_by_label_contains(&format!("attempt {}: success in {} steps", near.index, near.steps));
    assert!(h.query_by_label_contains("the re-run's outcome differs").is_none());
    h.get_by_label("Back to the charts").click();
    h.run_steps(2);
    assert!(h.state().model.side_by_side.is_none());
    h.get_by_label("Re-run that one");
    h.get_by_label("Re-run in preview").click();
    h.step();
    settle(&mut h);
    let model = &h.state().model;
    assert_eq!(model.screen, mimicgen_gui::Screen::Preview);
    let view = model.preview.view.as_ref().unwrap();
    assert_eq!((view.seed, view.index), (1, failed.index));
    let executed = view.executed.as_ref().unwrap();
    assert!(!executed.success);
    assert_eq!(executed.failure, Some(format!("subtask {}: {}", failed.failed_subtask.unwrap(), failed.reason.as_ref().unwrap())));
    assert_eq!(executed.cause, failed.cause, "the re-run fails for the reason and cause the run did");
    assert_eq!(executed.path.len(), failed.steps);
    // What went wrong, in numbers: the grasp pushed the cube, and the cube was left behind while
    // the gripper carried on (it "slipped" by the whole transport).
    let d = &executed.diagnostics;
    assert!(d[0].object_moved_mm.is_some_and(|mm| mm > 5.0), "{d:?}");
    assert!(d[1].held_object_slip_mm.is_some_and(|mm| mm > 20.0), "{d:?}");
    // A long run, cancelled: it stops early and its dataset is complete.
    h.get_by_label("Generate").click();
    h.run_steps(2);
    let long = mimicgen_gui::model::RunForm { attempts: 400, overwrite: true, ..form };
    h.state_mut().command(Command::SetRunForm(Box::new(long)));
    h.get_by_label("Start").click();
    let deadline = Instant::now() + Duration::from_secs(600);
    while h.state().model.run.as_ref().is_none_or(|r| r.rows.len() < 3) {
        h.step();
        assert!(Instant::now() < deadline, "no attempts arrived");
        std::thread::sleep(Duration::from_millis(20));
    }
    h.get_by_label("Cancel").click();
    h.step();
    until_run_ends(&mut h);
    let run = h.state().model.run.clone().unwrap();
    let report = run.report.as_ref().unwrap();
    assert!(report.cancelled && report.attempts < 400, "{} attempts", report.attempts);
    assert_eq!(run.rows.len(), report.attempts);
    let written = mimicgen_io::RobomimicDataset::open(&out).unwrap();
    assert_eq!(written.demo_names().len(), report.successes);
}

/// The quality report and the Doctor panel: folded until asked for, the Doctor it diagnoses the finished run on its own thread
/// (the UI goes on), shows the ranked suggestions and the tested one with its verdict, and puts
/// the tested change into the run form over the run's own spec fields.
#[test]
fn the_doctor_panel_tests_a_change_and_puts_it_into_the_run_form() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("noisy.hdf5");
    let mut h = harness(Some(fixture()));
    settle(&mut h);
    h.get_by_label("Generate").click();
    h.step();
    // So much noise that grasps miss: the run has failures with causes.
    let noisy = mimicgen_gui::model::SpecOverrides { action_noise: vec![mimicgen_pipeline::Scoped::all(0.3)], ..Default::default() };
    let form =
        mimicgen_gui::model::RunForm { attempts: 12, seed: 3, out: out.display().to_string(), spec: noisy.clone(), ..Default::default() };
    h.state_mut().command(Command::SetRunForm(Box::new(form)));
    h.run_steps(2);
    assert!(h.query_by_label("Doctor: what to change").is_none(), "no Doctor before a run has ended");
    h.get_by_label("Start").click();
    h.step();
    until_run_ends(&mut h);
    let report = h.state().model.run.as_ref().unwrap().report.clone().unwrap();
    assert!(report.successes < report.attempts && !report.causes.is_empty(), "{report:?}");
    assert!(h.query_by_label("Diagnose").is_none(), "folded");
    // The quality report, folded too: the replay sample's outcome as the report has it.
    let replay = report.quality.as_ref().unwrap().replay.clone().unwrap();
    h.get_by_label("Quality of the dataset").click();
    h.run_steps(2);
    h.get_by_label_contains(&format!("{} of {} written demos replay to success", replay.succeeded, replay.demos.len()));
    h.get_by_label("subtask 1 interpolation start");
    h.get_by_label("Quality of the dataset").click();
    h.run_steps(2);
    h.get_by_label("Doctor: what to change").click();
    h.run_steps(2);
    assert!(h.state().model.doctor.shown);
    h.state_mut().command(Command::SetDoctor { budget: 16, top: 1 });
    h.run_steps(2);
    h.get_by_label("Diagnose").click();
    h.step();
    let deadline = Instant::now() + Duration::from_secs(900);
    let mut saw_progress = false;
    while h.state().model.doctor.running {
        saw_progress |= h.query_by_label_contains("of 16 attempts").is_some();
        h.step();
        assert!(Instant::now() < deadline, "the doctor did not finish");
        std::thread::sleep(Duration::from_millis(20));
    }
    h.run_steps(2);
    let doctor = h.state().model.doctor.clone();
    assert!(doctor.error.is_none(), "{:?}", doctor.error);
    assert!(saw_progress || doctor.diagnosis.is_some(), "a progress bar while it worked");
    let d = doctor.diagnosis.unwrap();
    assert_eq!((d.first_attempt, d.attempts, d.trials.len()), (12, 8, 1));
    h.get_by_label("Suggestions, most failures addressed first");
    h.get_by_label_contains("Tested on attempts 12..20 (seed 3)");
    let t = &d.trials[0];
    h.get_by_label(t.verdict.words());
    h.get_by_label_contains(&format!("{:+.1} points [", 100.0 * t.paired.difference));
    // "use": the run's spec fields, then the change.
    h.get_by_label("use").click();
    h.run_steps(2);
    assert_eq!(h.state().model.run_form.spec, noisy.then(&t.suggestion.change));
    // The form's command line says so.
    let line = h.state().model.run_form.command_line(&h.state().model.file.as_ref().unwrap().path, None);
    assert!(line.contains(&t.suggestion.flags()), "{line}");
    h.get_by_label(&line);
    // Folded again.
    h.get_by_label("Doctor: what to change").click();
    h.run_steps(2);
    assert!(h.query_by_label("Diagnose").is_none());
}

/// The file browser lists folders and HDF5 files through the backend; a click goes up a folder,
/// into one, or opens a file.
#[test]
fn the_file_browser_opens_a_file_from_a_folder() {
    let mut h = harness(Some(fixture()));
    settle(&mut h);
    h.get_by_label("Browse…").click();
    h.step();
    settle(&mut h);
    let listing = h.state().model.browser.clone().unwrap();
    assert_eq!(listing.dir, fixture().parent().unwrap().canonicalize().unwrap());
    assert!(listing.files.iter().any(|(p, _)| p.ends_with("generated_D0_first3.hdf5")));
    h.get_by_label("⬆ ..").click();
    h.step();
    settle(&mut h);
    h.get_by_label("📁 data").click();
    h.step();
    settle(&mut h);
    h.get_by_label_contains("generated_D0_first3.hdf5").click();
    h.step();
    settle(&mut h);
    let model = &h.state().model;
    assert!(model.browser.is_none(), "the browser closes on open");
    let file = model.file.as_ref().unwrap();
    assert!(file.path.ends_with("generated_D0_first3.hdf5"), "{}", file.path.display());
    assert_eq!(file.demos.len(), 3);
}

/// A file with camera observations (`generate --cameras`) shows the shown demo's images at the
/// cursor, beside the timeline; they follow the cursor and the demo, and a demo without any
/// shows none.
#[test]
fn camera_images_follow_the_cursor_and_the_shown_demo() {
    use mimicgen_io::tree::{Array, Dataset, Node, Values};
    let dir = tempfile::tempdir().unwrap();
    let mut file = mimicgen_io::RobomimicDataset::open(fixture()).unwrap();
    let Some(Node::Group(data)) = file.root.members.get_mut("data") else { panic!("no data group") };
    data.members.retain(|name, _| ["demo_0", "demo_1", "demo_2"].contains(&name.as_str()));
    let (h_px, w_px) = (12, 16);
    for (i, name) in ["demo_0", "demo_1"].iter().enumerate() {
        let Some(Node::Group(demo)) = data.members.get_mut(*name) else { panic!("no {name}") };
        let steps = mimicgen_io::dataset::demo_steps(demo);
        // Each step's image is one grey level: step t of demo i is 10 * i + t.
        let pixels: Vec<u8> =
            (0..steps).flat_map(|t| std::iter::repeat_n(u8::try_from((10 * i + t) % 256).unwrap(), h_px * w_px * 3)).collect();
        let Node::Group(obs) = demo.members.entry("obs".into()).or_insert_with(|| Node::Group(Default::default())) else { panic!("obs") };
        obs.members.insert(
            "agentview_image".into(),
            Node::Dataset(Dataset::new(Array { shape: vec![steps, h_px, w_px, 3], values: Values::U8(pixels) })),
        );
    }
    let path = dir.path().join("cameras.hdf5");
    mimicgen_io::write_tree(&path, &file.root).unwrap();
    let mut h = harness(Some(path));
    settle(&mut h);
    let images = |h: &Harness<'static, MimicgenApp>| h.state().model.images.clone();
    let (demo, cameras) = images(&h);
    assert_eq!((demo, cameras.len()), (0, 1), "the first demo's images come with the file");
    assert_eq!((cameras[0].name.as_str(), cameras[0].width, cameras[0].height), ("agentview", w_px, h_px));
    h.get_by_label("agentview (step 0)");
    h.state_mut().command(Command::SetCursor(5));
    h.run_steps(2);
    h.get_by_label("agentview (step 5)");
    assert_eq!(cameras[0].frame(5).unwrap()[0], 5);
    h.get_by_label_contains("demo_1").click();
    h.step();
    settle(&mut h);
    let (demo, cameras) = images(&h);
    assert_eq!(demo, 1);
    assert_eq!(cameras[0].frame(0).unwrap()[0], 10, "demo_1's own images");
    h.get_by_label_contains("agentview (step");
    h.get_by_label_contains("demo_2").click();
    h.step();
    settle(&mut h);
    assert_eq!(images(&h), (2, Vec::new()));
    assert!(h.query_by_label_contains("agentview (step").is_none(), "demo_2 has no camera images");
}

/// Robot transfer and image datasets from the app: Square D0's bundled sources, the UR5e picked in
/// the run form, cameras ticked; the run writes images that the app then shows.
#[test]
fn a_ur5e_run_with_cameras_is_launched_watched_and_its_images_seen() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("square_ur5e.hdf5");
    let square = bundled("square_D0_source.hdf5");
    let mut h = harness(Some(square));
    settle(&mut h);
    h.get_by_label("Generate").click();
    h.step();
    let form = mimicgen_gui::model::RunForm { attempts: 1, guarantee: true, seed: 3, out: out.display().to_string(), ..Default::default() };
    h.state_mut().command(Command::SetRunForm(Box::new(form)));
    h.run_steps(2);
    // The arm from the welcome's list, by clicking the combo box and its entry.
    assert!(h.state().model.welcome.robots.iter().any(|r| r == "ur5e"), "{:?}", h.state().model.welcome.robots);
    h.get_by_role_and_label(egui::accesskit::Role::ComboBox, "Robot").click();
    h.run_steps(2);
    h.get_by_label("ur5e").click();
    h.run_steps(2);
    h.get_by_label("render cameras").click();
    h.run_steps(2);
    assert_eq!(h.state().model.run_form.robot.as_deref(), Some("ur5e"));
    let cameras = h.state().model.run_form.cameras.clone().unwrap();
    assert_eq!(cameras.names, ["agentview", "robot0_eye_in_hand"]);
    h.get_by_label_contains("--robot ur5e");
    h.get_by_label_contains("--cameras agentview,robot0_eye_in_hand --camera-size 84");
    h.get_by_label("Start").click();
    h.step();
    until_run_ends(&mut h);
    let run = h.state().model.run.clone().unwrap();
    assert!(run.error.is_none(), "{:?}", run.error);
    let report = run.report.as_ref().unwrap();
    assert_eq!(report.successes, 1, "{report:?}");
    let env_args: serde_json::Value = serde_json::from_str(mimicgen_io::RobomimicDataset::open(&out).unwrap().env_args().unwrap()).unwrap();
    assert_eq!(env_args["env_kwargs"]["robots"], serde_json::json!(["UR5e"]));
    assert_eq!(env_args["env_kwargs"]["camera_names"], serde_json::json!(["agentview", "robot0_eye_in_hand"]));
    // The dataset it wrote, opened: both cameras' images at the cursor.
    h.state_mut().command(Command::Open(out.clone()));
    settle(&mut h);
    let (demo, cameras) = h.state().model.images.clone();
    assert_eq!(demo, 0);
    let m = &h.state().model;
    assert!(m.error.is_none() && m.file.as_ref().is_some_and(|f| f.path == out), "{:?} {:?}", m.error, m.file.as_ref().map(|f| &f.path));
    let names: Vec<&str> = cameras.iter().map(|c| c.name.as_str()).collect();
    assert_eq!(names, ["agentview", "robot0_eye_in_hand"]);
    assert!(cameras.iter().all(|c| (c.width, c.height) == (84, 84) && c.frame(0).is_some_and(|f| f.iter().any(|&p| p > 0))));
    h.get_by_label("Annotate").click();
    h.run_steps(3);
    h.get_by_label("agentview (step 0)");
    h.get_by_label("robot0_eye_in_hand (step 0)");
}

/// The real backend behind a transport that answers the first preview request as the backend's
/// guard answers a request that panics.
struct Injecting {
    real: mimicgen_gui::backend::Backend,
    injected: Vec<mimicgen_gui::protocol::Reply>,
    armed: bool,
}

impl mimicgen_gui::Transport for Injecting {
    fn send(&mut self, request: mimicgen_gui::protocol::Request) {
        if self.armed && matches!(request, mimicgen_gui::protocol::Request::Preview(_)) {
            self.armed = false;
            let reply = mimicgen_gui::backend::guarded("answering the preview".into(), || panic!("injected failure"));
            self.injected.push(reply);
        } else {
            self.real.send(request);
        }
    }

    fn try_replies(&mut self) -> Vec<mimicgen_gui::protocol::Reply> {
        let mut replies = std::mem::take(&mut self.injected);
        replies.extend(self.real.try_replies());
        replies
    }
}

/// A request whose answer panics is shown as an error where it was made; the app is not left
/// "working", and everything after it works.
#[test]
fn a_failing_request_is_shown_and_the_app_goes_on() {
    let backend = Injecting { real: mimicgen_gui::backend::Backend::start(|| {}, None), injected: Vec::new(), armed: true };
    let app = MimicgenApp::new(Box::new(backend), Some(fixture()));
    let mut h = Harness::builder().with_size(egui::vec2(1280.0, 800.0)).build_ui_state(|ui, app: &mut MimicgenApp| app.show(ui), app);
    settle(&mut h);
    h.get_by_label("Preview").click();
    h.step();
    settle(&mut h);
    let model = &h.state().model;
    assert!(model.busy.is_none() && model.in_flight == 0, "left working: {:?}", model.busy);
    let error = model.error.clone().unwrap_or_default();
    assert!(error.contains("answering the preview") && error.contains("injected failure"), "{error}");
    h.get_by_label_contains("injected failure");
    assert!(model.preview.view.is_none());
    // The same screen again, and another file: answered as usual.
    h.state_mut().command(Command::NextScene);
    settle(&mut h);
    assert!(h.state().model.preview.view.is_some(), "{:?}", h.state().model.error);
    let square = bundled("square_D0_source.hdf5");
    h.state_mut().command(Command::Open(square));
    settle(&mut h);
    assert_eq!(h.state().model.file.as_ref().unwrap().task, "square");
}

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
