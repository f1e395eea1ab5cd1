//! Rerun logging of MimicGen: the MuJoCo scene, source demos, segments and attempts, live or saved.
//!
//! What it does: logs every visible geom of a compiled scene once and its pose per recorded step
//! ([`SceneLogger`]); logs source demos (end-effector path by subtask, subtask ends, object frames
//! there, subtask-end signals) and attempts (object frames of the new scene, the chosen source
//! segment, its transformed copy, the interpolation segment, the executed path, gripper, outcome)
//! ([`record`]); logs running statistics; opens a recording to a file, a running viewer or a spawned
//! viewer ([`Sink`]), with the default layout ([`default_blueprint`]).
//! What it does not do: run generation or read files (the `mimicgen` binary does), draw a GUI.
//!
//! Timelines: `attempt` (index in a run), `demo` (index in a dataset), `step` (within one attempt
//! or demo), `frame` (every step of the run one after the other) and the SDK's `log_time`.
//!
//! ```no_run
//! # fn main() -> Result<(), mimicgen_viz::VizError> {
//! let rec = mimicgen_viz::Sink::Save("run.rrd".into()).open("mimicgen")?;
//! rec.log("hello", &rerun::TextLog::new("a recording")).map_err(|e| mimicgen_viz::VizError::rerun("hello", &e))?;
//! # Ok(()) }
//! ```

mod blueprint;
pub mod record;
mod run;
mod scene;
mod sink;

pub use blueprint::{app_blueprint, blueprint_with_cameras, default_blueprint};
pub use rerun;
pub use run::{LogConfig, RunLogger, SceneLevel};
pub use scene::{SceneLogger, xyzw_from_xmat};
pub use sink::{Sink, send_blueprint, viewer_path};

/// Everything that can go wrong logging to Rerun.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum VizError {
    /// The Rerun SDK rejected data or could not open the sink.
    #[error("rerun: {what}: {reason}")]
    Rerun {
        /// The entity path or sink concerned.
        what: String,
        /// The SDK's message.
        reason: String,
    },
    /// The viewer binary is not installed where we looked.
    #[error("the Rerun viewer is not installed at {path}: {hint}")]
    ViewerMissing {
        /// Where we looked.
        path: String,
        /// How to install it.
        hint: String,
    },
    /// Recorded states do not fit the scene.
    #[error("{what}: {reason}")]
    Sim {
        /// The scene or demo concerned.
        what: String,
        /// What does not fit.
        reason: String,
    },
}

impl VizError {
    /// A [`VizError::Rerun`] about `what`.
    pub fn rerun(what: &str, reason: &dyn std::fmt::Display) -> Self {
        Self::Rerun { what: what.to_owned(), reason: reason.to_string() }
    }

    /// True when the user's input or setup is at fault (a missing viewer, mismatched states).
    #[must_use]
    pub fn is_user_error(&self) -> bool {
        !matches!(self, Self::Rerun { .. })
    }
}
