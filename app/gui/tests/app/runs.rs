//! Generation runs from the app: started, watched live, cancelled, re-run; the doctor's panel;
//! the file browser; camera images; a failing request.

use std::time::{Duration, Instant};

use egui_kittest::Harness;
use egui_kittest::kittest::Queryable as _;
use mimicgen_gui::{Command, MimicgenApp};

use crate::common::{bundled, fixture, harness, settle, until_run_ends};

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
