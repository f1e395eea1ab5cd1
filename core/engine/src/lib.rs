//! The MimicGen method (Mandlekar et al., CoRL 2023) as a pure-Rust engine.
//!
//! What it does: parses source demonstrations into object-centric subtask segments
//! ([`segment`]), selects a source segment for a new scene ([`select`]), transforms it so the
//! end-effector keeps its pose relative to the subtask's object and bridges to it with an
//! interpolation segment ([`transform`]), executes it as noisy delta-pose actions through an
//! [`Environment`] and keeps a structured record of every attempt ([`generate`]) with the cause
//! of each failure ([`diagnose`]); plus the task
//! spec formats ([`spec`]), the coverage analysis ([`coverage`]) and, for cluttered scenes,
//! SkillGen's planned collision-free transit to each segment ([`transit`]).
//!
//! What it does not do: no simulator, no file formats beyond its config files, no GUI, no
//! rendering. Simulators implement [`Environment`]; [`kinematic`] is a small physics-free one used
//! by tests, benchmarks and this example:
//!
//! ```
//! use mimicgen_engine::{Generator, kinematic};
//! use std::ops::ControlFlow;
//!
//! let spec = kinematic::pick_place_spec(20, 7);
//! let sources = kinematic::scripted_dataset(4, 1).unwrap();
//! let generator = Generator::new(spec, sources).unwrap();
//! let mut envs = vec![kinematic::PickPlace::new(0.1)];
//! let stats = mimicgen_engine::run(&generator, &mut envs, |_attempt, _stats| ControlFlow::Continue(())).unwrap();
//! assert_eq!(stats.attempts, 20);
//! assert!(stats.rate() > 0.8);
//! ```

pub mod action;
pub mod base;
pub mod coverage;
pub mod demo;
pub mod demonstrator;
pub mod detect;
pub mod diagnose;
pub mod env;
pub mod fingerprint;
pub mod generate;
pub mod image;
pub mod kinematic;
pub mod pose;
pub mod quality;
pub mod segment;
pub mod select;
pub mod spec;
pub mod transform;
pub mod transit;
pub mod two_arm;

#[cfg(test)]
pub(crate) mod testing;

pub use demo::{Rows, SimPayload, SourceDataset, SourceDemo, SubtaskMarks};
pub use env::{EnvError, Environment};
pub use generate::{Attempt, Failure, FailureReason, Generator, Overrides, Plan, RunControl, RunStats, Shard, SubtaskPlan, run, run_with};
pub use pose::Pose;
pub use spec::{GenerationSettings, SelectionStrategy, SubtaskSpec, TaskSpec};

/// Everything that can go wrong in the engine. Messages name the file, demo or field at fault.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum EngineError {
    /// A pose is not a finite rigid transform.
    #[error("invalid pose in {what}: {reason}")]
    InvalidPose {
        /// Where the pose came from.
        what: String,
        /// What is wrong with it.
        reason: String,
    },
    /// A recorded array (states, actions, gripper actions) holds NaN or infinity.
    #[error("{what} contains NaN or infinity")]
    NonFinite {
        /// The demo, field and step.
        what: String,
    },
    /// Arrays of one demo disagree in shape.
    #[error("bad shape in {what}: {reason}")]
    Shape {
        /// The field.
        what: String,
        /// What is wrong.
        reason: String,
    },
    /// A config file or value is invalid.
    #[error("invalid config{}{}: {reason}", if file.is_empty() { String::new() } else { format!(" {file}") }, if field.is_empty() { String::new() } else { format!(" field `{field}`") })]
    Config {
        /// The file (empty when not from a file).
        file: String,
        /// The field (empty when the whole file is at fault).
        field: String,
        /// What is wrong.
        reason: String,
    },
    /// A config names an object or signal that does not exist.
    #[error("`{field}` names {name:?}, which does not exist (available: {available:?})")]
    UnknownName {
        /// The config field.
        field: String,
        /// The unknown name.
        name: String,
        /// The names that exist.
        available: Vec<String>,
    },
    /// A demo cannot be split into subtask segments.
    #[error("cannot segment {demo}, subtask {subtask}: {reason}")]
    Segmentation {
        /// The demo's name.
        demo: String,
        /// The subtask index (0-based).
        subtask: usize,
        /// What is wrong.
        reason: String,
    },
    /// The environment failed in a way no attempt can recover from.
    #[error("environment failed in attempt {attempt}: {source}")]
    Env {
        /// The attempt index.
        attempt: u64,
        /// The environment's error.
        source: EnvError,
    },
    /// A file could not be read or written.
    #[error("{path}: {reason}")]
    Io {
        /// The file.
        path: String,
        /// The OS error.
        reason: String,
    },
}

impl EngineError {
    /// True when the user's input (data or config) is at fault rather than the program.
    #[must_use]
    pub fn is_user_error(&self) -> bool {
        !matches!(self, Self::Env { .. } | Self::Io { .. })
    }
}
