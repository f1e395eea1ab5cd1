//! Cross-crate integration tests live in `tests/`; this library holds their shared helpers and
//! the fuzz harnesses ([`fuzz`]).

pub mod fuzz;

/// Path of a file in the repository, from this crate's directory.
#[must_use]
pub fn repo_path(relative: &str) -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join(relative)
}
