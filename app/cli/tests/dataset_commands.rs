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

#[test]
fn export_lerobot_labels_subtasks_writes_a_card_and_pushes_to_a_local_folder() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("lerobot");
    let hub = dir.path().join("hub/stack_d0");
    let text = stdout_ok(&mimicgen(&[
        "export",
        &fixture("generated_D0_first3.hdf5"),
        "--lerobot",
        out.to_str().unwrap(),
        "--push",
        &format!("file://{}", hub.display()),
    ]));
    // The reference's Stack D0 file: the bundled Stack spec's two subtasks, the first ending on grasp.
    assert!(text.contains(r#"subtask_index 0: "cubeA until grasp""#), "{text}");
    assert!(text.contains(r#"subtask_index 1: "cubeB until the task succeeds""#), "{text}");
    let card = std::fs::read_to_string(out.join("README.md")).unwrap();
    assert!(card.starts_with("---\ntask_categories:\n- robotics") && card.contains("stack D0: 3 demos"), "{card}");
    assert!(card.contains("| 0 | cubeA until grasp | cubeA | nearest_neighbor_object | 0.05 | 5 |"), "{card}");
    for file in ["README.md", "meta/info.json", "meta/subtasks.parquet", "meta/tasks.parquet", "data/chunk-000/file-000.parquet"] {
        assert_eq!(std::fs::read(out.join(file)).unwrap(), std::fs::read(hub.join(file)).unwrap(), "{file} pushed");
    }
    // A second push into the same folder is refused, naming it; a repository must be user/name.
    let again = mimicgen(&[
        "export",
        &fixture("generated_D0_first3.hdf5"),
        "--lerobot",
        dir.path().join("again").to_str().unwrap(),
        "--push",
        &format!("file://{}", hub.display()),
    ]);
    assert!(!again.status.success() && String::from_utf8_lossy(&again.stderr).contains("is not empty"));
    let bad = mimicgen(&[
        "export",
        &fixture("generated_D0_first3.hdf5"),
        "--lerobot",
        dir.path().join("bad").to_str().unwrap(),
        "--push",
        "just-a-name",
    ]);
    assert!(!bad.status.success() && String::from_utf8_lossy(&bad.stderr).contains("user/name"));
    assert!(!dir.path().join("again").exists() && !dir.path().join("bad").exists(), "a refused push exports nothing");
}
