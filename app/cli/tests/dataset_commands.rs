//! `mimicgen info`, `mimicgen export` and `mimicgen bench-io` on the committed fixtures.
#![allow(clippy::unwrap_used, clippy::float_cmp)] // tests fail loudly by design

use std::path::PathBuf;
use std::process::{Command, Output};

fn mimicgen(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_mimicgen")).args(args).output().unwrap()
}

fn fixture(name: &str) -> String {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../core/io/tests/data").join(name).display().to_string()
}

fn stdout_ok(out: &Output) -> String {
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8(out.stdout.clone()).unwrap()
}

#[test]
fn info_summarises_the_source_fixture() {
    let text = stdout_ok(&mimicgen(&["info", &fixture("source_D0_prepared.hdf5")]));
    for expected in [
        "demos 10, samples 912 (data/total says 912)",
        "env: Stack_D0, controller OSC_POSE",
        "actions: 7 dims",
        "objects: cubeA, cubeB",
        "signal grasp: first 0->1 at step min 28, mean 47.2, max 104 (10 of 10 demos)",
        "filter keys: (none)",
        "MimicGen source: yes",
    ] {
        assert!(text.contains(expected), "missing `{expected}` in:\n{text}");
    }
}

#[test]
fn info_json_has_obs_shapes_and_action_bounds() {
    let json: serde_json::Value =
        serde_json::from_str(&stdout_ok(&mimicgen(&["info", "--json", &fixture("generated_D0_first3.hdf5")]))).unwrap();
    assert_eq!(json["num_demos"], 3);
    assert_eq!(json["obs"]["object"], serde_json::json!([23]));
    assert_eq!(json["obs"]["robot0_joint_pos"], serde_json::json!([7]));
    assert_eq!(json["action_min"].as_array().unwrap().len(), 7);
    assert!(json["action_max"][6].as_f64().unwrap() <= 1.0);
    assert_eq!(json["signals"]["grasp"]["demos"], 3);
    assert_eq!(json["lengths"]["count"], 3);
}

#[test]
fn info_on_a_missing_file_fails_with_its_name() {
    let out = mimicgen(&["info", "no/such/file.hdf5"]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("no/such/file.hdf5"));
}

#[test]
fn export_writes_an_mcap_with_every_stream() {
    let dir = tempfile::tempdir().unwrap();
    let mcap = dir.path().join("out.mcap");
    let text = stdout_ok(&mimicgen(&["export", &fixture("generated_D0_first3.hdf5"), "--mcap", mcap.to_str().unwrap()]));
    assert!(text.contains("3 demos"), "{text}");
    for topic in ["/eef_pose", "/target_pose", "/objects/cubeA", "/actions", "/gripper", "/subtask", "/source_demo", "/success"] {
        assert!(text.contains(topic), "missing {topic} in:\n{text}");
    }
    assert!(std::fs::metadata(&mcap).unwrap().len() > 10_000);
}

#[test]
fn bench_io_runs_small() {
    let dir = tempfile::tempdir().unwrap();
    let text = stdout_ok(&mimicgen(&["bench-io", "--demos", "4", "--steps", "20", "--dir", dir.path().to_str().unwrap()]));
    assert!(text.contains("4 demos x 20 steps") && text.contains("peak RSS"), "{text}");
}
