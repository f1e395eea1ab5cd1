//! `mimicgen demos` and `mimicgen generate` on robosuite's two-arm tasks (Two Arm Lift, Handover,
//! Transport).
#![allow(clippy::unwrap_used, clippy::indexing_slicing)] // tests fail loudly by design

use std::path::Path;
use std::process::Command;

use mimicgen_engine::spec::SourceSelection;
use mimicgen_io::RobomimicDataset;

fn mimicgen() -> Command {
    let mut command = Command::new(env!("CARGO_BIN_EXE_mimicgen"));
    command.env("HDF5_USE_FILE_LOCKING", "FALSE");
    command
}

fn generate(out: &Path, workers: &str, extra: &[&str]) {
    let run = mimicgen()
        .args(["generate", "--task", "two_arm_lift", "--num-demos", "6", "--seed", "3", "--workers", workers, "--out"])
        .arg(out)
        .args(extra)
        .output()
        .unwrap();
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
}

/// The file robosuite's TwoArmLift reads: 14-wide actions, both robots' observations, `env_args`
/// with both Pandas, each arm's annotations; the same seed gives the same demos on 1 or 2 workers.
#[test]
fn two_arm_lift_writes_both_arms_and_the_seed_decides_the_dataset() {
    let dir = tempfile::tempdir().unwrap();
    let (one, two) = (dir.path().join("one.hdf5"), dir.path().join("two.hdf5"));
    generate(&one, "1", &[]);
    generate(&two, "2", &[]);
    let (a, b) = (RobomimicDataset::open(&one).unwrap(), RobomimicDataset::open(&two).unwrap());
    assert!(!a.demo_names().is_empty(), "no attempt succeeded");
    assert_eq!(a.demo_names(), b.demo_names());
    for name in a.demo_names() {
        let actions = |d: &RobomimicDataset| d.demo(name).unwrap().dataset("actions").unwrap().array.clone();
        assert_eq!(actions(&a), actions(&b), "{name}: 1 and 2 workers differ");
        let demo = a.demo(name).unwrap();
        assert_eq!(actions(&a).shape[1], 14);
        let obs = demo.group("obs").unwrap();
        for key in ["robot0_eef_pos", "robot1_eef_pos", "robot0_gripper_qpos", "robot1_joint_pos_cos"] {
            assert!(obs.dataset(key).is_some(), "{name}: no obs/{key}");
        }
        assert_eq!(obs.dataset("object").unwrap().array.shape[1], 19, "TwoArmLift's object-state");
        for arm in ["robot0", "robot1"] {
            assert!(demo.dataset_at(&format!("datagen_info/eef_pose/{arm}")).is_some(), "{name}: no eef_pose of {arm}");
        }
    }
    let env_args: serde_json::Value = serde_json::from_str(a.env_args().unwrap()).unwrap();
    assert_eq!(env_args["env_name"], "TwoArmLift");
    assert_eq!(env_args["env_kwargs"]["robots"], serde_json::json!(["Panda", "Panda"]));
    assert_eq!(env_args["env_kwargs"]["env_configuration"], "single-arm-opposed");
    // What was generated is a two-arm source in turn: one view per arm, of the same demos.
    let views = a.to_arm_source_datasets(&SourceSelection::default(), &["robot0", "robot1"]).unwrap();
    assert_eq!(views[0].demos.len(), a.demo_names().len());
    assert_ne!(views[0].demos[0].eef_poses[0], views[1].demos[0].eef_poses[0]);
    let report: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(dir.path().join("one.json")).unwrap()).unwrap();
    assert_eq!(report["attempts"], 6);
    assert_eq!(report["successes"].as_u64().unwrap(), a.demo_names().len() as u64);
    // One-arm commands say that the file is a two-arm one and what reads it.
    for (command, args) in [("doctor", vec![one.to_str().unwrap()]), ("coverage", vec![one.to_str().unwrap()])] {
        let run = mimicgen().arg(command).args(&args).output().unwrap();
        let err = String::from_utf8_lossy(&run.stderr);
        assert_eq!(run.status.code(), Some(2), "{command}: {err}");
        assert!(err.contains("two-arm"), "{command}: {err}");
    }
}

