//! Files a user chose, read first in a child process: a damaged HDF5 header can crash libhdf5
//! (a C memory error nothing in-process can catch; `fuzz/known_crashes/README.md`), and the app or
//! server reading it would die with every tab and run in it. The child (`mimicgen vet FILE`, which
//! calls [`mimicgen_io::tree::vet`]) walks the file's structure and attributes; when it dies, the
//! request is refused naming the file, and the process that asked goes on.

use std::collections::BTreeMap;
use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::{Duration, Instant, SystemTime};

use mimicgen_ui::protocol::Request;

/// How long the child may take over one file's structure before the file is called damaged (one
/// known damaged header sends libhdf5 into an endless loop). Reading a healthy file's structure,
/// even of gigabytes of images, takes well under a second.
const DEADLINE: Duration = Duration::from_secs(120);

/// A file's verdict, per file, size and modification time.
type Verdicts = BTreeMap<(PathBuf, u64, Option<SystemTime>), Result<(), String>>;

/// Runs the vetting child and remembers its verdicts; clones share them (the server's tabs vet
/// a file once between them).
#[derive(Debug, Clone)]
pub struct Vetter {
    /// The program and its first arguments; the file is the last argument.
    command: Vec<OsString>,
    verdicts: Arc<Mutex<Verdicts>>,
}

impl Vetter {
    /// A vetter that runs `command` (a program and its first arguments, e.g. `mimicgen vet`) with
    /// the file appended. `None` when `command` is empty.
    #[must_use]
    pub fn new(command: Vec<OsString>) -> Option<Self> {
        (!command.is_empty()).then(|| Self { command, verdicts: Arc::default() })
    }

    /// `mimicgen vet`, the running binary's own subcommand (the `mimicgen` binary only).
    #[must_use]
    pub fn this_binary() -> Option<Self> {
        let exe = std::env::current_exe().ok()?;
        Self::new(vec![exe.into_os_string(), "vet".into()])
    }

    /// Checks every HDF5 file `request` reads.
    ///
    /// # Errors
    /// A message naming the file that crashed (or hung) the child.
    pub fn check_request(&self, request: &Request) -> Result<(), String> {
        files_read(request).into_iter().try_for_each(|path| self.check(path))
    }

    /// Checks `path` (once per version of the file). Paths that are not files pass: the reader
    /// then says what is wrong.
    ///
    /// # Errors
    /// A message naming the file when the child died or did not finish.
    pub fn check(&self, path: &Path) -> Result<(), String> {
        let Ok(meta) = std::fs::metadata(path) else { return Ok(()) };
        if !meta.is_file() {
            return Ok(());
        }
        let key = (path.to_path_buf(), meta.len(), meta.modified().ok());
        let verdicts = || self.verdicts.lock().unwrap_or_else(PoisonError::into_inner);
        if let Some(verdict) = verdicts().get(&key) {
            return verdict.clone();
        }
        // Not under the lock: other files are vetted meanwhile.
        let verdict = self.run(path);
        verdicts().insert(key, verdict.clone());
        verdict
    }

    fn run(&self, path: &Path) -> Result<(), String> {
        let (program, args) = self.command.split_first().ok_or("no vetting command")?;
        let damaged = |what: &str| format!("{}: damaged ({what}); nothing else was affected", path.display());
        let mut child = Command::new(program)
            .args(args)
            .arg(path)
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .map_err(|e| format!("{}: cannot check it in a child process ({}: {e})", path.display(), Path::new(program).display()))?;
        let started = Instant::now();
        let status = loop {
            match child.try_wait() {
                Ok(Some(status)) => break status,
                Ok(None) if started.elapsed() > DEADLINE => {
                    let _ = child.kill();
                    let _ = child.wait();
                    return Err(damaged(&format!("the HDF5 library did not finish reading its structure in {} s", DEADLINE.as_secs())));
                }
                Ok(None) => std::thread::sleep(Duration::from_millis(5)),
                Err(e) => return Err(format!("{}: cannot check it in a child process ({e})", path.display())),
            }
        };
        // 0: read; 1: refused with an error (the reader here says the same, naming the field).
        match status.code() {
            Some(0 | 1) => Ok(()),
            Some(code) => Err(damaged(&format!("the HDF5 library crashed reading its attributes: exit {code}"))),
            None => Err(damaged(&format!("the HDF5 library crashed reading its attributes: {}", signal_name(&status)))),
        }
    }
}

