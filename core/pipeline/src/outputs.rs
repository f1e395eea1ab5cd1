//! What a run writes beside its dataset, and what it needs to resume: the run's description and
//! progress (attributes of the dataset and its `.partial`), the attempt log, the failed-attempts
//! file, report and quality report paths, and clearing them for a new run.

use std::path::{Path, PathBuf};

use mimicgen_engine::{Failure, RunStats, Shard, TaskSpec};
use mimicgen_io::DatasetWriter;
use serde::{Deserialize, Serialize};

use crate::{CauseReport, DemoReport, FailureReport, PipelineError};

/// Root attribute of the output (and of its `.partial`) holding the run description.
pub const RUN_ATTR: &str = "mimicgen_run";
/// Root attribute of the `.partial` file holding the progress of the run (the commit point of
/// each attempt: attempts before its `next_attempt` are decided and their demos written).
pub const PROGRESS_ATTR: &str = "mimicgen_progress";

/// What a run was asked to make; a resumed run must describe the same dataset.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub(crate) struct RunDescription {
    pub(crate) task: String,
    pub(crate) variant: String,
    pub(crate) source: String,
    /// FNV-1a of the source file's bytes, so a resumed run reads the same demos.
    pub(crate) source_fingerprint: String,
    pub(crate) spec: TaskSpec,
    pub(crate) valid_fraction: Option<f64>,
    /// The share of the attempts a shard makes (absent for a whole run, and in a merged one).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(crate) shard: Option<Shard>,
    /// The cameras rendered into the demos.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(crate) cameras: Option<mimicgen_sim::camera::CameraConfig>,
    /// The arm, when it is not the Panda.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(crate) robot: Option<String>,
    /// The action forms written beside `actions` (`actions_abs`).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub(crate) actions: Vec<crate::ActionForm>,
}

/// How far a run has got, stored in the `.partial` file after every attempt.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub(crate) struct Progress {
    pub(crate) next_attempt: usize,
    pub(crate) failures_kept: usize,
    pub(crate) stats: RunStats,
}

/// One decided attempt, as a run logs it (`<out>.attempts.jsonl`, a line each, in index order)
/// so that `mimicgen merge` can cut the joined run where the whole run stops and count what it
/// counts, failures that were not kept included, and so that a merged or resumed run's quality
/// report sums the figures of every demo in its dataset.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AttemptRecord {
    /// Attempt index.
    pub index: usize,
    /// Whether the task succeeded.
    pub success: bool,
    /// Source demo per subtask.
    pub sources: Vec<usize>,
    /// Where and why it failed.
    pub failure: Option<Failure>,
    /// What went wrong there.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cause: Option<mimicgen_engine::diagnose::Cause>,
    /// Control steps.
    pub steps: usize,
    /// Its demo in the shard's dataset (a success) or failed-attempts file (a kept failure).
    pub kept: Option<String>,
    /// The object instance its episode drew (object transfer); absent for the other tasks.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub instance: Option<String>,
    /// A success's figures for the quality report (absent for failures).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub figures: Option<mimicgen_engine::quality::AttemptFigures>,
    /// A success's initial object poses, for the quality report's coverage (absent for failures).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub initial_object_poses: Option<std::collections::BTreeMap<String, mimicgen_engine::Pose>>,
}

/// A shard's attempt log: a JSON line per decided attempt, flushed after each (before the
/// dataset's progress, so the log never lags behind it).
pub(crate) struct AttemptLog {
    file: std::io::BufWriter<std::fs::File>,
    path: PathBuf,
}

impl AttemptLog {
    pub(crate) fn create(path: PathBuf) -> Result<Self, PipelineError> {
        let file =
            std::fs::File::create(&path).map_err(|e| PipelineError::Fs { file: path.display().to_string(), reason: e.to_string() })?;
        Ok(Self { file: std::io::BufWriter::new(file), path })
    }

    /// The log of an interrupted run, cut to the attempts before `next`, to go on appending,
    /// and those records. A run that has no log (one an older version began) starts one.
    pub(crate) fn resume(path: PathBuf, next: usize) -> Result<(Self, Vec<AttemptRecord>), PipelineError> {
        let kept: Vec<AttemptRecord> =
            if path.is_file() { read_attempt_log(&path)?.into_iter().filter(|r| r.index < next).collect() } else { Vec::new() };
        let mut log = Self::create(path)?;
        for r in &kept {
            log.append(r)?;
        }
        Ok((log, kept))
    }

