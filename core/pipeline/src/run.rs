//! A prepared run and its execution: workers, observations, writers, progress, report.

use std::collections::BTreeMap;
use std::ops::ControlFlow;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::time::Instant;

use mimicgen_engine::demo::initial_object_poses;
use mimicgen_engine::image::ImageStream;
use mimicgen_engine::{Attempt, EngineError, Environment, Generator, RunControl, RunStats};
use mimicgen_io::{DatasetWriter, DemoData, Observation, WriterOptions};
use mimicgen_sim::camera::Cameras;
use mimicgen_sim::{Scene, SimEnv, Task};

use crate::config::{Resolved, output_env_args, resolve};
use crate::{ActionForm, Outcome, PipelineError, Report, RunConfig, RunInfo};

use crate::events::{AttemptEvent, Event};

/// The control period of every task (robosuite's `control_freq` 20 Hz), s.
const CONTROL_PERIOD_S: f64 = 0.05;
/// Bins per object coordinate of the quality report's coverage (the paper's and the app's).
const COVERAGE_BINS: usize = 3;
/// Demos of a written dataset the quality report replays.
pub const QUALITY_REPLAYS: usize = 3;
use crate::outputs::{
    AttemptLog, AttemptRecord, PROGRESS_ATTR, Progress, RUN_ATTR, RunDescription, attempt_log_path, causes, clear_outputs,
    differing_fields, failed_path, failures, never_succeeded, per_source_demo, per_subtask_source, sibling,
};

/// What a worker makes of an attempt that may be kept: its observations, camera images, and the
/// episode's `model_file` where the simulator has one.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Observed {
    /// Low-dim observations by key.
    pub obs: BTreeMap<String, Observation>,
    /// Camera observations by key (`agentview_image`).
    pub images: BTreeMap<String, ImageStream>,
    /// The episode's scene XML.
    pub model_xml: Option<String>,
    /// The actions in the other forms the run asked for, by dataset key (`actions_abs`).
    pub other_actions: BTreeMap<String, mimicgen_engine::Rows>,
}

/// A run ready to go: inputs read and checked, scene compiled, task resolved.
pub struct Pipeline {
    config: RunConfig,
    task: Arc<dyn Task>,
    variant: String,
    source_path: PathBuf,
    generator: Generator,
    scene: Arc<Scene>,
    /// The scene's MJCF with portable asset paths: each demo's `model_file` starts from it.
    scene_xml: String,
    /// The variant's object instances, `(label, scene)`, one drawn per episode (the paper's
    /// object transfer); empty for the others.
    instances: Vec<(String, Arc<Scene>)>,
    env_args: String,
    description: RunDescription,
    /// The cameras rendered into every kept demo (`config.cameras`).
    cameras: Option<Cameras>,
}

impl std::fmt::Debug for Pipeline {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Pipeline").field("task", &self.task.name()).field("variant", &self.variant).field("config", &self.config).finish()
    }
}

impl Pipeline {
    /// Reads and checks every input of `config`: works out the task and variant, loads the spec
    /// and the source demos, refuses sources recorded with another controller, compiles the
    /// scene and parses the segments.
    ///
    /// # Errors
    /// [`PipelineError`] naming the file and field at fault.
    pub fn prepare(config: &RunConfig) -> Result<Self, PipelineError> {
        Self::prepare_with_ends(config, &BTreeMap::new())
    }

