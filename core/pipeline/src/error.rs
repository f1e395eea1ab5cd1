//! The pipeline's one error type.

use mimicgen_engine::EngineError;
use mimicgen_io::IoError;
use mimicgen_run::FrontEnd;
use mimicgen_sim::SimError;

/// Everything that can stop a run. Failed attempts are not errors: they are records in the report.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum PipelineError {
    /// The user's input is invalid: an argument, a config, a source file, an output that exists.
    #[error("{}{}{reason}", if file.is_empty() { String::new() } else { format!("{file}: ") }, if field.is_empty() { String::new() } else { format!("{field}: ") })]
    Input {
        /// The file at fault (empty for a command-line argument).
        file: String,
        /// The field or argument at fault.
        field: String,
        /// What is wrong and what to do.
        reason: String,
    },
    /// An output exists and the caller did not ask to replace it (each front end words how:
    /// [`PipelineError::advice`]).
    #[error("{file}: exists{}", if *resumable { " (an interrupted run left it)" } else { "" })]
    Exists {
        /// The first output found.
        file: String,
        /// An interrupted run left it: it can be resumed.
        resumable: bool,
    },
    /// The engine rejected the inputs or a simulator failed for good; `file` names the input.
    #[error("{}{source}", if file.is_empty() { String::new() } else { format!("{file}: ") })]
    Engine {
        /// The input concerned (the source demos or the spec), or the run; empty when the
        /// engine's error names it itself.
        file: String,
        /// The engine's error.
        source: EngineError,
    },
    /// Reading or writing a dataset failed.
    #[error(transparent)]
    Io(#[from] IoError),
    /// The simulator could not be built.
    #[error(transparent)]
    Sim(#[from] SimError),
    /// A file-system operation failed.
    #[error("{file}: {reason}")]
    Fs {
        /// The path.
        file: String,
        /// What the OS said.
        reason: String,
    },
}

impl PipelineError {
    /// True when the user's input is at fault (exit code 2 in the CLI, `ValueError` in Python).
    #[must_use]
    pub fn is_user_error(&self) -> bool {
        match self {
            Self::Input { .. } | Self::Exists { .. } => true,
            Self::Engine { source, .. } => source.is_user_error(),
            Self::Io(e) => e.is_user_error(),
            Self::Sim(e) => e.is_user_error(),
            Self::Fs { .. } => false,
        }
    }

    /// What the user can do about this error, in `front`'s words (`pass --overwrite`), when it
    /// is a choice the user has.
    #[must_use]
    pub fn advice(&self, front: FrontEnd) -> Option<String> {
        match self {
            Self::Exists { resumable, .. } => Some(front.output_exists_advice(*resumable)),
            Self::Io(IoError::Exists { .. }) => Some(front.output_exists_advice(false)),
            _ => None,
        }
    }

    /// The whole message as `front` words it: a run's field by its name there (Python's
    /// `spec["action_noise"]` for `--action-noise`), then the [advice](Self::advice).
    #[must_use]
    pub fn worded(&self, front: FrontEnd) -> String {
        let message = match self {
            Self::Input { file, field, reason } if field.starts_with("--") => {
                Self::input(file.clone(), front.field(field), reason.clone()).to_string()
            }
            _ => self.to_string(),
        };
        match self.advice(front) {
            Some(advice) => format!("{message}; {advice}"),
            None => message,
        }
    }

    pub(crate) fn input(file: impl Into<String>, field: impl Into<String>, reason: impl Into<String>) -> Self {
        Self::Input { file: file.into(), field: field.into(), reason: reason.into() }
    }

    pub(crate) fn engine(file: impl Into<String>, source: EngineError) -> Self {
        Self::Engine { file: file.into(), source }
    }
}

impl From<mimicgen_run::RunError> for PipelineError {
    fn from(e: mimicgen_run::RunError) -> Self {
        match e {
            mimicgen_run::RunError::Flag { flag, reason } => Self::input("", flag, reason),
            other => Self::input("", "", other.to_string()),
        }
    }
}
