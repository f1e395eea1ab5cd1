//! The generate screen's model: the run form (what `mimicgen generate` takes, as a command line
//! and as a pipeline config), a run as its updates arrive, and the pairing of a failed attempt with
//! its nearest success.

use std::path::{Path, PathBuf};

use mimicgen_engine::RunStats;
use mimicgen_engine::coverage::Dimension;
use mimicgen_run::{CameraConfig, Report, RunConfig, RunInfo, SpecOverrides};

use crate::protocol::{AttemptRow, PreviewView};

/// The run form: what `mimicgen generate` takes (the source is the open file, with the subtask
/// ends it holds on disk).
#[derive(Debug, Clone, PartialEq)]
pub struct RunForm {
    /// Attempts to make (successes to reach with `guarantee`).
    pub attempts: usize,
    /// Keep attempting until `attempts` successes.
    pub guarantee: bool,
    /// Run seed.
    pub seed: u64,
    /// Worker threads.
    pub workers: usize,
    /// Also write failed attempts.
    pub keep_failed: bool,
    /// End an attempt at the first subtask that misses its signal.
    pub early_abort: bool,
    /// Output dataset.
    pub out: String,
    /// Replace existing outputs.
    pub overwrite: bool,
    /// Continue the interrupted run that left `<out>.partial` (a killed app, server or
    /// `generate`), with the arguments it was started with.
    pub resume: bool,
    /// Task variant (`None`: what the source file names).
    pub variant: Option<String>,
    /// The arm (`None`: the source demos').
    pub robot: Option<String>,
    /// Camera observations rendered into the dataset (`None`: none).
    pub cameras: Option<CameraConfig>,
    /// Spec fields set for this run over the task spec's.
    pub spec: SpecOverrides,
}

impl Default for RunForm {
    fn default() -> Self {
        Self {
            attempts: 50,
            guarantee: false,
            seed: 1,
            workers: 1,
            keep_failed: true,
            early_abort: false,
            out: "out/app_run.hdf5".to_owned(),
            overwrite: false,
            resume: false,
            variant: None,
            robot: None,
            cameras: None,
            spec: SpecOverrides::default(),
        }
    }
}

impl RunForm {
    /// The pipeline's config for a run over `source`. Every field of [`RunConfig`] is named, so
    /// a field the pipeline gains does not compile here until the form has it (or says why not).
    /// A two-arm source (`two_arm_task`: its task) names its task (the CLI runs two arms by
    /// `--task`) and leaves out what two-arm runs lack: failed attempts, early abort, resume,
    /// another robot, cameras, spec fields.
    #[must_use]
    pub fn config(&self, source: &Path, two_arm_task: Option<&str>) -> RunConfig {
        if let Some(task) = two_arm_task {
            let one_arm = Self {
                keep_failed: false,
                early_abort: false,
                resume: false,
                robot: None,
                cameras: None,
                spec: SpecOverrides::default(),
                ..self.clone()
            };
            return RunConfig { task: Some(task.to_owned()), ..one_arm.config(source, None) };
        }
        RunConfig {
            source: Some(source.to_path_buf()),
            out: PathBuf::from(&self.out),
            workers: self.workers.max(1),
            num_demos: Some(self.attempts),
            seed: Some(self.seed),
            keep_failed: self.keep_failed,
            guarantee: self.guarantee,
            early_abort: self.early_abort,
            overwrite: self.overwrite && !self.resume,
            variant: self.variant.clone(),
            robot: self.robot.clone(),
            cameras: self.cameras.clone(),
            spec: self.spec.clone(),
            // The task and its spec are the open file's; the app makes whole runs (no shards,
            // no attempt cap, no validation split).
            task: None,
            config: None,
            max_attempts: None,
            valid_fraction: None,
            resume: self.resume,
            shard: None,
            // Other action forms are a batch job's (`mimicgen generate --actions abs`).
            actions: Vec::new(),
        }
    }

    /// The `mimicgen generate` line that makes the same run (for a batch machine).
    #[must_use]
    pub fn command_line(&self, source: &Path, two_arm_task: Option<&str>) -> String {
        let quote = |s: &str| {
            if s.chars().all(|c| c.is_ascii_alphanumeric() || "/._-+=:,".contains(c)) {
                s.to_owned()
            } else {
                format!("'{}'", s.replace('\'', "'\\''"))
            }
        };
        let args: Vec<String> = self.config(source, two_arm_task).to_args().iter().map(|a| quote(a)).collect();
        format!("mimicgen generate {}", args.join(" "))
    }
}

/// The successful attempt whose initial objects are nearest `failed`'s (mean distance per object,
/// cm), preferring those that used the same source demo for the subtask that failed.
pub fn nearest_success<'a>(rows: &'a [AttemptRow], failed: &AttemptRow) -> Option<(&'a AttemptRow, f64)> {
    let distance = |r: &AttemptRow| {
        let pairs: Vec<f64> = failed
            .objects
            .iter()
            .filter_map(|o| {
                let p = r.objects.iter().find(|q| q.name == o.name)?;
                Some(((o.position[0] - p.position[0]).powi(2) + (o.position[1] - p.position[1]).powi(2)).sqrt())
            })
            .collect();
        #[allow(clippy::cast_precision_loss)]
        let mean = pairs.iter().sum::<f64>() / pairs.len().max(1) as f64;
        100.0 * mean
    };
    let source = failed.failed_subtask.and_then(|k| failed.sources.get(k).map(|d| (k, *d)));
    let same_source = |r: &&AttemptRow| source.is_none_or(|(k, d)| r.sources.get(k) == Some(&d));
    let candidates = |filter: &dyn Fn(&&AttemptRow) -> bool| {
        rows.iter().filter(|r| r.success).filter(|r| filter(r)).map(|r| (r, distance(r))).min_by(|a, b| a.1.total_cmp(&b.1))
    };
    candidates(&same_source).or_else(|| candidates(&|_| true))
}