    /// [`Pipeline::prepare`] with hand-set subtask ends (exclusive, per demo name) in place of the
    /// signals of the demos `ends` names (the app's annotations, before they are saved).
    ///
    /// # Errors
    /// As [`Pipeline::prepare`]; ends naming a demo the file lacks are an input error.
    pub fn prepare_with_ends(config: &RunConfig, ends: &BTreeMap<String, Vec<usize>>) -> Result<Self, PipelineError> {
        if config.workers == 0 {
            return Err(PipelineError::input("", "--workers", "must be at least 1"));
        }
        if let Some(f) = config.valid_fraction
            && !(0.0..=1.0).contains(&f)
        {
            return Err(PipelineError::input("", "--valid-fraction", format!("must be between 0 and 1, got {f}")));
        }
        let Resolved { task, variant, spec, spec_file, source_path, dataset } = resolve(config)?;
        let source_label = source_path.display().to_string();
        let mut sources = dataset.to_source_dataset(&spec.source)?;
        drop(dataset);
        for (name, demo_ends) in ends {
            let demo = sources.demos.iter_mut().find(|d| &d.name == name).ok_or_else(|| {
                PipelineError::input(source_label.clone(), "subtask ends", format!("names demo {name:?}, which the file does not have"))
            })?;
            demo.manual_subtask_ends = Some(demo_ends.clone());
        }
        let model_xml = sources.demos.first().and_then(|d| d.sim.model_xml.clone());
        let robot = config
            .robot
            .as_deref()
            .map(mimicgen_sim::robot::robot)
            .transpose()
            .map_err(|reason| PipelineError::input("", "robot", reason))?;
        // Object transfer: the variant's own objects, composed with the arm, not the sources' scene.
        let instances: Vec<(String, Arc<Scene>)> = Scene::instances_for_task(task.as_ref(), robot.unwrap_or(&mimicgen_sim::robot::PANDA))?
            .into_iter()
            .map(|(label, scene)| (label, Arc::new(scene)))
            .collect();
        if instances.len() > 1 && config.cameras.is_some() {
            return Err(PipelineError::input(
                "",
                "cameras",
                format!(
                    "{} {variant} draws one of {} objects per episode; cameras are not supported there yet",
                    task.name(),
                    instances.len()
                ),
            ));
        }
        let composed = |(scene, xml): (Scene, String)| (Arc::new(scene), xml);
        let (scene, xml) = match (model_xml, robot) {
            // The first instance's scene, compiled above, is the run's scene.
            _ if let Some((_, first)) = instances.first() => (Arc::clone(first), first.xml.clone()),
            // Another arm than the sources': the task's scene composed with it (robot transfer).
            (Some(xml), Some(robot)) if robot.arm_joints.first().is_some_and(|joint| !xml.contains(&format!("\"{joint}\""))) => {
                composed(Scene::for_task_with_robot(task.as_ref(), robot)?)
            }
            // A variant with objects the sources' scene lacks (C0's clutter): the task's scene.
            (Some(xml), robot) if task.objects().iter().any(|(_, body)| !xml.contains(&format!("name=\"{body}\""))) => {
                composed(Scene::for_task_with_robot(task.as_ref(), robot.unwrap_or(&mimicgen_sim::robot::PANDA))?)
            }
            (Some(xml), _) => (Arc::new(Scene::from_model_file(&xml, &format!("{source_label} (model_file)"), task.as_ref())?), xml),
            (None, robot) => composed(Scene::for_task_with_robot(task.as_ref(), robot.unwrap_or(&mimicgen_sim::robot::PANDA))?),
        };
        let scene_xml = mimicgen_sim::assets::portable_asset_paths(&xml);
        let env_args = output_env_args(sources.env_args.as_deref(), task.as_ref(), &variant, &scene, config.cameras.as_ref());
        crate::config::check_spec_names(&spec, spec_file.as_deref(), task.name(), &sources)?;
        let generator = Generator::new(spec.clone(), sources).map_err(|e| PipelineError::engine(source_label.clone(), e))?;
        let bytes = std::fs::read(&source_path).map_err(|e| PipelineError::Fs { file: source_label.clone(), reason: e.to_string() })?;
        let description = RunDescription {
            task: task.name().to_owned(),
            variant: variant.clone(),
            source: source_label,
            source_fingerprint: mimicgen_engine::fingerprint::fnv1a_hex(&bytes),
            spec,
            valid_fraction: config.valid_fraction,
            shard: config.shard,
            cameras: config.cameras.clone(),
            robot: (scene.robot.model.name != mimicgen_sim::robot::PANDA.name).then(|| scene.robot.model.name.to_owned()),
            actions: config.actions.clone(),
        };
        let cameras = config.cameras.clone().map(|c| Cameras::new(&scene, c)).transpose()?;
        Ok(Self {
            config: config.clone(),
            task,
            variant,
            source_path,
            generator,
            scene,
            scene_xml,
            instances,
            env_args,
            description,
            cameras,
        })
    }

