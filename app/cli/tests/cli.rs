//! The `mimicgen` command line.
#![allow(clippy::unwrap_used)] // tests fail loudly by design

use std::process::Command;

use mimicgen_engine::TaskSpec;

fn mimicgen() -> Command {
    Command::new(env!("CARGO_BIN_EXE_mimicgen"))
}

#[test]
fn spec_convert_turns_a_mimicgen_config_into_equivalent_toml() {
    let json = repo_path("core/engine/tests/data/config_D0.json");
    let out = mimicgen().args(["spec", "convert"]).arg(&json).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let from_toml = TaskSpec::from_toml_str(&String::from_utf8(out.stdout).unwrap(), "stdout").unwrap();
    assert_eq!(from_toml, TaskSpec::load(&json).unwrap());
}

#[test]
fn spec_check_names_the_bad_field() {
    let dir = std::env::temp_dir().join(format!("mimicgen-flow-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let bad = dir.join("bad.toml");
    std::fs::write(&bad, "[[subtask]]\nobject_ref = \"cubeA\"\nselection = { strategy = \"nearest_neighbor_object\", nn_k = 0 }\n")
        .unwrap();
    let out = mimicgen().args(["spec", "check"]).arg(&bad).output().unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("bad.toml") && err.contains("subtask[0].selection.nn_k"), "{err}");
    std::fs::remove_dir_all(&dir).unwrap();
}

fn repo_path(relative: &str) -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../..").join(relative)
}

#[test]
fn help_teaches_with_examples() {
    let out = mimicgen().arg("--help").output().unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("Examples:") && text.contains("mimicgen spec check"), "{text}");
}
