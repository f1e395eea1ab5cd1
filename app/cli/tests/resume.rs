//! `mimicgen generate --resume`: a run killed at random points and resumed each time ends with the
//! same dataset as a run never interrupted.
#![allow(clippy::unwrap_used)] // tests fail loudly by design

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use mimicgen_io::RobomimicDataset;

fn generate(out: &Path, extra: &[&str]) -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_mimicgen"));
    c.args(["generate", "--num-demos", "30", "--seed", "5", "--workers", "2", "--keep-failed", "--valid-fraction", "0.25", "--out"])
        .arg(out)
        .args(extra)
        .env("HDF5_USE_FILE_LOCKING", "FALSE")
        .stdout(Stdio::null())
        .stderr(Stdio::piped());
    c
}

/// A fixed pseudo-random sequence of kill delays (splitmix64), so the test is repeatable.
fn delays_ms(count: usize, seed: u64) -> Vec<u64> {
    let mut state = seed;
    (0..count)
        .map(|_| {
            state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
            let mut z = state;
            z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
            150 + (z ^ (z >> 31)) % 500
        })
        .collect()
}

#[test]
fn a_run_killed_five_times_and_resumed_equals_an_uninterrupted_run() {
    let dir = tempfile::tempdir().unwrap();
    let whole = dir.path().join("whole.hdf5");
    let out = generate(&whole, &[]).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));

    let pieces = dir.path().join("pieces.hdf5");
    let partial = mimicgen_io::DatasetWriter::partial_path(&pieces);
    let mut kills = 0;
    let mut started_fresh = false;
    // Each session gets its start-up (reading inputs, compiling the scene: ~0.4 s in a test build)
    // plus a few attempts' time before it is killed.
    for delay in delays_ms(20, 7) {
        if pieces.exists() {
            break;
        }
        let resume: &[&str] = if started_fresh && partial.exists() { &["--resume"] } else { &[] };
        let mut child = generate(&pieces, resume).spawn().unwrap();
        started_fresh = true;
        // The kill lands `delay` after the session has started writing (start-up takes longer on
        // a loaded machine), so every session leaves a partial file with its attempts in it.
        let started = Instant::now();
        while !partial.exists() && started.elapsed() < Duration::from_secs(60) && child.try_wait().unwrap().is_none() {
            std::thread::sleep(Duration::from_millis(5));
        }
        let deadline = Instant::now() + Duration::from_millis(delay);
        while Instant::now() < deadline && child.try_wait().unwrap().is_none() {
            std::thread::sleep(Duration::from_millis(10));
        }
        if child.try_wait().unwrap().is_none() {
            child.kill().unwrap(); // SIGKILL: no chance to clean up
            child.wait().unwrap();
            kills += 1;
        } else {
            let status = child.wait_with_output().unwrap();
            assert!(status.status.success(), "{}", String::from_utf8_lossy(&status.stderr));
        }
    }
    if !pieces.exists() {
        let out = generate(&pieces, &["--resume"]).output().unwrap();
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    }
    assert!(kills >= 5, "only {kills} kills landed before the run finished");
    for (a, b) in [(&whole, &pieces), (&dir.path().join("whole_failed.hdf5"), &dir.path().join("pieces_failed.hdf5"))] {
        let a = RobomimicDataset::open(a).unwrap();
        let b = RobomimicDataset::open(b).unwrap();
        assert_eq!(a.demo_names(), b.demo_names());
        assert_eq!(a.data(), b.data(), "demos differ after {kills} kills");
        assert_eq!(a.masks().unwrap(), b.masks().unwrap());
    }
}

#[test]
fn resuming_with_other_arguments_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("r.hdf5");
    let mut child = generate(&out, &[]).spawn().unwrap();
    let partial = mimicgen_io::DatasetWriter::partial_path(&out);
    let deadline = Instant::now() + Duration::from_secs(60);
    while !partial.exists() && Instant::now() < deadline {
        std::thread::sleep(Duration::from_millis(20));
    }
    std::thread::sleep(Duration::from_millis(300));
    child.kill().unwrap();
    child.wait().unwrap();
    assert!(partial.exists());
    let other = Command::new(env!("CARGO_BIN_EXE_mimicgen"))
        .args(["generate", "--num-demos", "14", "--seed", "6", "--resume", "--out"])
        .arg(&out)
        .env("HDF5_USE_FILE_LOCKING", "FALSE")
        .output()
        .unwrap();
    assert!(!other.status.success());
    let err = String::from_utf8_lossy(&other.stderr);
    assert!(err.contains("spec") && err.contains("--overwrite"), "{err}");
    // Without --resume or --overwrite the interrupted run is not clobbered either.
    let fresh = generate(&out, &[]).output().unwrap();
    assert!(!fresh.status.success() && String::from_utf8_lossy(&fresh.stderr).contains("--resume"));
}