    /// A simulator of the run's scene (and of its object instances, where the variant draws one
    /// per episode): one per worker.
    #[must_use]
    pub fn env(&self) -> SimEnv {
        SimEnv::new(Arc::clone(&self.scene), Arc::clone(&self.task)).with_instances(self.instances.clone())
    }

    /// The task.
    #[must_use]
    pub fn task(&self) -> &Arc<dyn Task> {
        &self.task
    }

    /// The variant new scenes are drawn from.
    #[must_use]
    pub fn variant(&self) -> &str {
        &self.variant
    }

    /// The generator (spec, source demos, segmentation).
    #[must_use]
    pub fn generator(&self) -> &Generator {
        &self.generator
    }

    /// The cameras the run renders into every kept demo (`None` without `cameras` in the config).
    #[must_use]
    pub fn cameras(&self) -> Option<&Cameras> {
        self.cameras.as_ref()
    }

    /// The compiled scene every worker simulates.
    #[must_use]
    pub fn scene(&self) -> &Arc<Scene> {
        &self.scene
    }

    /// The source demo file.
    #[must_use]
    pub fn source_path(&self) -> &Path {
        &self.source_path
    }

    /// The `env_args` the outputs carry: the controller and environment generation used.
    #[must_use]
    pub fn env_args(&self) -> &str {
        &self.env_args
    }

    /// The config this pipeline was prepared from.
    #[must_use]
    pub fn config(&self) -> &RunConfig {
        &self.config
    }

    /// The failed-attempts file of this run.
    #[must_use]
    pub fn failed_path(&self) -> PathBuf {
        failed_path(&self.config.out)
    }

    /// The report file of this run.
    #[must_use]
    pub fn report_path(&self) -> PathBuf {
        sibling(&self.config.out, "", "json")
    }

    /// The attempt log of this run.
    #[must_use]
    pub fn attempt_log_path(&self) -> PathBuf {
        attempt_log_path(&self.config.out)
    }

    fn writer_options(&self) -> WriterOptions {
        WriterOptions {
            env_args: Some(self.env_args.clone()),
            compress_obs: true,
            valid_fraction: self.config.valid_fraction,
            split_seed: self.generator.spec().generation.seed,
        }
    }

