//! Crash safety: a writer killed with SIGKILL mid-demo leaves a file whose complete demos can be
//! recovered.
//!
//! A test binary of its own: HDF5 opens files without close-on-exec and locks them, so a child
//! spawned while other tests hold HDF5 files would inherit their locks and make those tests flaky.
#![allow(clippy::unwrap_used)] // tests fail loudly by design

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::process::Command;

use mimicgen_engine::spec::SourceSelection;
use mimicgen_engine::{Generator, kinematic};
use mimicgen_io::{DatasetWriter, IoError, ReadOptions, RobomimicDataset, WriterOptions};

/// Child half of `a_killed_writer_leaves_a_recoverable_file`: writes demos until killed.
#[test]
#[ignore = "run by a_killed_writer_leaves_a_recoverable_file as a child process"]
fn crash_child_writer() {
    let Some(out) = std::env::var_os("MIMICGEN_CRASH_CHILD_OUT") else { return };
    let generator = Generator::new(kinematic::pick_place_spec(1, 3), kinematic::scripted_dataset(2, 1).unwrap()).unwrap();
    let mut env = kinematic::PickPlace::new(0.1);
    let attempt = generator.attempt(&mut env, 0).unwrap();
    let n = attempt.trajectory.len();
    let obs = BTreeMap::from([("object".to_owned(), (vec![64], vec![0.25; n * 64]))]);
    let mut writer = DatasetWriter::create(PathBuf::from(out), WriterOptions::default()).unwrap();
    for i in 0.. {
        writer.append_attempt(&attempt, obs.clone(), None).unwrap();
        println!("appended {i}");
    }
}

#[test]
fn a_killed_writer_leaves_a_recoverable_file() {
    use std::io::BufRead as _;
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("killed.hdf5");
    for kill_after in [3, 17, 40] {
        let _ = std::fs::remove_file(DatasetWriter::partial_path(&out));
        let mut child = Command::new(std::env::current_exe().unwrap())
            .args(["--exact", "crash_child_writer", "--ignored", "--nocapture", "--test-threads=1"])
            .env("MIMICGEN_CRASH_CHILD_OUT", &out)
            .stdout(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        let stdout = std::io::BufReader::new(child.stdout.take().unwrap());
        for line in stdout.lines() {
            if line.unwrap() == format!("appended {kill_after}") {
                break;
            }
        }
        child.kill().unwrap(); // SIGKILL, mid-way through a later demo
        child.wait().unwrap();
        let partial = DatasetWriter::partial_path(&out);
        let err = RobomimicDataset::open(&partial).unwrap_err();
        assert!(matches!(err, IoError::Incomplete { .. }), "{err}");
        let recovered = RobomimicDataset::open_with(&partial, ReadOptions { recover: true }).unwrap();
        assert!(recovered.demo_names().len() > kill_after, "{} demos after kill at {kill_after}", recovered.demo_names().len());
        recovered.to_source_dataset(&SourceSelection::default()).unwrap();
    }
}
