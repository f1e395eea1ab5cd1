//! What a run is, in plain serializable data: the one description of a run ([`RunConfig`]) that
//! the CLI's flags, the app's run form, the browser and Python all fill in, the spec fields a run
//! sets over its task spec ([`SpecOverrides`]), its cameras, and what it reports back
//! ([`RunInfo`], [`Report`]).
//!
//! What it does not do: read files, simulate or run anything (that is `mimicgen-pipeline`, which
//! re-exports these types). It has no native dependency, so the app's browser build uses it too.
//!
//! ```
//! use mimicgen_run::{RunConfig, Scoped, SpecOverrides};
//!
//! let config = RunConfig {
//!     num_demos: Some(20),
//!     spec: SpecOverrides { action_noise: vec![Scoped::all(0.02)], ..SpecOverrides::default() },
//!     ..RunConfig::default()
//! };
//! assert_eq!(config.spec.to_args(), ["--action-noise", "0.02"]);
//! ```

mod camera;
mod config;
pub mod doctor;
mod overrides;
mod report;
mod wording;

pub use camera::CameraConfig;
pub use config::{ActionForm, RunConfig};
pub use overrides::{OffsetRange, Scoped, SpecOverrides};
pub use report::{
    CauseReport, CoverageFigure, DatasetQuality, DemoReport, FailureReport, InstanceReport, NEVER_SUCCEEDS_MIN_USES, Outcome, ReplayCheck,
    Report, RunInfo,
};
pub use wording::{Choice, FrontEnd};

/// `<out stem><suffix>.<ext>` beside `out`: where a run's outputs go beside its dataset (the
/// report `.json`, `_failed.hdf5`, `_quality.json`).
#[must_use]
pub fn sibling(out: &std::path::Path, suffix: &str, ext: &str) -> std::path::PathBuf {
    let stem = out.file_stem().map_or_else(|| "generated".into(), |s| s.to_string_lossy().into_owned());
    out.with_file_name(format!("{stem}{suffix}.{ext}"))
}

/// Where the quality report of the dataset `out` goes: `<out stem>_quality.json`.
#[must_use]
pub fn quality_path(out: &std::path::Path) -> std::path::PathBuf {
    sibling(out, "_quality", "json")
}

/// A run description that cannot be applied.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum RunError {
    /// A spec field set for the run is invalid for the task's spec.
    #[error("{flag}: {reason}")]
    Flag {
        /// The field, as the CLI's flag (`--action-noise`).
        flag: String,
        /// What is wrong and what to do.
        reason: String,
    },
}

impl RunError {
    fn flag(flag: impl Into<String>, reason: impl Into<String>) -> Self {
        Self::Flag { flag: flag.into(), reason: reason.into() }
    }

    /// True when the user's input is at fault (all of them: a run description is user input).
    #[must_use]
    pub fn is_user_error(&self) -> bool {
        matches!(self, Self::Flag { .. })
    }
}