    /// Opens the writers: fresh ones, or (with `resume`) those of the interrupted run, checked to
    /// describe the same dataset. Returns them with the progress to go on from and the log of
    /// the attempts before it.
    fn open_writers(&self) -> Result<Opened, PipelineError> {
        let out = &self.config.out;
        let failed = self.failed_path();
        let keep_failed = self.generator.spec().generation.keep_failed;
        let options = self.writer_options();
        let failed_options = WriterOptions { valid_fraction: None, ..options.clone() };
        let description =
            serde_json::to_string(&self.description).map_err(|e| PipelineError::input("", "run description", e.to_string()))?;
        let partial = DatasetWriter::partial_path(out);
        // A progress the interrupted run could not finish writing (a disk that filled as HDF5 put it
        // down leaves its attribute pointing past the file's end): the run starts again from its
        // first attempt, into fresh files, and makes the same dataset.
        if self.config.resume {
            let stored = DatasetWriter::partial_root_attrs(out, &[RUN_ATTR, PROGRESS_ATTR])?;
            let file = partial.display().to_string();
            let [Some(stored_run), progress] = stored.as_slice() else {
                return Err(PipelineError::input(
                    file,
                    RUN_ATTR,
                    "this file holds no run description; it was not written by a resumable run",
                ));
            };
            let stored_run: serde_json::Value =
                serde_json::from_str(stored_run).map_err(|e| PipelineError::input(file.clone(), RUN_ATTR, e.to_string()))?;
            let ours: serde_json::Value = serde_json::to_value(&self.description).unwrap_or_default();
            if stored_run != ours {
                let differing = differing_fields(&ours, &stored_run);
                return Err(PipelineError::input(
                    file,
                    RUN_ATTR,
                    format!(
                        "the interrupted run made a different dataset ({} differ); resume with the arguments it was started with, or replace the outputs to start over",
                        differing.join(", ")
                    ),
                ));
            }
            let Some(progress) = progress else {
                return self.fresh_writers(&description, true);
            };
            let progress: Progress =
                serde_json::from_str(progress).map_err(|e| PipelineError::input(file, PROGRESS_ATTR, e.to_string()))?;
            let next = progress.next_attempt as u64;
            let writer = DatasetWriter::resume(out, options, next)?;
            let failed_writer = if keep_failed {
                // A run killed while finishing may have finished its failed attempts' file but
                // not the dataset (whose rename commits the run): that file goes on.
                let failed_partial = DatasetWriter::partial_path(&failed);
                if !failed_partial.is_file() && failed.is_file() {
                    std::fs::rename(&failed, &failed_partial)
                        .map_err(|e| PipelineError::Fs { file: failed.display().to_string(), reason: e.to_string() })?;
                }
                Some(if failed_partial.is_file() {
                    DatasetWriter::resume(&failed, failed_options, next)?
                } else {
                    DatasetWriter::create(&failed, failed_options)?
                })
            } else {
                None
            };
            let (log, records) = AttemptLog::resume(self.attempt_log_path(), progress.next_attempt)?;
            return Ok(Opened { writer, failed_writer, progress, log, records });
        }
        self.fresh_writers(&description, self.config.overwrite)
    }

    /// New writers for a run from its first attempt, the outputs there replaced if `replace`.
    fn fresh_writers(&self, description: &str, replace: bool) -> Result<Opened, PipelineError> {
        let out = &self.config.out;
        let failed = self.failed_path();
        let keep_failed = self.generator.spec().generation.keep_failed;
        let options = self.writer_options();
        let failed_options = WriterOptions { valid_fraction: None, ..options.clone() };
        let log_path = self.attempt_log_path();
        clear_outputs(out, Some(&log_path), replace, true)?;
        let mut writer = DatasetWriter::create(out, options)?;
        let progress = Progress { next_attempt: 0, failures_kept: 0, stats: RunStats::new(self.generator.dataset().demos.len()) };
        writer.set_root_attr(RUN_ATTR, description)?;
        writer.set_root_attr(PROGRESS_ATTR, &serde_json::to_string(&progress).unwrap_or_default())?;
        let failed_writer = if keep_failed { Some(DatasetWriter::create(&failed, failed_options)?) } else { None };
        let log = AttemptLog::create(log_path)?;
        Ok(Opened { writer, failed_writer, progress, log, records: Vec::new() })
    }

