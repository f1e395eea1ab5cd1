//! `mimicgen export --lerobot`: a dataset as a LeRobot dataset, with the defaults the CLI, the app
//! and Python share (the task's instruction from `env_args`, robomimic's low-dim state, the
//! ffmpeg `scripts/setup.sh` installs). The format itself is `mimicgen_io::lerobot`.

use std::path::{Path, PathBuf};

use mimicgen_io::lerobot::{DEFAULT_STATE_KEYS, LeRobotOptions, LeRobotSummary};
use mimicgen_io::{DemoReader, DemoSource as _, ReadOptions};
use mimicgen_sim::registry;

use crate::PipelineError;

/// What to export; `None` fields take the defaults.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ExportRequest {
    /// Observation keys concatenated into `observation.state` (default [`DEFAULT_STATE_KEYS`]).
    pub state_keys: Option<Vec<String>>,
    /// The instruction (default: the task's, from the file's `env_args`).
    pub instruction: Option<String>,
    /// The ffmpeg to encode cameras with (default [`LeRobotOptions::default_ffmpeg`]).
    pub ffmpeg: Option<PathBuf>,
    /// Replace an existing output.
    pub overwrite: bool,
}

/// Exports `file` as the LeRobot dataset `out`; `on_episode(done, total)` after each episode.
///
/// # Errors
/// [`PipelineError::Io`] for unreadable input, a missing state key, an existing output, or a
/// failed write or encode.
pub fn export(
    file: &Path,
    out: &Path,
    request: &ExportRequest,
    on_episode: impl FnMut(usize, usize),
) -> Result<LeRobotSummary, PipelineError> {
    let reader = DemoReader::open_with(file, ReadOptions::default())?;
    let task = registry::task_from_env_args(reader.env_args_json()).ok().map(|(task, _)| task.name().to_owned());
    let options = LeRobotOptions {
        state_keys: request.state_keys.clone().unwrap_or_else(|| DEFAULT_STATE_KEYS.map(str::to_owned).to_vec()),
        fps: 20,
        task: request
            .instruction
            .clone()
            .unwrap_or_else(|| task.as_deref().map_or_else(|| "do the task".to_owned(), registry::instruction)),
        robot_type: "panda".to_owned(),
        ffmpeg: request.ffmpeg.clone().unwrap_or_else(LeRobotOptions::default_ffmpeg),
        overwrite: request.overwrite,
    };
    Ok(mimicgen_io::lerobot::export_lerobot(&reader, out, &options, on_episode)?)
}
