//! `mimicgen generate --resume`: a run killed at random points and resumed each time ends with the
//! same dataset as a run never interrupted.
#![allow(clippy::unwrap_used)] // tests fail loudly by design

use std::path::Path;
use std::process::{Command, Stdio};

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

/// A fixed pseudo-random sequence of how many attempts each session makes before it is killed
/// (1 to 4; splitmix64), so the test is repeatable.
fn attempts_before_kill(count: usize, seed: u64) -> Vec<usize> {
    let mut state = seed;
    (0..count)
        .map(|_| {
            state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
            let mut z = state;
            z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
            1 + usize::try_from((z ^ (z >> 31)) % 4).unwrap()
        })
        .collect()
}

/// Reads the child's progress lines (`progress N/TOTAL: ...`, what `generate` logs when stderr is
/// not a terminal) until `n` attempts beyond the first one it reported have been decided: waits
/// on the run's own events, not on time. False if the child ended first; `said` keeps what it
/// read.
fn wait_for_attempts(stderr: &mut impl std::io::BufRead, n: usize, said: &mut String) -> bool {
    let mut first: Option<usize> = None;
    let mut line = String::new();
    loop {
        line.clear();
        if stderr.read_line(&mut line).unwrap_or(0) == 0 {
            return false;
        }
        said.push_str(&line);
        let Some(done) = line.strip_prefix("progress ").and_then(|l| l.split('/').next()).and_then(|d| d.parse::<usize>().ok()) else {
            continue;
        };
        let first = *first.get_or_insert(done);
        if done >= first + n {
            return true;
        }
    }
}

/// Spawns `command` (a `generate`) and kills it (SIGKILL: no chance to clean up) once two
/// attempts beyond its first are decided, leaving its `.partial` behind.
fn killed_after_two_attempts(command: &mut Command) {
    let mut child = command.spawn().unwrap();
    let mut stderr = std::io::BufReader::new(child.stderr.take().unwrap());
    let mut said = String::new();
    assert!(
        wait_for_attempts(&mut stderr, 2, &mut said) && child.try_wait().unwrap().is_none(),
        "the run ended before it was killed: {said}"
    );
    child.kill().unwrap();
    child.wait().unwrap();
}

/// `generate --resume` onto `out` with other arguments than those of the run there.
fn resume_with_other_arguments(out: &Path) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_mimicgen"))
        .args(["generate", "--num-demos", "14", "--seed", "6", "--resume", "--out"])
        .arg(out)
        .env("HDF5_USE_FILE_LOCKING", "FALSE")
        .output()
        .unwrap()
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
    // Each session is killed (SIGKILL: no chance to clean up) once it has logged a few attempts
    // beyond its first, so every session leaves a partial file with attempts in it.
    for attempts in attempts_before_kill(30, 7) {
        if pieces.exists() {
            break;
        }
        let resume: &[&str] = if started_fresh && partial.exists() { &["--resume"] } else { &[] };
        let mut child = generate(&pieces, resume).spawn().unwrap();
        started_fresh = true;
        let mut stderr = std::io::BufReader::new(child.stderr.take().unwrap());
        let mut said = String::new();
        if wait_for_attempts(&mut stderr, attempts, &mut said) && child.try_wait().unwrap().is_none() {
            child.kill().unwrap();
            child.wait().unwrap();
            kills += 1;
        } else {
            let status = child.wait().unwrap();
            std::io::Read::read_to_string(&mut stderr, &mut said).unwrap();
            assert!(status.success(), "session {} ({kills} killed before it), {resume:?}: {said}", kills + 1);
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
    // The quality report covers every demo, those of the killed sessions from the attempt log.
    let quality = |stem: &str| {
        let text = std::fs::read_to_string(dir.path().join(format!("{stem}_quality.json"))).unwrap();
        let mut q: serde_json::Value = serde_json::from_str(&text).unwrap();
        q["dataset"] = serde_json::Value::Null;
        q
    };
    let demos = RobomimicDataset::open(&whole).unwrap().demo_names().len();
    assert_eq!(quality("whole")["quality"]["attempts"].as_u64(), Some(u64::try_from(demos).unwrap()));
    assert_eq!(quality("whole"), quality("pieces"));
}

#[test]
fn resuming_with_other_arguments_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("r.hdf5");
    killed_after_two_attempts(&mut generate(&out, &[]));
    assert!(mimicgen_io::DatasetWriter::partial_path(&out).exists());
    let other = resume_with_other_arguments(&out);
    assert!(!other.status.success());
    let err = String::from_utf8_lossy(&other.stderr);
    assert!(err.contains("spec") && err.contains("start over"), "{err}");
    // Without --resume or --overwrite the interrupted run is not clobbered either.
    let fresh = generate(&out, &[]).output().unwrap();
    let said = String::from_utf8_lossy(&fresh.stderr);
    assert_eq!(fresh.status.code(), Some(2), "{said}");
    assert!(said.contains("pass --resume to continue that run, or pass --overwrite to start over"), "{said}");
}

