//! The source demos that ship with the project, found by an installed binary too.
//!
//! The files are compiled into the crate and written once to the cache directory
//! (`$MIMICGEN_CACHE/bundled/<version>/`), since HDF5 reads from a path.

use std::path::PathBuf;

use mimicgen_engine::TaskSpec;

use crate::PipelineError;

/// `(task, variant, file name, bytes)` of every bundled source file: each
/// `core/sim/data/<task>_<variant>_source.hdf5`, listed by the build script.
const FILES: &[(&str, &str, &str, &[u8])] = include!(concat!(env!("OUT_DIR"), "/bundled_sources.rs"));

/// The spec bundled for `task` (the paper's settings, `core/sim/tasks/<task>.toml`).
///
/// # Errors
/// [`PipelineError::Input`] (field `--config`) when the task has none.
pub fn spec(task: &str) -> Result<TaskSpec, PipelineError> {
    let toml = mimicgen_sim::registry::default_spec_toml(task)
        .ok_or_else(|| PipelineError::input("", "--config", format!("task {task} has no bundled spec; pass --config")))?;
    TaskSpec::from_toml_str(toml, &format!("bundled {task} spec")).map_err(|e| PipelineError::engine("bundled spec", e))
}

/// The bundled source demos of `task` (recorded in its D0 variant: scripted, or for Lift robosuite's human ones), as a file on disk.
///
/// # Errors
/// [`PipelineError::Input`] when the task has no bundled demos, [`PipelineError::Fs`] when the
/// cache cannot be written.
pub fn source_demos(task: &str) -> Result<PathBuf, PipelineError> {
    let (_, _, name, bytes) = FILES.iter().find(|(t, ..)| *t == task).ok_or_else(|| PipelineError::Input {
        file: String::new(),
        field: "--source".to_owned(),
        reason: format!("task {task:?} has no bundled source demos; record some with `mimicgen demos --task {task}` and pass --source"),
    })?;
    let dir = mimicgen_sim::assets::cache_dir().join("bundled").join(env!("CARGO_PKG_VERSION"));
    let path = dir.join(name);
    if std::fs::read(&path).is_ok_and(|on_disk| on_disk == *bytes) {
        return Ok(path);
    }
    let fs = |e: std::io::Error| PipelineError::Fs { file: path.display().to_string(), reason: e.to_string() };
    std::fs::create_dir_all(&dir).map_err(fs)?;
    // Written under a name of its own and renamed, so that a concurrent run, in this process or
    // another, never reads half a file nor renames this one's.
    static WRITES: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let write = WRITES.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let tmp = dir.join(format!("{name}.{}.{write}.tmp", std::process::id()));
    std::fs::write(&tmp, bytes).map_err(fs)?;
    std::fs::rename(&tmp, &path).map_err(fs)?;
    Ok(path)
}