#[cfg(unix)]
fn signal_name(status: &std::process::ExitStatus) -> String {
    use std::os::unix::process::ExitStatusExt as _;
    match status.signal() {
        Some(6) => "abort".to_owned(),
        Some(11) => "segmentation fault".to_owned(),
        Some(s) => format!("signal {s}"),
        None => status.to_string(),
    }
}

#[cfg(not(unix))]
fn signal_name(status: &std::process::ExitStatus) -> String {
    status.to_string()
}

/// The files `request` reads as HDF5 (not the ones it writes).
#[must_use]
pub fn files_read(request: &Request) -> Vec<&Path> {
    match request {
        Request::Open { path } | Request::OpenCompare { path } | Request::OpenRun { path } => vec![path],
        Request::Save { source, .. } | Request::SaveArms { source, .. } => vec![source],
        Request::Preview(r) => vec![&r.source],
        Request::SideBySide(pair) => pair.iter().map(|r| r.source.as_path()).collect(),
        Request::Run(config) => config.source.iter().map(PathBuf::as_path).collect(),
        // The doctor reads a report (JSON) and the source file the run read.
        Request::ListDir { .. }
        | Request::Open3d { .. }
        | Request::ShowDemo { .. }
        | Request::CancelRun
        | Request::Doctor { .. }
        | Request::CancelDoctor => Vec::new(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_child_that_dies_marks_the_file_damaged_and_one_that_refuses_does_not() {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("a.hdf5");
        std::fs::write(&file, b"not hdf5").unwrap();
        // `sh -c SCRIPT sh FILE`: the file is $1.
        let sh = |script: &str| Vetter::new(vec!["sh".into(), "-c".into(), script.into(), "sh".into()]).unwrap();
        assert_eq!(sh("test -f \"$1\"").check(&file), Ok(()));
        assert_eq!(sh("exit 1").check(&file), Ok(()), "a refusal is the reader's to word");
        let crashed = sh("kill -SEGV $$").check(&file).unwrap_err();
        assert!(crashed.starts_with(&file.display().to_string()) && crashed.contains("damaged"), "{crashed}");
        assert!(crashed.contains("segmentation fault"), "{crashed}");
        let aborted = sh("exit 134").check(&file).unwrap_err();
        assert!(aborted.contains("exit 134"), "{aborted}");
        // A folder or a missing file is not vetted.
        assert_eq!(sh("kill -SEGV $$").check(dir.path()), Ok(()));
        assert_eq!(sh("kill -SEGV $$").check(&dir.path().join("missing.hdf5")), Ok(()));
    }

    #[test]
    fn a_verdict_is_kept_until_the_file_changes() {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("a.hdf5");
        let count = dir.path().join("count");
        std::fs::write(&file, b"x").unwrap();
        let script = format!("echo >> {}; exit 0", count.display());
        let vetter = Vetter::new(vec!["sh".into(), "-c".into(), script.into(), "sh".into()]).unwrap();
        vetter.check(&file).unwrap();
        vetter.clone().check(&file).unwrap();
        assert_eq!(std::fs::read_to_string(&count).unwrap().lines().count(), 1);
        std::fs::write(&file, b"longer now").unwrap();
        vetter.check(&file).unwrap();
        assert_eq!(std::fs::read_to_string(&count).unwrap().lines().count(), 2);
    }
}
