//! Two-arm runs: scripted source demos and generation for robosuite's two-arm tasks
//! ([`TwoArmTask`]), written as robomimic datasets robosuite's own two-arm environments load
//! (`actions` (T, 14), `robot0_*` and `robot1_*` observations, `env_args` with both Pandas,
//! `datagen_info/<field>/<arm>` per arm).
//!
//! What the one-arm [`crate::Pipeline`] adds and this does not yet: resume, shards, the attempt
//! log, quality and doctor reports, failed-attempt files, cameras.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::mpsc;

use mimicgen_engine::EngineError;
use mimicgen_engine::RunStats;
use mimicgen_engine::demo::SourceDataset;
use mimicgen_engine::demonstrator::Style;
use mimicgen_engine::generate::FailureReason;
use mimicgen_engine::spec::SourceSelection;
use mimicgen_engine::two_arm::{
    TwoArmAttempt, TwoArmEnvironment as _, TwoArmGenerator, TwoArmHandoverScript, TwoArmLiftScript, TwoArmTransportScript,
};
use mimicgen_io::{DatasetWriter, DemoData, RobomimicDataset, WriterOptions};
use mimicgen_sim::two_arm::{TwoArmSimEnv, TwoArmTask};
use rand::SeedableRng as _;

use crate::{PipelineError, Report, RunConfig, RunInfo};

/// The arms' names in files (robosuite's observation prefixes without the `_`).
pub const ARMS: [&str; 2] = ["robot0", "robot1"];

/// The two-arm task named `name`, with a usage error naming `field` otherwise.
///
/// # Errors
/// [`PipelineError::Input`] for a name that is no two-arm task.
pub fn task(name: &str, variant: &str) -> Result<TwoArmTask, PipelineError> {
    let task = TwoArmTask::from_name(name).ok_or_else(|| {
        let known: Vec<&str> = TwoArmTask::ALL.iter().map(|t| t.name()).collect();
        PipelineError::input("", "--task", format!("{name:?} is no two-arm task (they are: {})", known.join(", ")))
    })?;
    if !task.variants().contains(&variant) {
        return Err(PipelineError::input("", "--variant", format!("{name} has variants {}, not {variant:?}", task.variants().join(", "))));
    }
    Ok(task)
}

/// Records `num_demos` scripted source demos of `task` in `variant` (seeded by `seed`), the
/// operators moving in `style`, into `out`, keeping those that succeed and that the task's spec splits into both arms' subtasks;
/// `log` gets a line per try. Returns the file and the number of tries.
///
/// # Errors
/// Simulator and write failures; [`PipelineError::Input`] (field `--num-demos`) when fewer than
/// one try in ten succeeds.
pub fn record_demos(
    task: TwoArmTask,
    variant: &str,
    style: Style,
    num_demos: usize,
    seed: u64,
    out: &Path,
    log: &mut dyn FnMut(&str),
) -> Result<(PathBuf, usize), PipelineError> {
    let scene = Arc::new(task.scene()?);
    let mut env = TwoArmSimEnv::new(Arc::clone(&scene), task, variant)?;
    let spec = task.spec().map_err(|e| PipelineError::engine("bundled spec", e))?;
    let xml = mimicgen_sim::assets::portable_asset_paths(env.model_xml());
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let options = WriterOptions { env_args: Some(task.env_args()), compress_obs: false, valid_fraction: None, split_seed: 0 };
    let mut writer = DatasetWriter::create(out, options)?;
    let mut tries = 0;
    while writer.len() < num_demos {
        tries += 1;
        if tries > 10 * num_demos.max(1) {
            return Err(PipelineError::input(
                "",
                "--num-demos",
                format!("the scripted demonstrator made only {} usable demos in {} tries", writer.len(), tries - 1),
            ));
        }
        env.reset(&mut rng).map_err(|e| PipelineError::engine("", EngineError::Env { attempt: 0, source: e }))?;
        let demo = match task {
            TwoArmTask::Lift => TwoArmLiftScript::pot().record(&mut env, style, &mut rng),
            TwoArmTask::Handover => TwoArmHandoverScript::hammer().record(&mut env, style, &mut rng),
            TwoArmTask::Transport => TwoArmTransportScript::transport().record(&mut env, style, &mut rng),
        }
        .map_err(|e| PipelineError::engine("", EngineError::Env { attempt: 0, source: e }))?;
        if !demo.success {
            log(&format!("try {tries}: failed ({}); discarded", env.unmet_success().unwrap_or_default()));
            continue;
        }
        let sources = demo.arm_views("demo").into_iter().map(|d| SourceDataset { demos: vec![d], env_args: None }).collect();
        if let Err(e) = TwoArmGenerator::new(spec.clone(), sources) {
            log(&format!("try {tries}: succeeded but is no usable source demo ({e}); discarded"));
            continue;
        }
        let mut data = DemoData::from_two_arm_attempt(&demo, &ARMS, BTreeMap::new(), Some(xml.clone()));
        (data.attempt_index, data.src_demo_labels) = (None, Vec::new());
        let name = writer.append(&data)?;
        log(&format!("{name}: {} steps", demo.actions.len()));
    }
    Ok((writer.finish()?, tries))
}