#[test]
fn an_object_transfer_run_killed_and_resumed_draws_the_same_mugs() {
    let run = |out: &Path, resume: bool| {
        let mut c = Command::new(env!("CARGO_BIN_EXE_mimicgen"));
        c.args([
            "generate",
            "--task",
            "mug_cleanup",
            "--variant",
            "O2",
            "--num-demos",
            "8",
            "--seed",
            "5",
            "--workers",
            "2",
            "--keep-failed",
        ])
        .arg("--out")
        .arg(out)
        .env("HDF5_USE_FILE_LOCKING", "FALSE")
        .stdout(Stdio::null())
        .stderr(Stdio::piped());
        if resume {
            c.arg("--resume");
        }
        c
    };
    let dir = tempfile::tempdir().unwrap();
    let whole = dir.path().join("whole.hdf5");
    let out = run(&whole, false).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    // Killed (SIGKILL) once two attempts beyond its first are decided, then resumed.
    let pieces = dir.path().join("pieces.hdf5");
    killed_after_two_attempts(&mut run(&pieces, false));
    let out = run(&pieces, true).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    for (a, b) in [(&whole, &pieces), (&dir.path().join("whole_failed.hdf5"), &dir.path().join("pieces_failed.hdf5"))] {
        let (a, b) = (RobomimicDataset::open(a).unwrap(), RobomimicDataset::open(b).unwrap());
        assert_eq!(a.data(), b.data(), "demos differ after a kill");
        for name in a.demo_names() {
            assert!(a.demo(name).unwrap().attrs.contains_key(mimicgen_io::INSTANCE_ATTR), "{name} names no mug");
        }
    }
    // The report counts every attempt per mug, those before the kill too.
    let per_mug = |p: &Path| -> serde_json::Value {
        let report: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap();
        report["per_object_instance"].clone()
    };
    let whole_mugs = per_mug(&dir.path().join("whole.json"));
    let attempts: u64 = whole_mugs.as_array().unwrap().iter().map(|m| m["attempts"].as_u64().unwrap()).sum();
    assert_eq!(attempts, 8, "{whole_mugs}");
    assert_eq!(per_mug(&dir.path().join("pieces.json")), whole_mugs);
}

#[test]
fn a_killed_run_resumes_from_the_app() {
    use mimicgen_gui::protocol::{Reply, Request, RunUpdate};
    let dir = tempfile::tempdir().unwrap();
    let source = mimicgen_pipeline::bundled::source_demos("stack").unwrap();
    let cli = |out: &Path| {
        let mut c = Command::new(env!("CARGO_BIN_EXE_mimicgen"));
        c.args(["generate", "--num-demos", "12", "--seed", "5", "--workers", "2", "--keep-failed", "--source"])
            .arg(&source)
            .arg("--out")
            .arg(out)
            .env("HDF5_USE_FILE_LOCKING", "FALSE")
            .stdout(Stdio::null())
            .stderr(Stdio::piped());
        c
    };
    let whole = dir.path().join("whole.hdf5");
    let out = cli(&whole).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    // A run killed part-way (as a killed app or server would leave it).
    let pieces = dir.path().join("pieces.hdf5");
    killed_after_two_attempts(&mut cli(&pieces));
    assert!(mimicgen_io::DatasetWriter::partial_path(&pieces).exists());
    // The app's run form, "continue an interrupted run" ticked, through the app's backend.
    let form = mimicgen_gui::model::RunForm {
        attempts: 12,
        seed: 5,
        workers: 2,
        keep_failed: true,
        out: pieces.display().to_string(),
        resume: true,
        overwrite: true,
        ..Default::default()
    };
    let config = form.config(&source, None);
    assert!(config.resume && !config.overwrite, "resuming never replaces");
    let (tx, updates) = std::sync::mpsc::channel();
    let tx = std::sync::Mutex::new(tx);
    let notify: mimicgen_gui::backend::Notify = std::sync::Arc::new(move |reply| {
        let _ = tx.lock().unwrap().send(reply);
    });
    let mut worker = mimicgen_gui::backend::Worker::new(notify, None);
    assert_eq!(worker.handle(Request::Run(Box::new(config))), Reply::RunAccepted);
    let report = loop {
        match updates.recv().unwrap() {
            Reply::Run(RunUpdate::Finished(report)) => break report,
            Reply::Run(RunUpdate::Failed(e)) => panic!("{e}"),
            _ => {}
        }
    };
    assert!(report.resumed_from >= 2, "resumed at attempt {}", report.resumed_from);
    let (a, b) = (RobomimicDataset::open(&whole).unwrap(), RobomimicDataset::open(&pieces).unwrap());
    assert_eq!(a.demo_names(), b.demo_names());
    assert_eq!(a.data(), b.data(), "the resumed run's demos differ from the uninterrupted run's");
}

#[test]
fn a_run_killed_after_its_rename_gets_its_report_on_resume() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("done.hdf5");
    let first = generate(&out, &[]).output().unwrap();
    assert!(first.status.success(), "{}", String::from_utf8_lossy(&first.stderr));
    let report_path = dir.path().join("done.json");
    let read = |p: &Path| -> serde_json::Value { serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap() };
    let original = read(&report_path);
    // Killed between the dataset's rename and the report: the dataset is whole, the report absent.
    std::fs::remove_file(&report_path).unwrap();
    let again = generate(&out, &["--resume"]).output().unwrap();
    assert!(again.status.success(), "{}", String::from_utf8_lossy(&again.stderr));
    let recovered = read(&report_path);
    for field in
        ["task", "variant", "seed", "attempts", "successes", "generation_rate", "per_source_demo", "failures", "output", "failed_output"]
    {
        assert_eq!(recovered[field], original[field], "{field}");
    }
    assert_eq!(recovered["resumed_from"], original["attempts"], "a session with nothing left to do");
    assert_eq!(recovered["cancelled"], false);
    // Another run's arguments are refused, naming what differs.
    std::fs::remove_file(&report_path).unwrap();
    let other = resume_with_other_arguments(&out);
    assert!(!other.status.success());
    let err = String::from_utf8_lossy(&other.stderr);
    assert!(err.contains("different dataset"), "{err}");
    assert!(!report_path.exists());
}