/// Recorded two-arm demos are a source for generation.
#[test]
fn recorded_two_arm_demos_are_a_source() {
    let dir = tempfile::tempdir().unwrap();
    let source = dir.path().join("source.hdf5");
    let run =
        mimicgen().args(["demos", "--task", "two_arm_lift", "--variant", "D1", "--num-demos", "3", "--out"]).arg(&source).output().unwrap();
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    let out = dir.path().join("out.hdf5");
    generate(&out, "1", &["--source", source.to_str().unwrap()]);
    let report: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(dir.path().join("out.json")).unwrap()).unwrap();
    // The one-arm runs' report: the three source demos, every subtask of both arms numbered
    // through (arm 0's, then arm 1's), each attempt counted once per subtask it planned.
    assert_eq!(report["per_source_demo"].as_array().unwrap().len(), 3);
    let spec = mimicgen_sim::two_arm::TwoArmTask::Lift.spec().unwrap();
    let subtasks: usize = spec.arms.iter().map(|a| a.subtasks.len()).sum();
    let matrix = report["per_subtask_source"].as_array().unwrap();
    assert_eq!(matrix.len(), subtasks);
    let first_subtask_uses: u64 = matrix[0].as_array().unwrap().iter().map(|d| d["attempts"].as_u64().unwrap()).sum();
    assert_eq!(first_subtask_uses, report["attempts"].as_u64().unwrap());
    let rate = report["successes"].as_f64().unwrap() / report["attempts"].as_f64().unwrap();
    assert!((report["generation_rate"].as_f64().unwrap() - rate).abs() < 1e-12, "{report}");
}

/// A flag the two-arm run does not take is refused by name, and nothing is written.
#[test]
fn a_flag_two_arm_runs_lack_is_refused_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.hdf5");
    let run = mimicgen().args(["generate", "--task", "two_arm_lift", "--resume", "--out"]).arg(&out).output().unwrap();
    let err = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(2), "{err}");
    assert!(err.contains("--resume") && err.contains("two_arm_lift"), "{err}");
    assert!(!out.exists());
}

/// `mimicgen spec check` reads a two-arm spec: its arms and ties; a tie it can never meet is
/// refused naming the field.
#[test]
fn spec_check_reads_a_two_arm_spec_and_names_a_bad_tie() {
    let spec = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../core/sim/tasks/two_arm_handover.two_arm.toml");
    let run = mimicgen().args(["spec", "check"]).arg(&spec).output().unwrap();
    let out = String::from_utf8_lossy(&run.stdout);
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    assert!(out.contains("coordination: arm 0 subtask 2 with arm 1 subtask 1"), "{out}");
    assert!(out.contains("sequential: arm 0 subtask 3 after arm 1 subtask 1"), "{out}");
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("bad.toml");
    // Arm 1's grasp tied to arm 0's carry (world frame): two frames in one coordination.
    let text = std::fs::read_to_string(&spec).unwrap().replacen("subtasks = [[0, 1], [1, 0]]", "subtasks = [[0, 1], [1, 1]]", 1);
    std::fs::write(&bad, text).unwrap();
    let run = mimicgen().args(["spec", "check"]).arg(&bad).output().unwrap();
    let err = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(2), "{err}");
    assert!(err.contains("bad.toml") && err.contains("coordination[0].subtasks"), "{err}");
}

/// `--guarantee` keeps attempting until the successes asked for: they are the first ones in
/// attempt order, the same on 1 and 2 workers; `--valid-fraction` writes robomimic's masks.
#[test]
fn guarantee_gives_the_first_successes_whatever_the_workers() {
    let dir = tempfile::tempdir().unwrap();
    let (one, two) = (dir.path().join("one.hdf5"), dir.path().join("two.hdf5"));
    for (out, workers) in [(&one, "1"), (&two, "2")] {
        let run = mimicgen()
            .args(["generate", "--task", "two_arm_handover", "--num-demos", "2", "--guarantee", "--seed", "1", "--valid-fraction", "0.5"])
            .args(["--workers", workers, "--out"])
            .arg(out)
            .output()
            .unwrap();
        assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    }
    let (a, b) = (RobomimicDataset::open(&one).unwrap(), RobomimicDataset::open(&two).unwrap());
    assert_eq!(a.demo_names().len(), 2);
    let attempts = |d: &RobomimicDataset| -> Vec<String> {
        d.demo_names().iter().map(|n| format!("{:?}", d.demo(n).unwrap().attrs.get("mimicgen_attempt"))).collect()
    };
    assert_eq!(attempts(&a), attempts(&b));
    assert!(attempts(&a).iter().all(|x| x.starts_with("Some")), "{:?}", attempts(&a));
    assert_eq!(a.masks().unwrap().get("valid").map(Vec::len), Some(1));
    let report: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(dir.path().join("one.json")).unwrap()).unwrap();
    assert_eq!(report["successes"], 2);
    assert!(report["attempts"].as_u64().unwrap() >= 2);
}