    /// Runs generation: `workers` threads each simulate attempts and compute the observations of
    /// the ones that will be kept; this thread writes them in attempt order, commits the progress
    /// after each, and reports every step to `on_event`. Setting `cancel` stops after the attempts
    /// already decided; the outputs are then finished as complete, valid datasets.
    ///
    /// An error (or a killed process) leaves `<out>.partial`, which a run with `resume` continues:
    /// the finished dataset then equals an uninterrupted run's.
    ///
    /// # Errors
    /// [`PipelineError`] for outputs that exist, fatal simulator errors and write failures.
    pub fn run(&self, cancel: &AtomicBool, on_event: impl FnMut(&Event)) -> Result<Report, PipelineError> {
        let mut envs: Vec<SimEnv> = (0..self.config.workers).map(|_| self.env()).collect();
        let cameras = self.cameras.as_ref();
        // On the workers: observations, camera images and the episode's model_file.
        let observe = |env: &mut SimEnv, attempt: &Attempt| -> Result<Observed, EngineError> {
            let initial = initial_object_poses(&attempt.trajectory.object_poses);
            env.place_fixed_objects(&initial);
            let env_error = |e| EngineError::Env { attempt: attempt.index, source: e };
            let mut other_actions = BTreeMap::new();
            for form in &self.config.actions {
                let rows = match form {
                    ActionForm::Abs => env.absolute_actions(&attempt.trajectory.states, &attempt.trajectory.actions),
                    ActionForm::Joint => env.joint_actions(&attempt.trajectory.states, &attempt.trajectory.actions),
                };
                other_actions.insert(form.key().to_owned(), rows.map_err(env_error)?);
            }
            let obs = env.observations_for_states(&attempt.trajectory.states).map_err(env_error)?;
            let images = match cameras {
                Some(cameras) => env.images_for_states(&attempt.trajectory.states, cameras).map_err(env_error)?,
                None => BTreeMap::new(),
            };
            // The instance's own scene where the variant draws one per episode.
            let instance_xml = env.instance().map(|_| mimicgen_sim::assets::portable_asset_paths(&env.physics().scene().xml));
            let xml = env
                .physics()
                .scene()
                .xml_with_fixed_objects(instance_xml.as_deref().unwrap_or(&self.scene_xml), &initial)
                .map_err(|e| EngineError::Io { path: "model_file".to_owned(), reason: e.to_string() })?;
            Ok(Observed { obs, images, model_xml: Some(xml), other_actions })
        };
        self.run_envs(&mut envs, observe, cancel, on_event, true)
    }

    /// [`Pipeline::run`] on other simulators (one driven from Python, say), one per worker:
    /// `observe` makes the observations (and `model_file`) of each attempt that may be kept, on
    /// the worker that ran it. Writers, resume, shards, events and report are `run`'s.
    ///
    /// The quality report replays no demo: they were made in another simulator.
    ///
    /// # Errors
    /// As [`Pipeline::run`].
    pub fn run_on<E: Environment + Send>(
        &self,
        envs: &mut [E],
        observe: impl Fn(&mut E, &Attempt) -> Result<Observed, EngineError> + Sync,
        cancel: &AtomicBool,
        on_event: impl FnMut(&Event),
    ) -> Result<Report, PipelineError> {
        self.run_envs(envs, observe, cancel, on_event, false)
    }

