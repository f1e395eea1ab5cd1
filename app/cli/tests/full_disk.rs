//! A run whose disk fills: it stops with an error naming the output, leaves no file that claims
//! to be complete, and resumes to the same dataset once there is room. Needs a small tmpfs, so
//! root (or CAP_SYS_ADMIN); where mounting is impossible the test says so on stderr and passes.
#![allow(clippy::indexing_slicing, reason = "test helpers: an index out of range fails the test, as it should")]
#![allow(clippy::unwrap_used)] // tests fail loudly by design

use std::path::{Path, PathBuf};
use std::process::Command;

fn mimicgen() -> Command {
    let mut command = Command::new(env!("CARGO_BIN_EXE_mimicgen"));
    command.env("HDF5_USE_FILE_LOCKING", "FALSE");
    command
}

/// A tmpfs mounted on a fresh directory, unmounted when dropped.
struct Tmpfs {
    dir: tempfile::TempDir,
}

impl Tmpfs {
    fn mount(size: &str) -> Result<Self, String> {
        let dir = tempfile::tempdir().map_err(|e| e.to_string())?;
        let out = Command::new("mount")
            .args(["-t", "tmpfs", "-o", &format!("size={size}"), "tmpfs"])
            .arg(dir.path())
            .output()
            .map_err(|e| format!("running mount: {e}"))?;
        if !out.status.success() {
            return Err(String::from_utf8_lossy(&out.stderr).trim().to_owned());
        }
        Ok(Self { dir })
    }

    fn resize(&self, size: &str) {
        let out = Command::new("mount").args(["-o", &format!("remount,size={size}")]).arg(self.dir.path()).output().unwrap();
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    }

    fn path(&self) -> &Path {
        self.dir.path()
    }
}

impl Drop for Tmpfs {
    fn drop(&mut self) {
        let _ = Command::new("umount").arg(self.dir.path()).status();
    }
}

fn generate(out: &Path, extra: &[&str]) -> std::process::Output {
    mimicgen().args(["generate", "--num-demos", "12", "--workers", "1", "--seed", "3", "--out"]).arg(out).args(extra).output().unwrap()
}

fn info(file: &Path) -> serde_json::Value {
    let out = mimicgen().args(["info", "--json"]).arg(file).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let mut json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    // Where the file is, not what it holds.
    json.as_object_mut().unwrap().remove("file");
    json["report"].as_object_mut().unwrap().remove("file");
    json
}

#[test]
fn a_full_disk_stops_the_run_and_resume_finishes_it() {
    // 1 MiB holds three or four Stack demos of the twelve.
    let disk = match Tmpfs::mount("1m") {
        Ok(disk) => disk,
        Err(why) => {
            eprintln!(
                "\n*** SKIPPED a_full_disk_stops_the_run_and_resume_finishes_it: cannot mount a tmpfs ({why}); run as root to test a full disk ***\n"
            );
            return;
        }
    };
    let out = disk.path().join("stack.hdf5");
    let full = generate(&out, &[]);
    let err = String::from_utf8_lossy(&full.stderr);
    assert_eq!(full.status.code(), Some(1), "a full disk is the machine's failure, worth a retry: {err}");
    assert!(err.contains(&out.display().to_string()), "the error names the output: {err}");
    assert!(err.contains("No space left on device"), "and why: {err}");
    assert!(!out.exists(), "no file claims to be the finished dataset");
    assert!(!out.with_extension("json").exists(), "no report claims the run finished");
    assert!(PathBuf::from(format!("{}.partial", out.display())).exists(), "the partial file stays, to resume");

    disk.resize("64m");
    let resumed = generate(&out, &["--resume"]);
    assert!(resumed.status.success(), "{}", String::from_utf8_lossy(&resumed.stderr));

    let elsewhere = tempfile::tempdir().unwrap();
    let direct = elsewhere.path().join("stack.hdf5");
    let run = generate(&direct, &[]);
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    assert_eq!(info(&out), info(&direct), "the resumed dataset is the one an uninterrupted run writes");
}
