//! What a user asks of a run: every field of `mimicgen generate`.

use std::path::PathBuf;

use mimicgen_engine::Shard;
use serde::{Deserialize, Serialize};

use crate::{CameraConfig, SpecOverrides};

/// A run as the user describes it: every field of `mimicgen generate`. `None` means "the default"
/// or "what the inputs say".
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct RunConfig {
    /// Task (`stack`); default: what the config or the source file names, else `stack`.
    pub task: Option<String>,
    /// Variant (`D1`); default: what the config or the source file names, else `D0`.
    pub variant: Option<String>,
    /// Task spec file (our TOML or a MimicGen experiment JSON); default: the task's bundled spec.
    pub config: Option<PathBuf>,
    /// Source demos (MimicGen source layout); default: the task's bundled demos.
    pub source: Option<PathBuf>,
    /// Output dataset; failed attempts go to `<out>_failed.hdf5`, the report to `<out>.json`.
    pub out: PathBuf,
    /// Worker threads, each with its own simulator. The dataset does not depend on it.
    pub workers: usize,
    /// Attempts to make (successes to reach with `guarantee`); default: the spec's `num_trials`.
    pub num_demos: Option<usize>,
    /// Run seed; default: the spec's.
    pub seed: Option<u64>,
    /// Also write failed attempts (up to the spec's `max_num_failures`).
    pub keep_failed: bool,
    /// Keep attempting until `num_demos` successes.
    pub guarantee: bool,
    /// Hard cap on attempts with `guarantee`.
    pub max_attempts: Option<usize>,
    /// Fraction of demos, drawn with the run seed, in a `mask/valid` filter key.
    pub valid_fraction: Option<f64>,
    /// End an attempt as soon as a subtask ends without its signal (see `GenerationSettings`).
    pub early_abort: bool,
    /// Replace an existing output.
    pub overwrite: bool,
    /// Continue the interrupted run that left `<out>.partial`.
    pub resume: bool,
    /// Spec fields set for this run over the spec's (`--action-noise`, `--selection`, ...).
    #[serde(default)]
    pub spec: SpecOverrides,
    /// Make only this share of the attempts (`--shard 1/4`); `mimicgen merge` joins the shards
    /// into the dataset of the whole run.
    #[serde(default)]
    pub shard: Option<Shard>,
    /// Render these cameras into the dataset (`agentview_image`, ...); none by default.
    #[serde(default)]
    pub cameras: Option<CameraConfig>,
    /// The arm to generate with (`sawyer`); default: the sources' (their `model_file`), else the
    /// Panda. Another arm than the sources' runs in the task's scene composed with it.
    #[serde(default)]
    pub robot: Option<String>,
}

impl Default for RunConfig {
    fn default() -> Self {
        Self {
            task: None,
            variant: None,
            config: None,
            source: None,
            out: PathBuf::from("out/generated.hdf5"),
            workers: 1,
            num_demos: None,
            seed: None,
            keep_failed: false,
            guarantee: false,
            max_attempts: None,
            valid_fraction: None,
            early_abort: false,
            overwrite: false,
            resume: false,
            spec: SpecOverrides::default(),
            shard: None,
            cameras: None,
            robot: None,
        }
    }
}