    pub(crate) fn append(&mut self, record: &AttemptRecord) -> Result<(), PipelineError> {
        use std::io::Write as _;
        let fs = |e: std::io::Error| PipelineError::Fs { file: self.path.display().to_string(), reason: e.to_string() };
        let line = serde_json::to_string(record).map_err(|e| PipelineError::input("", "attempt record", e.to_string()))?;
        writeln!(self.file, "{line}").map_err(fs)?;
        self.file.flush().map_err(fs)
    }
}

/// The quality figures and initial scenes of the successes among `records`: what a resumed run
/// (its earlier sessions) and a merged run (its shards) sum their quality report from.
pub(crate) fn logged_quality<'a>(
    records: impl IntoIterator<Item = &'a AttemptRecord>,
) -> (mimicgen_engine::quality::QualityStats, Vec<std::collections::BTreeMap<String, mimicgen_engine::Pose>>) {
    let mut quality = mimicgen_engine::quality::QualityStats::default();
    let mut scenes = Vec::new();
    for record in records.into_iter().filter(|r| r.success) {
        if let Some(f) = &record.figures {
            quality.add_figures(f);
        }
        scenes.extend(record.initial_object_poses.clone());
    }
    (quality, scenes)
}

/// Attempts and successes per object instance (object transfer), counted as attempts arrive.
#[derive(Debug, Default)]
pub(crate) struct InstanceTally(std::collections::BTreeMap<String, (usize, usize)>);

impl InstanceTally {
    /// The tally of logged attempts.
    pub(crate) fn of<'a>(records: impl IntoIterator<Item = &'a AttemptRecord>) -> Self {
        let mut tally = Self::default();
        for record in records {
            tally.add(record.instance.as_deref(), record.success);
        }
        tally
    }

    /// Counts one attempt under each instance it drew (a label `pan+carrot` names one per
    /// object); one that drew no instance is not counted.
    pub(crate) fn add(&mut self, instance: Option<&str>, success: bool) {
        for part in instance.into_iter().flat_map(|label| label.split('+')) {
            let count = self.0.entry(part.to_owned()).or_default();
            count.0 += 1;
            count.1 += usize::from(success);
        }
    }

    /// The report's rows, by name; empty when no attempt drew an instance.
    pub(crate) fn report(&self) -> Vec<crate::InstanceReport> {
        self.0
            .iter()
            .map(|(instance, &(attempts, successes))| crate::InstanceReport { instance: instance.clone(), attempts, successes })
            .collect()
    }
}

/// Writes the quality report of the dataset at `out` beside it.
pub(crate) fn write_quality(out: &Path, quality: &crate::DatasetQuality) -> Result<(), PipelineError> {
    let path = quality_path(out);
    std::fs::write(&path, serde_json::to_string_pretty(quality).unwrap_or_default())
        .map_err(|e| PipelineError::Fs { file: path.display().to_string(), reason: e.to_string() })
}

/// Reads a run's attempt log.
///
/// # Errors
/// [`PipelineError::Fs`] when it cannot be read, [`PipelineError::Input`] naming the line that
/// is not a record.
pub fn read_attempt_log(path: &Path) -> Result<Vec<AttemptRecord>, PipelineError> {
    let file = path.display().to_string();
    let text = std::fs::read_to_string(path).map_err(|e| PipelineError::Fs { file: file.clone(), reason: e.to_string() })?;
    text.lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty())
        .map(|(n, l)| serde_json::from_str(l).map_err(|e| PipelineError::input(file.clone(), format!("line {}", n + 1), e.to_string())))
        .collect()
}

/// The report's rows per source demo.
pub(crate) fn per_source_demo(stats: &RunStats) -> Vec<DemoReport> {
    stats.per_source_demo.iter().enumerate().map(|(demo, d)| DemoReport { demo, attempts: d.attempts, successes: d.successes }).collect()
}

/// The report's success matrix: per subtask, per source demo.
pub(crate) fn per_subtask_source(stats: &RunStats) -> Vec<Vec<DemoReport>> {
    stats
        .per_subtask_source
        .iter()
        .map(|row| row.iter().enumerate().map(|(demo, d)| DemoReport { demo, attempts: d.attempts, successes: d.successes }).collect())
        .collect()
}

