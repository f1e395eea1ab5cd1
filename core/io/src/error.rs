//! The crate's one error type.

use mimicgen_engine::EngineError;

/// Everything that can go wrong reading or writing datasets. Messages name the file, the HDF5
/// group and the field at fault.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum IoError {
    /// The HDF5 library failed (unreadable or truncated file, write error).
    #[error("{file}: group `{group}`{}: HDF5 error: {reason}", if field.is_empty() { String::new() } else { format!(" field `{field}`") })]
    Hdf5 {
        /// The file.
        file: String,
        /// The group (`/` for the root).
        group: String,
        /// The dataset or attribute (empty when the group itself is at fault).
        field: String,
        /// The library's message.
        reason: String,
    },
    /// A required group, dataset or attribute is absent.
    #[error("{file}: group `{group}` has no `{field}`{}", if hint.is_empty() { String::new() } else { format!(" ({hint})") })]
    Missing {
        /// The file.
        file: String,
        /// The group that should hold it.
        group: String,
        /// The missing member or attribute.
        field: String,
        /// What it is needed for.
        hint: String,
    },
    /// A dataset has the wrong shape, or datasets of one demo disagree in length.
    #[error("{file}: group `{group}` field `{field}`: bad shape: {reason}")]
    Shape {
        /// The file.
        file: String,
        /// The group.
        group: String,
        /// The dataset.
        field: String,
        /// What is wrong.
        reason: String,
    },
    /// A value is unusable: a NaN or non-rigid pose, an unsupported type, bad JSON.
    #[error("{file}: group `{group}` field `{field}`: {reason}")]
    Invalid {
        /// The file.
        file: String,
        /// The group.
        group: String,
        /// The dataset or attribute.
        field: String,
        /// What is wrong.
        reason: String,
    },
    /// The file was left incomplete by an interrupted writer.
    #[error(
        "{file}: group `/` field `{field}`: the file was not finished by its writer (interrupted?); \
         {complete_demos} complete demos can be recovered with `ReadOptions {{ recover: true, .. }}`"
    )]
    Incomplete {
        /// The file.
        file: String,
        /// The marker attribute.
        field: String,
        /// Demos that were completely written.
        complete_demos: usize,
    },
    /// A plain robomimic dataset lacks what MimicGen needs; the report lists every gap.
    #[error("{file}: not a MimicGen source dataset: {report}")]
    NotMimicGen {
        /// The file.
        file: String,
        /// What is present and what is missing.
        report: Box<crate::DatasetReport>,
    },
    /// The data read fine but the engine rejects it.
    #[error("{file}: group `data` field `{field}`: {source}")]
    Engine {
        /// The file.
        file: String,
        /// The demo or field at fault, as far as known.
        field: String,
        /// The engine's error.
        source: Box<EngineError>,
    },
    /// A filesystem operation failed.
    #[error("{file}: {reason}")]
    Fs {
        /// The file.
        file: String,
        /// The OS error.
        reason: String,
    },
    /// Writing MCAP failed.
    #[error("{file}: channel `{channel}`: MCAP error: {reason}")]
    Mcap {
        /// The file.
        file: String,
        /// The channel (topic) being written.
        channel: String,
        /// The library's message.
        reason: String,
    },
    /// The caller used the API wrongly (e.g. appended a demo with inconsistent arrays).
    #[error("{file}: group `{group}` field `{field}`: {reason}")]
    Usage {
        /// The file.
        file: String,
        /// The group.
        group: String,
        /// The field.
        field: String,
        /// What is wrong.
        reason: String,
    },
}

impl IoError {
    /// True when the input (a file's content or a request) is at fault rather than the program
    /// or the machine.
    #[must_use]
    pub fn is_user_error(&self) -> bool {
        !matches!(self, Self::Fs { .. } | Self::Mcap { .. })
    }

    pub(crate) fn hdf5(file: &str, group: &str, field: &str, e: &hdf5::Error) -> Self {
        Self::Hdf5 { file: file.to_owned(), group: group.to_owned(), field: field.to_owned(), reason: e.to_string() }
    }
}

/// Crate result type.
pub type Result<T, E = IoError> = std::result::Result<T, E>;
