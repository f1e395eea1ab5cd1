//! What a run says of itself: how it started, where each attempt went, and its report.

use std::path::PathBuf;

use mimicgen_engine::Shard;
use mimicgen_engine::generate::TransitTotals;
use serde::{Deserialize, Serialize};

use crate::SpecOverrides;

/// Where an attempt went.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Outcome {
    /// A success, written to the dataset as `demo`.
    Written {
        /// Its name in the dataset.
        demo: String,
    },
    /// A failure kept in the failed-attempts file as `demo`.
    KeptFailed {
        /// Its name in the failed-attempts file.
        demo: String,
    },
    /// A failure not kept.
    Discarded,
}

/// The run as it starts.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunInfo {
    /// Task name.
    pub task: String,
    /// Variant.
    pub variant: String,
    /// Source demo file.
    pub source: PathBuf,
    /// Number of source demos.
    pub num_sources: usize,
    /// Worker threads.
    pub workers: usize,
    /// Run seed.
    pub seed: u64,
    /// Spec fields set over the spec's.
    pub spec_overrides: SpecOverrides,
    /// Attempts to make, or successes to reach with `guarantee`.
    pub target: usize,
    /// Whether `target` counts successes.
    pub guarantee: bool,
    /// First attempt index of this session (non-zero when resumed).
    pub resumed_from: usize,
}

/// Attempts and successes of one source demo, as reported.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DemoReport {
    /// Source demo index.
    pub demo: usize,
    /// Attempts that used it.
    pub attempts: usize,
    /// Of those, successes.
    pub successes: usize,
}

/// Failures of one subtask for one reason, as reported.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FailureReport {
    /// Subtask index.
    pub subtask: usize,
    /// Why (human-readable).
    pub reason: String,
    /// How many attempts.
    pub count: usize,
}

/// Failures of one subtask for one cause class ([`mimicgen_engine::diagnose::Cause::class`]), as
/// reported.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CauseReport {
    /// Subtask index.
    pub subtask: usize,
    /// The cause's class (`grasp_missed`, `object_moved`, `arm_lagged`, `grasp_slipped`,
    /// `ran_out_of_steps`, `success_unmet`, `simulation`).
    pub cause: String,
    /// How many attempts.
    pub count: usize,
}

/// The quality report of a generated dataset (its successful attempts).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DatasetQuality {
    /// The dataset.
    pub dataset: String,
    /// Stitch jumps and jerks per subtask, and the pose actions against the controller's limits,
    /// over the successes of this session (a resumed run's earlier sessions are not in them).
    pub quality: mimicgen_engine::quality::Quality,
    /// Support coverage of the successes' initial object poses over the variant's reset region.
    pub coverage: Option<CoverageFigure>,
    /// A sample of the written demos replayed from their first state with their stored actions
    /// (robomimic's playback), in the run's simulator.
    pub replay: Option<ReplayCheck>,
}

/// The paper's support coverage of a set of initial scenes.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CoverageFigure {
    /// Bins per object coordinate.
    pub bins: usize,
    /// Scenes binned.
    pub scenes: usize,
    /// Share of the joint bins hit.
    pub support_coverage: f64,
    /// What as many uniformly spread scenes would hit.
    pub uniform_support_coverage: f64,
}

/// Demos of the written dataset replayed.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ReplayCheck {
    /// The demos replayed (evenly spread over the dataset).
    pub demos: Vec<String>,
    /// Of those, the ones that achieved the task again.
    pub succeeded: usize,
    /// Why the replay could not run, if it could not.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
}

/// The attempts whose episode drew one object instance (object transfer), and their successes.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct InstanceReport {
    /// The instance (the `mimicgen_object_instance` of the demos that drew it, or one of its
    /// `+`-joined parts where an episode draws one instance per object).
    pub instance: String,
    /// Attempts whose episode drew it.
    pub attempts: usize,
    /// Of those, successes.
    pub successes: usize,
}

/// Uses below which a source demo without a success is not yet flagged in
/// [`Report::never_succeeded`].
pub const NEVER_SUCCEEDS_MIN_USES: usize = 5;

/// The report of a run, written as `<out>.json` beside the dataset.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Report {
    /// Task name.
    pub task: String,
    /// Variant.
    pub variant: String,
    /// Run seed.
    pub seed: u64,
    /// Worker threads.
    pub workers: usize,
    /// Source demo file.
    pub source: String,
    /// The task spec file the run read (`--config`); `None`: the task's bundled spec.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub config: Option<String>,
    /// The arm the run generated with (`--robot`); `None`: the sources' own.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub robot: Option<String>,
    /// The dataset.
    pub output: String,
    /// The failed-attempts file, if kept.
    pub failed_output: Option<String>,
    /// Attempts decided (over every session of a resumed run).
    pub attempts: usize,
    /// Successful attempts.
    pub successes: usize,
    /// successes / attempts.
    pub generation_rate: f64,
    /// Wall time of this session.
    pub wall_time_s: f64,
    /// Attempts of this session per second.
    pub attempts_per_s: f64,
    /// Control steps simulated in this session (failed attempts included): the work done,
    /// independent of the machine's load.
    pub control_steps: usize,
    /// Per source demo.
    pub per_source_demo: Vec<DemoReport>,
    /// The success matrix: per subtask, per source demo, the attempts whose segment for that
    /// subtask came from it and their successes.
    #[serde(default)]
    pub per_subtask_source: Vec<Vec<DemoReport>>,
    /// Source demos that supplied a segment to at least [`NEVER_SUCCEEDS_MIN_USES`] attempts and
    /// never to a success: candidates to drop.
    #[serde(default)]
    pub never_succeeded: Vec<usize>,
    /// Per object instance the episodes drew (object transfer: Mug Cleanup O2's twelve mugs), by
    /// name, over every session of a resumed run; left out when no episode draws one.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub per_object_instance: Vec<InstanceReport>,
    /// Peak resident memory of the process, MiB.
    pub peak_rss_mib: Option<f64>,
    /// Failures by subtask and reason.
    pub failures: Vec<FailureReport>,
    /// Failures by subtask and cause (what went wrong where they failed).
    #[serde(default)]
    pub causes: Vec<CauseReport>,
    /// Whether the run was cancelled before its stopping rule (the dataset is complete and valid,
    /// with the attempts decided before the cancel).
    pub cancelled: bool,
    /// First attempt index of this session (non-zero when resumed).
    pub resumed_from: usize,
    /// Whether attempts ended at the first subtask that missed its signal.
    pub early_abort: bool,
    /// Spec fields the run set over the spec's (`--action-noise` ...), so it can be made again.
    #[serde(default, skip_serializing_if = "SpecOverrides::is_empty")]
    pub spec_overrides: SpecOverrides,
    /// The share of the attempts this run made, if it was a shard.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub shard: Option<Shard>,
    /// What a user checks before training: stitches, actions, coverage, a replay sample
    /// (also written as `<out>_quality.json`). `None` for a merged run's report.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub quality: Option<DatasetQuality>,
    /// Planned transits and obstacle contacts over the run's attempts (`--transit plan`, a
    /// cluttered variant); left out when there were none. A merged run's report leaves them out.
    #[serde(default, skip_serializing_if = "TransitTotals::is_empty")]
    pub transit: TransitTotals,
}