/// A two-arm generation run.
#[derive(Debug, Clone, PartialEq)]
pub struct TwoArmRun {
    /// The task.
    pub task: TwoArmTask,
    /// The variant new scenes are drawn from.
    pub variant: String,
    /// Two-arm source demos (`datagen_info/<field>/robot0` and `robot1`); `None`: the bundled.
    pub source: Option<PathBuf>,
    /// The dataset to write.
    pub out: PathBuf,
    /// Attempts to run; with `guarantee`, successes to reach.
    pub num_trials: usize,
    /// Keep attempting until `num_trials` successes (at most `max_attempts` attempts).
    pub guarantee: bool,
    /// The cap on attempts with `guarantee` (`None`: 100 x `num_trials`).
    pub max_attempts: Option<usize>,
    /// Put this fraction of the demos, drawn with the seed, in `mask/valid` (the rest in
    /// `mask/train`); `None` writes no masks.
    pub valid_fraction: Option<f64>,
    /// The run's seed (attempt `i` draws from its own stream of it).
    pub seed: u64,
    /// Worker threads, each with its own simulator.
    pub workers: usize,
    /// Replace existing outputs (the dataset, its `.partial` and its report).
    pub overwrite: bool,
}

impl TwoArmRun {
    /// The two-arm run `config` asks for: its task named by `config.task` or, without one, by the
    /// source file's `env_args`; or why it cannot be made.
    ///
    /// # Errors
    /// [`PipelineError::Input`] naming the fields two-arm runs lack (`--resume`, ...), a task that
    /// is no two-arm task, a variant the task lacks.
    pub fn from_config(config: &RunConfig) -> Result<Self, PipelineError> {
        let lacking: Vec<&str> = [
            (config.config.is_some(), "--config"),
            (config.robot.is_some(), "--robot"),
            (config.cameras.is_some(), "--cameras"),
            (config.resume, "--resume"),
            (config.shard.is_some(), "--shard"),
            (config.keep_failed, "--keep-failed"),
            (config.early_abort, "--early-abort"),
            (!config.actions.is_empty(), "--actions"),
            (!config.spec.is_empty(), "spec fields (--action-noise, ...)"),
        ]
        .into_iter()
        .filter_map(|(set, flag)| set.then_some(flag))
        .collect();
        let name = match (&config.task, &config.source) {
            (Some(name), _) => name.clone(),
            (None, Some(source)) => RobomimicDataset::open(source)?
                .env_args()
                .and_then(TwoArmTask::from_env_args)
                .map(|t| t.name().to_owned())
                .ok_or_else(|| PipelineError::input(source.display().to_string(), "data attribute env_args", "names no two-arm task"))?,
            (None, None) => return Err(PipelineError::input("", "task", "a two-arm run needs its task or a two-arm source file")),
        };
        let variant = config.variant.clone().unwrap_or_else(|| "D0".to_owned());
        let task = task(&name, &variant)?;
        if !lacking.is_empty() {
            return Err(PipelineError::input("", lacking.join(", "), format!("not available for two-arm tasks ({name}) yet")));
        }
        Ok(Self {
            task,
            variant,
            source: config.source.clone(),
            out: config.out.clone(),
            num_trials: config.num_demos.unwrap_or(100),
            guarantee: config.guarantee,
            max_attempts: config.max_attempts,
            valid_fraction: config.valid_fraction,
            seed: config.seed.unwrap_or(1),
            workers: config.workers.max(1),
            overwrite: config.overwrite,
        })
    }

