//! The app driven through its real UI with egui_kittest (no display): open files (source demos, a
//! broken file, a plain robomimic file, a large file), annotate (keyboard, mouse, undo and redo,
//! auto-detect, segment starts, save and reload), preview and try attempts (new scenes, forced
//! sources, dragged objects, planned transit), the 3D view's recording, and generation runs
//! (start, progress, cancel, re-run).
#![allow(clippy::unwrap_used)] // tests fail loudly by design
#![allow(clippy::float_cmp)] // positions pass through the backend unchanged: exact comparisons are the point

mod common;
mod runs;
mod tasks;

use egui_kittest::kittest::Queryable as _;
use mimicgen_gui::Command;

use common::{drag, fixture, harness, settle, until_run_ends};

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
