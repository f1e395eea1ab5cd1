//! The crate's one error type.

use mimicgen_engine::EngineError;

/// Everything that can go wrong reading or writing datasets. Messages name the file, the HDF5
/// group and the field at fault.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum IoError {
    /// The HDF5 library could not read (an unreadable or truncated file).
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
    /// Writing failed (a full disk, a file another program holds, no permission).
    #[error("{file}: group `{group}`{}: HDF5 error while writing: {reason}", if field.is_empty() { String::new() } else { format!(" field `{field}`") })]
    Write {
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
    /// A file cannot be opened: missing, a directory, not readable, not HDF5.
    #[error("{file}: {reason}")]
    Open {
        /// The file.
        file: String,
        /// Why, in a user's words (`no such file`).
        reason: String,
    },
    /// An output exists and the caller did not ask to replace it.
    #[error("{file}: exists")]
    Exists {
        /// The output.
        file: String,
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
        !matches!(self, Self::Fs { .. } | Self::Mcap { .. } | Self::Write { .. })
    }

    /// Opens an HDF5 file for reading; when HDF5 cannot, says why in a user's words (no such
    /// file, a directory, permission denied, not an HDF5 file) and keeps HDF5's message for the
    /// rest.
    pub(crate) fn open_h5(path: &std::path::Path) -> Result<hdf5::File> {
        hdf5::File::open(path).map_err(|e| {
            let file = path.display().to_string();
            match why_unreadable(path) {
                Some(reason) => Self::Open { file, reason },
                None => Self::hdf5(&file, "/", "", &e),
            }
        })
    }

    pub(crate) fn hdf5_write(file: &str, group: &str, field: &str, e: &hdf5::Error) -> Self {
        Self::Write { file: file.to_owned(), group: group.to_owned(), field: field.to_owned(), reason: e.to_string() }
    }

    pub(crate) fn hdf5(file: &str, group: &str, field: &str, e: &hdf5::Error) -> Self {
        Self::Hdf5 { file: file.to_owned(), group: group.to_owned(), field: field.to_owned(), reason: e.to_string() }
    }
}

/// Why `path` cannot be read as HDF5, as far as the file system and the format's signature tell.
fn why_unreadable(path: &std::path::Path) -> Option<String> {
    use std::io::Read as _;
    const SIGNATURE: &[u8] = b"\x89HDF\r\n\x1a\n";
    let meta = match std::fs::metadata(path) {
        Ok(m) => m,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Some("no such file".into()),
        Err(e) => return Some(e.to_string()),
    };
    if meta.is_dir() {
        return Some("is a directory, not an HDF5 file".into());
    }
    let mut f = match std::fs::File::open(path) {
        Ok(f) => f,
        Err(e) if e.kind() == std::io::ErrorKind::PermissionDenied => return Some("permission denied".into()),
        Err(e) => return Some(e.to_string()),
    };
    let mut head = Vec::new();
    // HDF5's signature sits at 0, 512, 1024, 2048, ... (after a user block); 4 KiB covers files
    // as robomimic and h5py write them.
    f.by_ref().take(4096).read_to_end(&mut head).ok()?;
    let signed = [0usize, 512, 1024, 2048].iter().any(|&at| head.get(at..at + SIGNATURE.len()) == Some(SIGNATURE));
    if head.is_empty() {
        Some("is empty, not an HDF5 file".into())
    } else if !signed {
        Some("not an HDF5 file (no HDF5 signature)".into())
    } else {
        None
    }
}

/// Crate result type.
pub type Result<T, E = IoError> = std::result::Result<T, E>;
