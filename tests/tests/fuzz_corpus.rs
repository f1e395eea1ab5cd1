//! The fuzz targets' saved corpus and crash reproducers (`fuzz/corpus/<target>/`,
//! `fuzz/artifacts/<target>/`), replayed through the same harnesses `cargo fuzz` runs
//! (`mimicgen_tests::fuzz`): no input may panic a reader or be refused without naming its file.
//! Runs in CI with no fuzzing tool; `scripts/fuzz.sh` grows the corpus.
#![allow(clippy::unwrap_used)] // tests fail loudly by design

use std::path::PathBuf;

use mimicgen_tests::{fuzz, repo_path};

/// Every saved input of `target`, corpus and reproducers.
fn inputs(target: &str) -> Vec<PathBuf> {
    let mut files = Vec::new();
    for dir in ["fuzz/corpus", "fuzz/artifacts"] {
        let Ok(entries) = std::fs::read_dir(repo_path(&format!("{dir}/{target}"))) else { continue };
        files.extend(entries.filter_map(Result::ok).map(|e| e.path()).filter(|p| p.is_file()));
    }
    files.sort();
    files
}

/// Runs `harness` on every input of `target`; fails naming each input that panicked.
fn replay(target: &str, mut harness: impl FnMut(&[u8])) {
    let files = inputs(target);
    assert!(files.len() >= 5 || target == "spec_json", "{target}: only {} saved inputs", files.len());
    let failed: Vec<String> = files
        .iter()
        .filter_map(|path| {
            let data = std::fs::read(path).unwrap();
            // An input that aborts the process (not a panic) is found by the last name printed.
            if std::env::var_os("MIMICGEN_FUZZ_VERBOSE").is_some() {
                eprintln!("replaying {}", path.display());
            }
            let outcome = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| harness(&data)));
            outcome.err().map(|_| path.display().to_string())
        })
        .collect();
    assert!(failed.is_empty(), "{target}: {} of {} inputs panicked: {failed:?}", failed.len(), files.len());
}

#[test]
fn the_spec_toml_corpus_is_read_or_refused_by_name() {
    replay("spec_toml", fuzz::spec_toml);
}

#[test]
fn the_mimicgen_json_corpus_is_read_or_refused_by_name() {
    replay("spec_json", fuzz::spec_json);
}

#[test]
fn the_task_file_corpus_is_read_or_refused_by_name() {
    replay("task_file", fuzz::task_file);
}

#[test]
fn the_dataset_corpus_is_read_or_refused_by_name() {
    let seed = fuzz::dataset_seed();
    let dir = tempfile::tempdir().unwrap();
    let scratch = dir.path().join("mutated.hdf5");
    replay("dataset", |data| fuzz::dataset(&seed, data, &scratch));
}

/// Set in the child process that replays one `dataset_bytes` input.
const ONE_INPUT: &str = "MIMICGEN_FUZZ_ONE_INPUT";

/// Byte edits reach libhdf5's C parser, which can crash on a damaged header in ways that depend
/// on the heap's layout (`fuzz/known_crashes/README.md`): each input is replayed in a child
/// process of this test binary. A panic or a refusal without the file name (the child's test
/// fails) fails this test; a death by signal, or a child stopped after 2 minutes, is listed as
/// below our code.
#[test]
fn the_dataset_bytes_corpus_is_read_or_refused_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let scratch = dir.path().join("mutated.hdf5");
    if let Some(input) = std::env::var_os(ONE_INPUT) {
        let seed = fuzz::dataset_seed_bytes(&scratch);
        return fuzz::dataset_bytes(&seed, &std::fs::read(input).unwrap(), &scratch);
    }
    let files = inputs("dataset_bytes");
    assert!(files.len() >= 5, "dataset_bytes: only {} saved inputs", files.len());
    let (mut failed, mut killed) = (Vec::new(), Vec::new());
    for path in &files {
        let mut child = std::process::Command::new(std::env::current_exe().unwrap())
            .args(["--exact", "the_dataset_bytes_corpus_is_read_or_refused_by_name", "--test-threads=1", "--nocapture"])
            .env(ONE_INPUT, path)
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        // libhdf5 can also loop forever on a damaged header (one such input is in known_crashes).
        let started = std::time::Instant::now();
        while child.try_wait().unwrap().is_none() && started.elapsed() < std::time::Duration::from_secs(120) {
            std::thread::sleep(std::time::Duration::from_millis(20));
        }
        if child.try_wait().unwrap().is_none() {
            child.kill().unwrap();
        }
        let child = child.wait_with_output().unwrap();
        match child.status.code() {
            Some(0) => {}
            Some(_) => {
                let stderr = String::from_utf8_lossy(&child.stderr);
                let panic = stderr.lines().find(|l| l.contains("panicked") || l.contains("refused")).unwrap_or_default().to_owned();
                failed.push(format!("{}: {panic}", path.display()));
            }
            None => killed.push(path.display().to_string()),
        }
    }
    if !killed.is_empty() {
        eprintln!("dataset_bytes: {} inputs crashed or hung libhdf5 or the hdf5 crate (below our code): {killed:?}", killed.len());
    }
    assert!(failed.is_empty(), "dataset_bytes: {} of {} inputs failed: {failed:?}", failed.len(), files.len());
}

/// The harnesses catch what they are for: a refusal that does not name the file fails.
#[test]
#[should_panic(expected = "without naming it")]
fn a_refusal_without_the_file_name_fails_the_harness() {
    fuzz::check_names("a reader", "expected a table", fuzz::ORIGIN_TOML);
}

/// A damaged header that claims more elements than the file stores is refused, naming the file
/// and the dataset, before the reader allocates them (this input once asked for 44 TB and aborted).
#[test]
fn a_dataset_claiming_more_than_its_file_stores_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let scratch = dir.path().join("damaged.hdf5");
    let seed = fuzz::dataset_seed_bytes(&scratch);
    let input = std::fs::read(repo_path("fuzz/artifacts/dataset_bytes/crash-037a2a2f7cc88e34ca658ec711499ff6163c3f88")).unwrap();
    fuzz::dataset_bytes(&seed, &input, &scratch);
    let err = mimicgen_io::RobomimicDataset::open(&scratch).unwrap_err().to_string();
    assert!(err.contains("damaged.hdf5") && err.contains("the file is damaged") && err.contains("claims shape"), "{err}");
}

#[test]
fn the_client_message_corpus_is_confined_refused_by_name_or_answered() {
    let served = fuzz::ServedRoot::new();
    let mut seen = std::collections::BTreeSet::new();
    replay("client_message", |data| {
        seen.insert(fuzz::client_message(data, &served));
    });
    // The corpus reaches every outcome (a corpus of unreadable inputs would test nothing).
    assert_eq!(seen.len(), 4, "outcomes reached: {seen:?}");
}