    /// The run as it starts, as a one-arm run reports itself, with `num_sources` source demos.
    #[must_use]
    pub fn info(&self, num_sources: usize) -> RunInfo {
        RunInfo {
            task: self.task.name().to_owned(),
            variant: self.variant.clone(),
            source: self.source.clone().unwrap_or_default(),
            num_sources,
            workers: self.workers,
            seed: self.seed,
            spec_overrides: crate::SpecOverrides::default(),
            target: self.num_trials,
            guarantee: self.guarantee,
            resumed_from: 0,
        }
    }
}

/// What a two-arm run did.
#[derive(Debug, Clone, PartialEq)]
pub struct TwoArmSummary {
    /// Attempts run.
    pub attempts: usize,
    /// Successes written.
    pub successes: usize,
    /// Failed attempts by where and why (`arm 0: subtask 0: signal "grasp_handle0" never
    /// turned on`, `task not achieved`).
    pub failures: BTreeMap<String, usize>,
    /// The dataset written.
    pub out: PathBuf,
    /// The source demos used.
    pub source: PathBuf,
    /// How many source demos.
    pub num_sources: usize,
    /// The run's statistics, subtasks numbered through both arms (arm 0's, then arm 1's).
    pub stats: RunStats,
    /// Subtasks per arm (how `stats` numbers them).
    pub subtask_counts: Vec<usize>,
    /// Control steps simulated (failed attempts included).
    pub control_steps: usize,
    /// Whether the run was cancelled before its stopping rule (the dataset holds the attempts
    /// decided before).
    pub cancelled: bool,
}

impl TwoArmSummary {
    /// The run's report (`<out>.json`), the one-arm runs' [`Report`]: its subtasks numbered
    /// through both arms ([`Self::subtask_counts`]); no failed-attempt file, quality or causes yet.
    #[must_use]
    pub fn report(&self, run: &TwoArmRun, wall_time_s: f64) -> Report {
        #[allow(clippy::cast_precision_loss, reason = "counts far below 2^52")]
        let attempts_per_s = if wall_time_s > 0.0 { self.attempts as f64 / wall_time_s } else { 0.0 };
        Report {
            task: run.task.name().to_owned(),
            variant: run.variant.clone(),
            seed: run.seed,
            workers: run.workers,
            source: self.source.display().to_string(),
            config: None,
            robot: None,
            output: self.out.display().to_string(),
            failed_output: None,
            attempts: self.stats.attempts,
            successes: self.stats.successes,
            generation_rate: self.stats.rate(),
            wall_time_s,
            attempts_per_s,
            control_steps: self.control_steps,
            per_source_demo: crate::outputs::per_source_demo(&self.stats),
            per_subtask_source: crate::outputs::per_subtask_source(&self.stats),
            never_succeeded: crate::outputs::never_succeeded(&self.stats),
            per_object_instance: Vec::new(),
            peak_rss_mib: crate::memory::peak_rss_mib(),
            failures: crate::outputs::failures(&self.stats),
            causes: Vec::new(),
            cancelled: self.cancelled,
            resumed_from: 0,
            early_abort: false,
            spec_overrides: crate::SpecOverrides::default(),
            shard: None,
            quality: None,
            transit: mimicgen_engine::generate::TransitTotals::default(),
        }
    }
}