    /// [`Pipeline::run_on`]; with `replay`, the quality report replays a sample of the written
    /// demos in this pipeline's simulator.
    fn run_envs<E: Environment + Send>(
        &self,
        envs: &mut [E],
        observe: impl Fn(&mut E, &Attempt) -> Result<Observed, EngineError> + Sync,
        cancel: &AtomicBool,
        mut on_event: impl FnMut(&Event),
        replay: bool,
    ) -> Result<Report, PipelineError> {
        if let Some(report) = self.report_of_a_finished_run()? {
            on_event(&Event::Finished(Box::new(report.clone())));
            return Ok(report);
        }
        let Opened { mut writer, mut failed_writer, progress, mut log, records } = self.open_writers()?;
        let settings = &self.generator.spec().generation;
        let resumed_from = progress.next_attempt;
        let mut failures_kept = progress.failures_kept;
        on_event(&Event::Started(Box::new(RunInfo {
            task: self.task.name().to_owned(),
            variant: self.variant.clone(),
            source: self.source_path.clone(),
            num_sources: self.generator.dataset().demos.len(),
            workers: self.config.workers,
            seed: settings.seed,
            spec_overrides: self.config.spec.clone(),
            target: settings.num_trials,
            guarantee: settings.guarantee,
            resumed_from,
        })));
        let keep_failed = settings.keep_failed;
        // Only attempts that may be kept are observed; every one says which object instance its
        // episode drew.
        let finish = |env: &mut E, attempt: &Attempt| -> Result<(Option<Observed>, Option<String>), EngineError> {
            let instance = env.object_instance();
            let observed = if attempt.success || keep_failed { Some(observe(env, attempt)?) } else { None };
            Ok((observed, instance))
        };
        let started = Instant::now();
        let mut write_error: Option<PipelineError> = None;
        // The quality report covers every demo of the dataset: those of an earlier session from
        // the log.
        let (mut quality, mut initial_scenes) = crate::outputs::logged_quality(&records);
        // Attempts and successes per drawn object instance, those of an earlier session first.
        let mut instances = crate::outputs::InstanceTally::of(&records);
        let mut control_steps = 0usize;
        let control = RunControl {
            start: progress.next_attempt,
            stats: Some(progress.stats),
            cancel: Some(cancel),
            shard: self.config.shard.unwrap_or_default(),
        };
        let result = mimicgen_engine::run_with(&self.generator, envs, control, finish, |attempt, (payload, instance), stats| {
            control_steps += attempt.trajectory.len();
            instances.add(instance.as_deref(), attempt.success);
            let figures = attempt.success.then(|| mimicgen_engine::quality::AttemptFigures::of(&attempt, CONTROL_PERIOD_S));
            if let Some(f) = &figures {
                quality.add_figures(f);
                initial_scenes.push(attempt.initial_object_poses.clone());
            }
            let step = (|| -> Result<Outcome, PipelineError> {
                let target = if attempt.success {
                    Some((&mut writer, true))
                } else if keep_failed && failures_kept < settings.max_num_failures {
                    failures_kept += 1;
                    failed_writer.as_mut().map(|w| (w, false))
                } else {
                    None
                };
                let outcome = match (target, payload) {
                    (Some((w, success)), Some(Observed { obs, images, model_xml, other_actions })) => {
                        let object_instance = instance.clone();
                        let demo = w.append(&DemoData {
                            images,
                            object_instance,
                            other_actions,
                            ..DemoData::from_attempt(&attempt, obs, model_xml)
                        })?;
                        if success { Outcome::Written { demo } } else { Outcome::KeptFailed { demo } }
                    }
                    _ => Outcome::Discarded,
                };
                log.append(&AttemptRecord {
                    index: usize::try_from(attempt.index).unwrap_or(usize::MAX),
                    success: attempt.success,
                    sources: attempt.src_demo_per_subtask.clone(),
                    failure: attempt.failure.clone(),
                    cause: attempt.cause.clone(),
                    steps: attempt.trajectory.len(),
                    kept: match &outcome {
                        Outcome::Written { demo } | Outcome::KeptFailed { demo } => Some(demo.clone()),
                        Outcome::Discarded => None,
                    },
                    instance: instance.clone(),
                    initial_object_poses: figures.is_some().then(|| attempt.initial_object_poses.clone()),
                    figures,
                })?;
                let progress = Progress {
                    next_attempt: usize::try_from(attempt.index).unwrap_or(usize::MAX) + 1,
                    failures_kept,
                    stats: stats.clone(),
                };
                writer.set_root_attr(PROGRESS_ATTR, &serde_json::to_string(&progress).unwrap_or_default())?;
                Ok(outcome)
            })();
            match step {
                Ok(outcome) => {
                    let elapsed_s = started.elapsed().as_secs_f64();
                    on_event(&Event::Attempt(Box::new(AttemptEvent { attempt, outcome, instance, stats: stats.clone(), elapsed_s })));
                    ControlFlow::Continue(())
                }
                Err(e) => {
                    write_error = Some(e);
                    ControlFlow::Break(Ok(()))
                }
            }
        });
        if let Some(e) = write_error {
            return Err(e);
        }
        let stats = result.map_err(|e| PipelineError::engine(self.source_path.display().to_string(), e))?;
        let cancelled = cancel.load(std::sync::atomic::Ordering::Relaxed)
            && !(settings.guarantee && stats.successes >= settings.num_trials)
            && stats.attempts < settings.attempt_cap();
        // The failed attempts first: the dataset's rename is the run's commit point (a run killed
        // between the two resumes, and takes the finished failed file back).
        let failed_written = failed_writer.map(DatasetWriter::finish).transpose()?;
        let written = writer.finish()?;
        let mut report =
            self.report(&stats, resumed_from, started.elapsed().as_secs_f64(), control_steps, cancelled, &written, failed_written);
        let dataset_quality = dataset_quality(self.task.as_ref(), &written, quality.summary(), &initial_scenes, replay);
        crate::outputs::write_quality(&self.config.out, &dataset_quality)?;
        report.quality = Some(dataset_quality);
        report.per_object_instance = instances.report();
        self.write_report(&report)?;
        on_event(&Event::Finished(Box::new(report.clone())));
        Ok(report)
    }