/// The run doctor's panel: its settings, and the diagnosis as its updates arrive.
#[derive(Debug, Clone, PartialEq)]
pub struct DoctorState {
    /// Whether the panel is unfolded.
    pub shown: bool,
    /// Attempts to simulate in all (`mimicgen doctor --budget`).
    pub budget: usize,
    /// Suggestions to test (`--top`).
    pub top: usize,
    /// Whether the doctor is at work.
    pub running: bool,
    /// Every suggestion, ranked, once the doctor has read the run.
    pub suggestions: Vec<mimicgen_run::doctor::Suggestion>,
    /// Attempts per arm.
    pub attempts: usize,
    /// Per arm (the run's spec first): attempts decided and successes.
    pub progress: Vec<(usize, usize)>,
    /// The diagnosis, once done.
    pub diagnosis: Option<mimicgen_run::doctor::Diagnosis>,
    /// What stopped it, if something did.
    pub error: Option<String>,
}

impl Default for DoctorState {
    fn default() -> Self {
        Self {
            shown: false,
            budget: 200,
            top: 3,
            running: false,
            suggestions: Vec::new(),
            attempts: 0,
            progress: Vec::new(),
            diagnosis: None,
            error: None,
        }
    }
}

impl DoctorState {
    /// Attempts decided and to decide, over every arm.
    #[must_use]
    pub fn done_of(&self) -> (usize, usize) {
        (self.progress.iter().map(|p| p.0).sum(), self.attempts * self.progress.len())
    }
}

/// Two attempts of a run re-run to be seen side by side (a failure and the nearest success).
#[derive(Debug, Clone, PartialEq)]
pub struct SideBySide {
    /// The attempts: the failure, then the success.
    pub indices: [u64; 2],
    /// Both, executed, once the backend has them.
    pub views: Option<Box<[PreviewView; 2]>>,
}

/// A run started from the app, as its updates arrive.
#[derive(Debug, Clone, PartialEq)]
pub struct RunState {
    /// What was asked.
    pub config: RunConfig,
    /// The run as it started (task, variant, target).
    pub info: Option<RunInfo>,
    /// The task variant's reset region per object coordinate (for coverage).
    pub dimensions: Vec<Dimension>,
    /// Every decided attempt, in index order.
    pub rows: Vec<AttemptRow>,
    /// The report, once the run has ended.
    pub report: Option<Report>,
    /// The error that stopped it, if one did.
    pub error: Option<String>,
    /// Whether a cancel was asked for.
    pub cancelling: bool,
}

impl RunState {
    /// A run of `config` before its first update.
    #[must_use]
    pub fn new(config: RunConfig) -> Self {
        Self { config, info: None, dimensions: Vec::new(), rows: Vec::new(), report: None, error: None, cancelling: false }
    }

    /// Whether the run is still going.
    #[must_use]
    pub fn running(&self) -> bool {
        self.report.is_none() && self.error.is_none()
    }

    /// Statistics after the last decided attempt.
    #[must_use]
    pub fn stats(&self) -> Option<&RunStats> {
        self.rows.last().map(|r| &r.stats)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_run_form_is_a_generate_command_line_and_a_pipeline_config() {
        let form = RunForm { attempts: 30, seed: 7, workers: 2, guarantee: true, out: "my runs/out.hdf5".into(), ..RunForm::default() };
        let line = form.command_line(Path::new("/data/src.hdf5"), None);
        assert_eq!(
            line,
            "mimicgen generate --source /data/src.hdf5 --num-demos 30 --seed 7 --workers 2 --out 'my runs/out.hdf5' --keep-failed --guarantee"
        );
        let arm = RunForm { robot: Some("ur5e".into()), cameras: Some(CameraConfig::default()), ..form.clone() };
        assert!(arm.command_line(Path::new("s.hdf5"), None).contains("--robot ur5e --source s.hdf5"));
        assert_eq!(arm.config(Path::new("s.hdf5"), None).cameras, Some(CameraConfig::default()));
        let config = form.config(Path::new("/data/src.hdf5"), None);
        assert_eq!(
            (config.num_demos, config.seed, config.workers, config.guarantee, config.keep_failed),
            (Some(30), Some(7), 2, true, true)
        );
    }

    /// A two-arm source's run names its task (the CLI runs two arms by `--task`) and leaves out
    /// what two-arm runs lack, whatever the form holds from a one-arm file.
    #[test]
    fn a_two_arm_run_names_its_task_and_leaves_out_what_two_arm_runs_lack() {
        let form = RunForm {
            robot: Some("ur5e".into()),
            cameras: Some(CameraConfig::default()),
            early_abort: true,
            resume: true,
            spec: SpecOverrides { action_noise: vec![mimicgen_run::Scoped::all(0.1)], ..SpecOverrides::default() },
            ..RunForm::default()
        };
        let config = form.config(Path::new("two.hdf5"), Some("two_arm_lift"));
        assert_eq!(config.task.as_deref(), Some("two_arm_lift"));
        assert!(!config.keep_failed && !config.early_abort && !config.resume);
        assert_eq!((config.robot, config.cameras, config.spec), (None, None, SpecOverrides::default()));
        assert_eq!((config.num_demos, config.seed), (Some(form.attempts), Some(form.seed)));
        assert_eq!(
            form.command_line(Path::new("two.hdf5"), Some("two_arm_lift")),
            "mimicgen generate --task two_arm_lift --source two.hdf5 --num-demos 50 --seed 1 --workers 1 --out out/app_run.hdf5"
        );
    }
}