/// What a two-arm run reports as it goes.
#[derive(Debug)]
pub enum TwoArmEvent<'a> {
    /// The run is about to start: its spec and its source demos' names.
    Started {
        /// The spec (the run's seed and trials in it).
        spec: &'a mimicgen_engine::two_arm::TwoArmSpec,
        /// The source demos, in file order.
        source_names: &'a [String],
    },
    /// An attempt was decided (in index order).
    Attempt {
        /// The attempt.
        attempt: &'a TwoArmAttempt,
        /// Attempts decided so far.
        attempts: usize,
        /// Successes among them.
        successes: usize,
        /// The run's statistics with it (subtasks numbered through both arms).
        stats: &'a RunStats,
        /// The demo it was written as, if it was.
        written: Option<&'a str>,
        /// Subtasks per arm (how `stats` numbers them: arm 0's, then arm 1's).
        subtask_counts: &'a [usize],
    },
}

/// One finished attempt, with what the writer needs of it.
type Finished = (u64, Result<(TwoArmAttempt, Option<DemoData>), PipelineError>);

/// Runs `run`: attempts in order of index spread over the workers, successes written in that
/// order (the same dataset for the same seed whatever the number of workers); with `guarantee`,
/// until `num_trials` successes; `progress` hears of the start and of each attempt, in index
/// order. Once `cancel` is set no attempt starts; those decided are written and the dataset
/// finished.
///
/// # Errors
/// Unreadable sources, a spec they do not fit, simulator or write failures.
pub fn generate(run: &TwoArmRun, cancel: &AtomicBool, progress: &mut dyn FnMut(TwoArmEvent<'_>)) -> Result<TwoArmSummary, PipelineError> {
    crate::clear_outputs(&run.out, None, run.overwrite, false)?;
    let source = match &run.source {
        Some(path) => path.clone(),
        None => crate::bundled::source_demos(run.task.name())?,
    };
    let file = source.display().to_string();
    let dataset = RobomimicDataset::open(&source)?;
    let views = dataset.to_arm_source_datasets(&SourceSelection::default(), &ARMS)?;
    let num_sources = views.first().map_or(0, |v| v.demos.len());
    let source_names: Vec<String> = views.first().map(|v| v.demos.iter().map(|d| d.name.clone()).collect()).unwrap_or_default();
    let mut spec = run.task.spec().map_err(|e| PipelineError::engine("bundled spec", e))?;
    spec.generation.seed = run.seed;
    spec.generation.num_trials = run.num_trials;
    spec.generation.guarantee = run.guarantee;
    spec.generation.max_attempts = run.max_attempts.unwrap_or(0);
    let cap = spec.generation.attempt_cap();
    let target = if run.guarantee { run.num_trials } else { usize::MAX };
    let subtask_counts: Vec<usize> = spec.arms.iter().map(|a| a.subtasks.len()).collect();
    let generator = TwoArmGenerator::new(spec, views).map_err(|e| PipelineError::engine(file.clone(), e))?;
    progress(TwoArmEvent::Started { spec: generator.spec(), source_names: &source_names });
    let scene = Arc::new(run.task.scene()?);
    let xml = mimicgen_sim::assets::portable_asset_paths(&scene.xml);
    let options =
        WriterOptions { env_args: Some(run.task.env_args()), compress_obs: true, valid_fraction: run.valid_fraction, split_seed: run.seed };
    let mut writer = DatasetWriter::create(&run.out, options)?;
    let next = AtomicUsize::new(0);
    let stop = AtomicBool::new(false);
    let (tx, rx) = mpsc::channel::<Finished>();
    let mut summary = TwoArmSummary {
        attempts: 0,
        successes: 0,
        failures: BTreeMap::new(),
        out: run.out.clone(),
        source,
        num_sources,
        stats: RunStats::new(num_sources),
        subtask_counts,
        control_steps: 0,
        cancelled: false,
    };
    let written: Result<(), PipelineError> = std::thread::scope(|scope| {
        for _ in 0..run.workers.max(1) {
            let (tx, scene, generator, next, stop) = (tx.clone(), Arc::clone(&scene), &generator, &next, &stop);
            let (task, variant, xml) = (run.task, run.variant.as_str(), xml.as_str());
            scope.spawn(move || {
                let mut env = match TwoArmSimEnv::new(scene, task, variant) {
                    Ok(env) => env,
                    Err(e) => {
                        let _ = tx.send((0, Err(e.into())));
                        return;
                    }
                };
                loop {
                    let index = next.fetch_add(1, Ordering::Relaxed);
                    if index >= cap || stop.load(Ordering::Relaxed) || cancel.load(Ordering::Relaxed) {
                        return;
                    }
                    let index = u64::try_from(index).unwrap_or(u64::MAX);
                    let result = attempt(generator, &mut env, index, xml);
                    if tx.send((index, result)).is_err() {
                        return;
                    }
                }
            });
        }
        drop(tx);
        // Attempts come back in any order; they are written in index order.
        let mut pending: BTreeMap<u64, Result<(TwoArmAttempt, Option<DemoData>), PipelineError>> = BTreeMap::new();
        let mut expected = 0_u64;
        for (index, result) in rx {
            pending.insert(index, result);
            while let Some(result) = pending.remove(&expected) {
                expected += 1;
                let (attempt, data) = match result {
                    Ok(done) => done,
                    Err(e) => {
                        stop.store(true, Ordering::Relaxed);
                        return Err(e);
                    }
                };
                summary.attempts += 1;
                summary.control_steps += attempt.actions.len();
                attempt.record_into(&mut summary.stats, &summary.subtask_counts);
                let mut written = None;
                match (&attempt.failure, data) {
                    (None, Some(data)) => {
                        written = Some(writer.append(&data)?);
                        summary.successes += 1;
                    }
                    (Some(failure), _) => {
                        let key = match &failure.reason {
                            FailureReason::TaskNotAchieved { .. } => "task not achieved".to_owned(),
                            FailureReason::Unstable { .. } => failure.arm.map_or_else(
                                || "simulation unstable".to_owned(),
                                |arm| format!("arm {arm}: subtask {}: simulation unstable", failure.subtask),
                            ),
                            _ => failure.to_string(),
                        };
                        *summary.failures.entry(key).or_default() += 1;
                    }
                    (None, None) => {}
                }
                progress(TwoArmEvent::Attempt {
                    attempt: &attempt,
                    attempts: summary.attempts,
                    successes: summary.successes,
                    stats: &summary.stats,
                    written: written.as_deref(),
                    subtask_counts: &summary.subtask_counts,
                });
                // With `guarantee`, the first `num_trials` successes in index order, whatever
                // the workers ran ahead.
                if summary.successes >= target {
                    stop.store(true, Ordering::Relaxed);
                    return Ok(());
                }
            }
        }
        Ok(())
    });
    written?;
    writer.finish()?;
    summary.cancelled = cancel.load(Ordering::Relaxed) && summary.attempts < cap && summary.successes < target;
    Ok(summary)
}

/// Runs attempt `index` and, for a success, its demo with robosuite's observations.
fn attempt(
    generator: &TwoArmGenerator,
    env: &mut TwoArmSimEnv,
    index: u64,
    xml: &str,
) -> Result<(TwoArmAttempt, Option<DemoData>), PipelineError> {
    let attempt = generator.attempt(env, index).map_err(|e| PipelineError::engine("", e))?;
    if !attempt.success {
        return Ok((attempt, None));
    }
    let obs = env
        .observations_for_states(&attempt.states)
        .map_err(|e| PipelineError::engine("", EngineError::Env { attempt: index, source: e }))?;
    let data = DemoData::from_two_arm_attempt(&attempt, &ARMS, obs, Some(xml.to_owned()));
    Ok((attempt, Some(data)))
}

/// Runs `run` as [`generate`] does and writes its report (`<out>.json`, the one-arm runs'
/// [`Report`]); returns both.
///
/// # Errors
/// As [`generate`]; a report that cannot be written.
pub fn run_and_report(
    run: &TwoArmRun,
    cancel: &AtomicBool,
    progress: &mut dyn FnMut(TwoArmEvent<'_>),
) -> Result<(TwoArmSummary, Report), PipelineError> {
    let started = std::time::Instant::now();
    let summary = generate(run, cancel, progress)?;
    let report = summary.report(run, started.elapsed().as_secs_f64());
    let path = crate::sibling(&run.out, "", "json");
    std::fs::write(&path, serde_json::to_string_pretty(&report).unwrap_or_default())
        .map_err(|e| PipelineError::Fs { file: path.display().to_string(), reason: e.to_string() })?;
    Ok((summary, report))
}