    /// The report of this session of the run.
    #[allow(clippy::too_many_arguments)]
    fn report(
        &self,
        stats: &RunStats,
        resumed_from: usize,
        wall: f64,
        control_steps: usize,
        cancelled: bool,
        written: &Path,
        failed_written: Option<PathBuf>,
    ) -> Report {
        let settings = &self.generator.spec().generation;
        #[allow(clippy::cast_precision_loss)]
        let session_attempts = stats.attempts.saturating_sub(resumed_from) as f64;
        Report {
            task: self.task.name().to_owned(),
            variant: self.variant.clone(),
            seed: settings.seed,
            workers: self.config.workers,
            source: self.source_path.display().to_string(),
            config: self.config.config.as_ref().map(|p| p.display().to_string()),
            robot: self.config.robot.clone(),
            output: written.display().to_string(),
            failed_output: failed_written.map(|p| p.display().to_string()),
            attempts: stats.attempts,
            successes: stats.successes,
            generation_rate: stats.rate(),
            wall_time_s: wall,
            attempts_per_s: if wall > 0.0 { session_attempts / wall } else { 0.0 },
            control_steps,
            per_source_demo: per_source_demo(stats),
            per_subtask_source: per_subtask_source(stats),
            never_succeeded: never_succeeded(stats),
            per_object_instance: Vec::new(),
            peak_rss_mib: crate::memory::peak_rss_mib(),
            failures: failures(stats),
            causes: causes(stats),
            cancelled,
            resumed_from,
            early_abort: settings.early_abort,
            spec_overrides: self.config.spec.clone(),
            shard: self.config.shard,
            quality: None,
            transit: stats.transit,
        }
    }

    fn write_report(&self, report: &Report) -> Result<(), PipelineError> {
        let report_path = self.report_path();
        let text = serde_json::to_string_pretty(report).unwrap_or_default();
        std::fs::write(&report_path, text).map_err(|e| PipelineError::Fs { file: report_path.display().to_string(), reason: e.to_string() })
    }