/// The source demos used by at least [`mimicgen_run::NEVER_SUCCEEDS_MIN_USES`] attempts, none a
/// success.
pub(crate) fn never_succeeded(stats: &RunStats) -> Vec<usize> {
    stats.never_succeeded(mimicgen_run::NEVER_SUCCEEDS_MIN_USES)
}

/// The report's failures by subtask and cause class.
pub(crate) fn causes(stats: &RunStats) -> Vec<CauseReport> {
    stats.causes.iter().map(|c| CauseReport { subtask: c.subtask, cause: c.class.clone(), count: c.count }).collect()
}

/// The report's failures by subtask and reason.
pub(crate) fn failures(stats: &RunStats) -> Vec<FailureReport> {
    stats.failures.iter().map(|f| FailureReport { subtask: f.subtask, reason: f.reason.to_string(), count: f.count }).collect()
}

/// The failed-attempts file beside dataset `out`.
#[must_use]
pub fn failed_path(out: &Path) -> PathBuf {
    sibling(out, "_failed", "hdf5")
}

/// The top-level fields whose values differ between two descriptions of a run (JSON objects).
pub(crate) fn differing_fields(a: &serde_json::Value, b: &serde_json::Value) -> Vec<String> {
    a.as_object().map(|o| o.iter().filter(|(k, v)| b.get(*k) != Some(*v)).map(|(k, _)| k.clone()).collect()).unwrap_or_default()
}

/// Makes room for a run's outputs at `out` (the dataset, failed attempts, their `.partial`s, the
/// report, and `extra`): refuses any that exists, or with `overwrite` removes them; then creates
/// `out`'s folder. With `resumable`, a `.partial` left there is said to be resumable.
///
/// # Errors
/// [`PipelineError::Exists`] naming the first output that exists;
/// [`PipelineError::Fs`] when one cannot be removed or the folder made.
pub fn clear_outputs(out: &Path, extra: Option<&Path>, overwrite: bool, resumable: bool) -> Result<(), PipelineError> {
    let failed = failed_path(out);
    let partial = DatasetWriter::partial_path(out);
    let outputs = [
        out.to_path_buf(),
        partial.clone(),
        failed.clone(),
        DatasetWriter::partial_path(&failed),
        sibling(out, "", "json"),
        quality_path(out),
    ];
    let existing: Vec<&Path> = outputs.iter().map(PathBuf::as_path).chain(extra).filter(|p| p.exists()).collect();
    if let Some(first) = existing.first() {
        if !overwrite {
            let resumable = resumable && *first == partial.as_path();
            return Err(PipelineError::Exists { file: first.display().to_string(), resumable });
        }
        for path in existing {
            std::fs::remove_file(path).map_err(|e| PipelineError::Fs { file: path.display().to_string(), reason: e.to_string() })?;
        }
    }
    if let Some(dir) = out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|e| PipelineError::Fs { file: dir.display().to_string(), reason: e.to_string() })?;
    }
    Ok(())
}

/// Where a run writing `out` logs its attempts.
#[must_use]
pub fn attempt_log_path(out: &Path) -> PathBuf {
    sibling(out, "", "attempts.jsonl")
}

pub use mimicgen_run::{quality_path, sibling};

#[cfg(test)]
mod tests {
    use super::InstanceTally;

    /// An episode that drew one instance per object (`pan+carrot`) counts under each; one that
    /// drew one instance counts under it; one that drew none is not counted.
    #[test]
    fn a_combined_instance_counts_under_each_part() {
        let mut tally = InstanceTally::default();
        tally.add(Some("steel_pan+baby_carrot"), true);
        tally.add(Some("copper_pan+baby_carrot"), false);
        tally.add(Some("tall_green"), true);
        tally.add(None, true);
        let rows: Vec<(String, usize, usize)> = tally.report().into_iter().map(|r| (r.instance, r.attempts, r.successes)).collect();
        assert_eq!(
            rows,
            [
                ("baby_carrot".to_owned(), 2, 1),
                ("copper_pan".to_owned(), 1, 0),
                ("steel_pan".to_owned(), 1, 1),
                ("tall_green".to_owned(), 1, 1)
            ]
        );
    }
}
