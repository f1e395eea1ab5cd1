//! Embeds the directory of libmujoco.so (from `MUJOCO_DYNAMIC_LINK_DIR`, set by .cargo/config.toml)
//! as an rpath, so binaries and tests find the library with no `LD_LIBRARY_PATH`.
//!
//! For `mimicgen-sim` it also lists the bundled task files (`tasks/<name>.task.toml` and the
//! spec `<name>.toml` beside it), and for `mimicgen-pipeline` the bundled source demos
//! (`../sim/data/<task>_<variant>_source.hdf5`): a file put there is a task, with no list in code.
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

fn main() {
    println!("cargo::rerun-if-env-changed=MUJOCO_DYNAMIC_LINK_DIR");
    if let Ok(dir) = std::env::var("MUJOCO_DYNAMIC_LINK_DIR") {
        println!("cargo::rustc-link-arg=-Wl,-rpath,{dir}");
    }
    let manifest = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").expect("cargo sets CARGO_MANIFEST_DIR"));
    let out = PathBuf::from(std::env::var("OUT_DIR").expect("cargo sets OUT_DIR"));
    match std::env::var("CARGO_PKG_NAME").as_deref() {
        Ok("mimicgen-sim") => write(&out.join("bundled_tasks.rs"), &bundled_tasks(&manifest.join("tasks"))),
        Ok("mimicgen-pipeline") => write(&out.join("bundled_sources.rs"), &bundled_sources(&manifest.join("../sim/data"))),
        _ => {}
    }
}

fn write(path: &Path, text: &str) {
    std::fs::write(path, text).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
}

/// The files in `dir` whose names end with `suffix`, sorted, with the name before the suffix.
fn files(dir: &Path, suffix: &str) -> Vec<(String, PathBuf)> {
    println!("cargo::rerun-if-changed={}", dir.display());
    let listing = std::fs::read_dir(dir).unwrap_or_else(|e| panic!("{}: {e}", dir.display()));
    let mut found: Vec<(String, PathBuf)> = listing
        .filter_map(Result::ok)
        .filter_map(|e| {
            let name = e.file_name().to_string_lossy().into_owned();
            Some((name.strip_suffix(suffix)?.to_owned(), e.path()))
        })
        .collect();
    found.sort();
    found
}

/// `const BUNDLED: &[(&str, &str, Option<&str>)]`: `(name, task file, spec)` of every task file.
fn bundled_tasks(dir: &Path) -> String {
    let mut text = String::from("&[\n");
    for (name, path) in files(dir, ".task.toml") {
        let spec = path.with_file_name(format!("{name}.toml"));
        let spec = if spec.is_file() { format!("Some(include_str!({:?}))", spec.display().to_string()) } else { "None".to_owned() };
        let _ = writeln!(text, "    ({name:?}, include_str!({:?}), {spec}),", path.display().to_string());
    }
    text.push(']');
    text
}

/// `&[(task, variant, file name, bytes)]` of every `<task>_<variant>_source.hdf5`.
fn bundled_sources(dir: &Path) -> String {
    let mut text = String::from("&[\n");
    for (stem, path) in files(dir, "_source.hdf5") {
        let (task, variant) = stem.rsplit_once('_').unwrap_or_else(|| panic!("{}: expected <task>_<variant>_source.hdf5", path.display()));
        let file = format!("{stem}_source.hdf5");
        let _ = writeln!(text, "    ({task:?}, {variant:?}, {file:?}, include_bytes!({:?})),", path.display().to_string());
    }
    text.push(']');
    text
}