    /// With `resume`, a run that was killed after its dataset's rename (the run's commit point)
    /// and before its report was written: the report, made from what the finished dataset keeps
    /// (its run description, which must be this run's, and its progress: every attempt's
    /// counts), as a resumed session that had nothing left to do reports it; written beside the
    /// dataset. `None` for every other case (no resume, an interrupted run to continue, a report
    /// already there).
    fn report_of_a_finished_run(&self) -> Result<Option<Report>, PipelineError> {
        let out = &self.config.out;
        if !self.config.resume || DatasetWriter::partial_path(out).exists() || !out.is_file() || self.report_path().exists() {
            return Ok(None);
        }
        let file = out.display().to_string();
        let stored = mimicgen_io::root_string_attrs(out, &[RUN_ATTR, PROGRESS_ATTR])?;
        let [Some(stored_run), Some(progress)] = stored.as_slice() else { return Ok(None) };
        let stored_run: serde_json::Value =
            serde_json::from_str(stored_run).map_err(|e| PipelineError::input(file.clone(), RUN_ATTR, e.to_string()))?;
        if stored_run != serde_json::to_value(&self.description).unwrap_or_default() {
            let differing = differing_fields(&serde_json::to_value(&self.description).unwrap_or_default(), &stored_run);
            return Err(PipelineError::input(
                file,
                RUN_ATTR,
                format!(
                    "the finished run made a different dataset ({} differ); its report cannot be written from here",
                    differing.join(", ")
                ),
            ));
        }
        let progress: Progress = serde_json::from_str(progress).map_err(|e| PipelineError::input(file, PROGRESS_ATTR, e.to_string()))?;
        let settings = &self.generator.spec().generation;
        let stats = progress.stats;
        let cancelled = stats.attempts < settings.attempt_cap() && !(settings.guarantee && stats.successes >= settings.num_trials);
        let failed = self.failed_path();
        let failed_written = failed.is_file().then_some(failed);
        let mut report = self.report(&stats, progress.next_attempt, 0.0, 0, cancelled, out, failed_written);
        if let Ok(records) = crate::outputs::read_attempt_log(&self.attempt_log_path()) {
            report.per_object_instance = crate::outputs::InstanceTally::of(&records).report();
        }
        self.write_report(&report)?;
        Ok(Some(report))
    }
}

/// What [`Pipeline::open_writers`] opens.
struct Opened {
    writer: DatasetWriter,
    failed_writer: Option<DatasetWriter>,
    progress: Progress,
    log: AttemptLog,
    /// The log's records of the attempts before `progress`'s next.
    records: Vec<AttemptRecord>,
}

/// The quality report of `written`, a dataset of `task`: `quality` of its demos' attempts, the
/// coverage of `scenes` (their initial object poses), and with `replay` [`QUALITY_REPLAYS`] of
/// its demos replayed in MuJoCo (a replay that cannot run is the report's finding, not an error).
pub(crate) fn dataset_quality(
    task: &dyn Task,
    written: &Path,
    quality: mimicgen_engine::quality::Quality,
    scenes: &[BTreeMap<String, mimicgen_engine::Pose>],
    replay: bool,
) -> mimicgen_run::DatasetQuality {
    let dimensions = task.coverage_dimensions();
    let coverage = (!scenes.is_empty() && !dimensions.is_empty())
        .then(|| mimicgen_engine::coverage::coverage(scenes, &dimensions, COVERAGE_BINS).ok())
        .flatten()
        .map(|c| mimicgen_run::CoverageFigure {
            bins: COVERAGE_BINS,
            scenes: c.scenes,
            support_coverage: c.support_coverage(),
            uniform_support_coverage: mimicgen_engine::coverage::uniform_support_coverage(c.joint_bins_total, c.scenes),
        });
    let names = if replay {
        mimicgen_io::RobomimicDataset::open(written).map(|d| d.demo_names().to_vec()).map_err(|e| e.to_string())
    } else {
        Ok(Vec::new())
    };
    let replay = match names {
        Ok(names) if names.is_empty() => None,
        Ok(names) => {
            let k = QUALITY_REPLAYS.min(names.len());
            let demos: Vec<String> = (0..k).filter_map(|i| names.get(i * names.len() / k).cloned()).collect();
            Some(match crate::replay::replay(written, &demos, crate::replay::ReplayMode::Actions, Some(task.name()), |_, _, _| {}) {
                Ok(traces) => mimicgen_run::ReplayCheck { succeeded: traces.iter().filter(|t| t.success).count(), demos, error: None },
                Err(e) => mimicgen_run::ReplayCheck { demos, succeeded: 0, error: Some(e.to_string()) },
            })
        }
        Err(error) => Some(mimicgen_run::ReplayCheck { demos: Vec::new(), succeeded: 0, error: Some(error) }),
    };
    mimicgen_run::DatasetQuality { dataset: written.display().to_string(), quality, coverage, replay }
}