/// `mimicgen prepare` on a two-arm robomimic file (a teleoperated one has only actions, states
/// and model_file): replayed in the simulator, each arm's annotations and the signals are those
/// the generator recorded, so a user's own two-arm demos become a source.
#[test]
fn prepare_rebuilds_each_arms_annotations_from_states_and_actions() {
    let dir = tempfile::tempdir().unwrap();
    let generated = dir.path().join("generated.hdf5");
    generate(&generated, "1", &[]);
    let prepared = dir.path().join("prepared.hdf5");
    let run = mimicgen().arg("prepare").arg(&generated).arg("--out").arg(&prepared).output().unwrap();
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    let (a, b) = (RobomimicDataset::open(&generated).unwrap(), RobomimicDataset::open(&prepared).unwrap());
    assert_eq!(a.demo_names(), b.demo_names());
    let views = |d: &RobomimicDataset| d.to_arm_source_datasets(&SourceSelection::default(), &["robot0", "robot1"]).unwrap();
    for (arm, (x, y)) in views(&a).iter().zip(views(&b).iter()).enumerate() {
        for (dx, dy) in x.demos.iter().zip(&y.demos) {
            assert_eq!(dx.subtask_term_signals, dy.subtask_term_signals, "arm {arm}, {}", dx.name);
            assert_eq!(dx.gripper_actions, dy.gripper_actions, "arm {arm}, {}", dx.name);
            for (field, p, q) in [("eef", &dx.eef_poses, &dy.eef_poses), ("target", &dx.target_poses, &dy.target_poses)] {
                let worst = p.iter().zip(q).map(|(p, q)| (p.translation.vector - q.translation.vector).norm()).fold(0.0, f64::max);
                assert!(worst < 1e-9, "arm {arm}, {}: {field} poses differ by {worst} m", dx.name);
            }
        }
    }
    assert!(b.demo(&b.demo_names()[0]).unwrap().group("obs").unwrap().dataset("robot1_eef_pos").is_some(), "observations copied");
}

/// `mimicgen annotate --auto` on a two-arm file proposes each arm's ends and writes them as each
/// arm's signals, which generation then reads.
#[test]
fn annotate_proposes_each_arms_ends_and_writes_them() {
    let dir = tempfile::tempdir().unwrap();
    let source = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../core/sim/data/two_arm_lift_D0_source.hdf5");
    let out = dir.path().join("annotated.hdf5");
    let run = mimicgen().args(["annotate", "--auto", "--out"]).arg(&out).arg(&source).output().unwrap();
    let text = String::from_utf8_lossy(&run.stdout);
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    assert!(text.contains("arm robot0:") && text.contains("arm robot1:"), "{text}");
    let views = RobomimicDataset::open(&out).unwrap().to_arm_source_datasets(&SourceSelection::default(), &["robot0", "robot1"]).unwrap();
    for (view, signal) in views.iter().zip(["grasp_handle0", "grasp_handle1"]) {
        assert!(view.demos.iter().all(|d| d.subtask_term_signals[signal].contains(&1)), "{signal}");
    }
    let refused = mimicgen().args(["annotate", "--ends", "demo_0=30"]).arg(&source).output().unwrap();
    assert_eq!(refused.status.code(), Some(2), "{}", String::from_utf8_lossy(&refused.stderr));
    assert!(String::from_utf8_lossy(&refused.stderr).contains("two-arm"));
}

/// Two Arm Transport from its bundled scripted sources: a delivery (the hammer in the target bin,
/// the trash in the trash bin) written as robosuite's TwoArmTransport reads it: 14-wide actions,
/// its 41-value object-state, both arms' annotations and every signal of the task.
#[test]
fn two_arm_transport_delivers_from_the_bundled_sources() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("transport.hdf5");
    let run = mimicgen()
        .args(["generate", "--task", "two_arm_transport", "--num-demos", "1", "--guarantee", "--max-attempts", "20"])
        .args(["--seed", "1", "--workers", "2", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    let file = RobomimicDataset::open(&out).unwrap();
    assert_eq!(file.demo_names().len(), 1);
    let demo = file.demo(&file.demo_names()[0]).unwrap();
    assert_eq!(demo.dataset("actions").unwrap().array.shape[1], 14);
    assert_eq!(demo.group("obs").unwrap().dataset("object").unwrap().array.shape[1], 41, "TwoArmTransport's object-state");
    for signal in ["lid_grasp", "lid_off", "payload_lift", "at_handover", "trash_grasp", "trash_in_bin", "handle_grasp"] {
        let path = format!("datagen_info/subtask_term_signals/{signal}");
        let values = &demo.dataset_at(&path).unwrap_or_else(|| panic!("no {path}")).array;
        assert!(values.values.to_f64().unwrap().iter().any(|&v| v != 0.0), "{signal} never turned on in a delivery");
    }
    let env_args: serde_json::Value = serde_json::from_str(file.env_args().unwrap()).unwrap();
    assert_eq!(env_args["env_name"], "TwoArmTransport");
}
