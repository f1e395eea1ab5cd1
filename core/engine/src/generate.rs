//! The generation loop: attempts, their records, and a run over several workers.
//!
//! Attempt `k` of a run draws every random number (scene, segment offsets, source choice, action
//! noise) from ChaCha8 stream `k` of the run seed, so an attempt is the same whichever worker runs
//! it and whenever. [`run`] hands attempts to the caller strictly in index order and stops at the
//! same index whatever the number of workers, so the same seed gives the same dataset.

use std::collections::BTreeMap;
use std::ops::ControlFlow;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Condvar, Mutex, mpsc};

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use serde::{Deserialize, Serialize};

use crate::EngineError;
use crate::action::POSE_ACTION_DIM;
use crate::demo::{Rows, SimPayload, SourceDataset, SourceDemo};
use crate::env::{EnvError, Environment};
use crate::pose::Pose;
use crate::segment::{Segmentation, Span};
use crate::select::{SceneContext, pick_source, source_distances};
use crate::spec::TaskSpec;
use crate::transform::{Waypoint, WaypointKind, subtask_waypoints, transform_segment};

/// The random stream of attempt `index` in a run seeded with `seed`.
#[must_use]
pub fn attempt_rng(seed: u64, index: u64) -> ChaCha8Rng {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(index);
    rng
}

/// Why an attempt failed.
#[derive(Debug, Clone, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum FailureReason {
    /// The subtask ran to its end but its end signal never turned on (e.g. the grasp missed).
    SignalNeverOn {
        /// The signal that stayed off.
        signal: String,
    },
    /// Every subtask ran but the task was never achieved.
    TaskNotAchieved {
        /// The part of the success condition that did not hold at the end, when the
        /// environment can say (`pod in machine`).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        unmet: Option<String>,
    },
    /// The simulation became unstable.
    Unstable {
        /// What the simulator reported.
        reason: String,
    },
}

impl std::fmt::Display for FailureReason {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::SignalNeverOn { signal } => write!(f, "signal {signal:?} never turned on"),
            Self::TaskNotAchieved { unmet: None } => write!(f, "task not achieved"),
            Self::TaskNotAchieved { unmet: Some(unmet) } => write!(f, "task not achieved: {unmet} failed"),
            Self::Unstable { reason } => write!(f, "simulation unstable: {reason}"),
        }
    }
}

/// Where and why an attempt failed.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Failure {
    /// Index of the first subtask that went wrong.
    pub subtask: usize,
    /// What went wrong there.
    pub reason: FailureReason,
}

/// How one subtask of an attempt was planned: the pieces the paper's Fig. 2 draws.
#[derive(Debug, Clone, PartialEq)]
pub struct SubtaskPlan {
    /// The source demo the segment came from.
    pub src_demo: usize,
    /// How far each source demo was from the scene by the selection strategy (`None` when the
    /// source was kept from the previous subtask or the strategy is random).
    pub source_distances: Option<Vec<f64>>,
    /// The segment's steps in that demo, after this attempt's offsets.
    pub src_span: Span,
    /// The source segment's poses before the transform (first eef pose, then targets).
    pub source_poses: Vec<Pose>,
    /// The reference object's pose in the source demo at the segment start.
    pub world_from_obj_src: Option<Pose>,
    /// The reference object's pose in the new scene at the subtask start.
    pub world_from_obj_new: Option<Pose>,
    /// The segment re-expressed in the new scene.
    pub transformed_poses: Vec<Pose>,
    /// The waypoints actually executed (interpolation, then transformed).
    pub waypoints: Vec<(Pose, WaypointKind)>,
    /// First executed step of this subtask in the attempt.
    pub first_step: usize,
}

/// Everything recorded per executed step, step-aligned like a source demo.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Trajectory {
    /// Simulator state before each action.
    pub states: Rows,
    /// The actions executed (noise included, clipped).
    pub actions: Rows,
    /// `world_from_eef` before each action.
    pub eef_poses: Vec<Pose>,
    /// Controller target implied by each executed action.
    pub target_poses: Vec<Pose>,
    /// Gripper part of each action.
    pub gripper_actions: Rows,
    /// `world_from_object` before each action.
    pub object_poses: BTreeMap<String, Vec<Pose>>,
    /// Signals before each action.
    pub subtask_term_signals: BTreeMap<String, Vec<i64>>,
    /// Source demo each step came from.
    pub src_demo_labels: Vec<usize>,
    /// Subtask each step belongs to.
    pub subtask_labels: Vec<usize>,
    /// Whether each step was interpolation or transformed segment.
    pub kinds: Vec<WaypointKind>,
}

impl Trajectory {
    /// An empty trajectory for states of `state_dim` and actions of `action_dim` values.
    #[must_use]
    pub fn new(state_dim: usize, action_dim: usize) -> Self {
        Self {
            states: Rows::new(state_dim),
            actions: Rows::new(action_dim),
            gripper_actions: Rows::new(action_dim.saturating_sub(POSE_ACTION_DIM)),
            ..Self::default()
        }
    }

    /// The trajectory as a source demo (for re-use as a source, or for writing out).
    #[must_use]
    pub fn to_source_demo(&self, name: &str) -> SourceDemo {
        SourceDemo {
            name: name.to_owned(),
            eef_poses: self.eef_poses.clone(),
            target_poses: self.target_poses.clone(),
            gripper_actions: self.gripper_actions.clone(),
            object_poses: self.object_poses.clone(),
            subtask_term_signals: self.subtask_term_signals.clone(),
            manual_subtask_ends: None,
            sim: SimPayload { actions: self.actions.clone(), states: self.states.clone(), model_xml: None },
        }
    }

    /// Number of executed steps.
    #[must_use]
    pub fn len(&self) -> usize {
        self.eef_poses.len()
    }

    /// True when nothing was executed.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.eef_poses.is_empty()
    }
}

/// The record of one attempt, kept whether it succeeded or not.
#[derive(Debug, Clone, PartialEq)]
pub struct Attempt {
    /// Index in the run (its random stream).
    pub index: u64,
    /// The run seed.
    pub seed: u64,
    /// Whether the task was achieved at any step.
    pub success: bool,
    /// Where and why it failed, if it did.
    pub failure: Option<Failure>,
    /// Source demo chosen for each subtask.
    pub src_demo_per_subtask: Vec<usize>,
    /// Object poses of the sampled scene before the first action.
    pub initial_object_poses: BTreeMap<String, Pose>,
    /// The simulator state of the sampled scene.
    pub initial_state: Vec<f64>,
    /// Per-subtask plans.
    pub plans: Vec<SubtaskPlan>,
    /// Per-step records.
    pub trajectory: Trajectory,
}

/// A task spec bound to a parsed source dataset, ready to run attempts.
#[derive(Debug, Clone)]
pub struct Generator {
    spec: TaskSpec,
    dataset: SourceDataset,
    segmentation: Segmentation,
}

impl Generator {
    /// Validates the dataset, checks the spec's names against it and parses the segments.
    ///
    /// # Errors
    /// Any validation, naming or segmentation error, naming the demo and field.
    pub fn new(spec: TaskSpec, dataset: SourceDataset) -> Result<Self, EngineError> {
        spec.check("task spec")?;
        dataset.validate()?;
        spec.check_names(&dataset.object_names(), &dataset.signal_names())?;
        let segmentation = Segmentation::new(&dataset.demos, &spec)?;
        Ok(Self { spec, dataset, segmentation })
    }

    /// The same generator with hand-set subtask ends (exclusive, one per subtask but the last)
    /// for the demos `ends` names, in place of their signals.
    ///
    /// # Errors
    /// [`EngineError::UnknownName`] for a demo that does not exist, [`EngineError::Segmentation`]
    /// for ends that do not fit the demo.
    pub fn with_subtask_ends(&self, ends: &BTreeMap<String, Vec<usize>>) -> Result<Self, EngineError> {
        let mut dataset = self.dataset.clone();
        for (name, demo_ends) in ends {
            let demo = dataset.demos.iter_mut().find(|d| &d.name == name).ok_or_else(|| EngineError::UnknownName {
                field: "subtask ends".to_owned(),
                name: name.clone(),
                available: self.dataset.demos.iter().map(|d| d.name.clone()).collect(),
            })?;
            demo.manual_subtask_ends = Some(demo_ends.clone());
        }
        let segmentation = Segmentation::new(&dataset.demos, &self.spec)?;
        Ok(Self { spec: self.spec.clone(), dataset, segmentation })
    }

    /// The same generator drawing from run seed `seed`.
    #[must_use]
    pub fn with_seed(mut self, seed: u64) -> Self {
        self.spec.generation.seed = seed;
        self
    }

    /// The task spec.
    #[must_use]
    pub fn spec(&self) -> &TaskSpec {
        &self.spec
    }

    /// The source dataset.
    #[must_use]
    pub fn dataset(&self) -> &SourceDataset {
        &self.dataset
    }

    /// The nominal segmentation.
    #[must_use]
    pub fn segmentation(&self) -> &Segmentation {
        &self.segmentation
    }

    /// Runs attempt `index`: samples a scene, then for every subtask selects, transforms,
    /// interpolates and executes a source segment.
    ///
    /// # Errors
    /// Only [`EnvError::Fatal`] problems; a failed attempt is an `Ok` record with `success == false`.
    pub fn attempt<E: Environment + ?Sized>(&self, env: &mut E, index: u64) -> Result<Attempt, EngineError> {
        self.attempt_with(env, index, &Overrides::default())
    }

    /// [`Generator::attempt`] with what `overrides` forces: the source demo of some subtasks, and
    /// objects moved after the reset. Every random number is still drawn, so the segment offsets
    /// and the action noise (and the scene, but for the moved objects) are those of attempt
    /// `index` of a run: with no overrides this is that attempt exactly.
    ///
    /// # Errors
    /// As [`Generator::attempt`], and [`EngineError::Config`] for a source past the last demo or
    /// [`EngineError::Env`] for an object the scene does not have.
    pub fn attempt_with<E: Environment + ?Sized>(&self, env: &mut E, index: u64, overrides: &Overrides) -> Result<Attempt, EngineError> {
        let sources = &overrides.sources;
        self.check_overrides(sources)?;
        let settings = &self.spec.generation;
        let mut rng = attempt_rng(settings.seed, index);
        let fatal = |e: EnvError| EngineError::Env { attempt: index, source: e };
        let unstable = |e: EnvError, subtask: usize| match e {
            EnvError::Unstable { reason } => Ok(Failure { subtask, reason: FailureReason::Unstable { reason } }),
            other => Err(fatal(other)),
        };
        let mut attempt = Attempt {
            index,
            seed: settings.seed,
            success: false,
            failure: None,
            src_demo_per_subtask: Vec::new(),
            initial_object_poses: BTreeMap::new(),
            initial_state: Vec::new(),
            plans: Vec::new(),
            trajectory: Trajectory::new(0, env.action_dim()),
        };
        if let Err(e) = env.reset(&mut rng) {
            attempt.failure = Some(unstable(e, 0)?);
            return Ok(attempt);
        }
        env.place_objects(&overrides.object_poses).map_err(fatal)?;
        attempt.initial_object_poses = env.object_poses();
        attempt.initial_state = env.state();
        attempt.trajectory = Trajectory::new(attempt.initial_state.len(), env.action_dim());
        let spans = self.segmentation.draw_spans(&mut rng);
        let mut selected: Option<usize> = None;
        let mut last_target: Option<Pose> = None;
        for (subtask_index, subtask) in self.spec.subtasks.iter().enumerate() {
            let here = PlanInput {
                subtask: subtask_index,
                world_from_eef: env.eef_pose(),
                objects: env.object_poses(),
                last_target,
                selected,
                forced: sources.get(subtask_index).copied().flatten(),
            };
            let (plan, waypoints) = self.plan_subtask(&here, &spans, &mut rng).map_err(|reason| fatal(EnvError::Fatal { reason }))?;
            selected = Some(plan.src_demo);
            last_target = waypoints.last().map(|(w, _)| w.pose).or(last_target);
            attempt.src_demo_per_subtask.push(plan.src_demo);
            let labels = StepLabels { src_demo: plan.src_demo, subtask: subtask_index, kind: WaypointKind::Transformed };
            attempt.plans.push(SubtaskPlan { first_step: attempt.trajectory.len(), ..plan });
            let mut signal_seen = false;
            let signal = if subtask_index + 1 < self.spec.subtasks.len() { subtask.term_signal.as_deref() } else { None };
            for (waypoint, kind) in &waypoints {
                let signals = match execute_step(env, waypoint, StepLabels { kind: *kind, ..labels }, &mut attempt.trajectory, &mut rng) {
                    Ok(signals) => signals,
                    Err(e) => {
                        attempt.failure = Some(unstable(e, subtask_index)?);
                        return Ok(attempt);
                    }
                };
                signal_seen |= signal.is_some_and(|s| signals.get(s).is_some_and(|&v| v != 0));
                attempt.success |= env.is_success();
            }
            if let Some(name) = signal {
                signal_seen |= env.subtask_term_signals().get(name).is_some_and(|&v| v != 0);
                if !signal_seen && attempt.failure.is_none() {
                    attempt.failure =
                        Some(Failure { subtask: subtask_index, reason: FailureReason::SignalNeverOn { signal: name.to_owned() } });
                    if settings.early_abort && !attempt.success {
                        return Ok(attempt);
                    }
                }
            }
        }
        if attempt.success {
            attempt.failure = None;
        } else if attempt.failure.is_none() {
            let reason = FailureReason::TaskNotAchieved { unmet: env.unmet_success() };
            attempt.failure = Some(Failure { subtask: self.spec.subtasks.len() - 1, reason });
        }
        Ok(attempt)
    }

    /// Plans attempt `index` without executing it: samples its scene (the same as the attempt's,
    /// with the objects `overrides` moves moved) and, for every subtask, ranks and picks the source
    /// demo (or takes the one `overrides` forces), transforms
    /// its segment into the scene and bridges to it. Objects are taken to stay where the scene put
    /// them and each subtask to start where the previous one's last target is, so later subtasks
    /// are what the attempt would plan if execution went as planned (with per-subtask random
    /// selection the attempt may pick differently, since execution draws noise in between).
    ///
    /// # Errors
    /// As [`Generator::attempt_with`]; a scene the simulator rejects is [`EngineError::Env`].
    pub fn plan<E: Environment + ?Sized>(&self, env: &mut E, index: u64, overrides: &Overrides) -> Result<Plan, EngineError> {
        let sources = &overrides.sources;
        self.check_overrides(sources)?;
        let mut rng = attempt_rng(self.spec.generation.seed, index);
        let fatal = |e: EnvError| EngineError::Env { attempt: index, source: e };
        env.reset(&mut rng).map_err(fatal)?;
        env.place_objects(&overrides.object_poses).map_err(fatal)?;
        let objects = env.object_poses();
        let world_from_eef = env.eef_pose();
        let spans = self.segmentation.draw_spans(&mut rng);
        let mut plan =
            Plan { index, world_from_eef, initial_object_poses: objects.clone(), initial_state: env.state(), subtasks: Vec::new() };
        let (mut selected, mut last_target) = (None, None);
        for subtask in 0..self.spec.subtasks.len() {
            let here = PlanInput {
                subtask,
                world_from_eef: last_target.unwrap_or(world_from_eef),
                objects: objects.clone(),
                last_target,
                selected,
                forced: sources.get(subtask).copied().flatten(),
            };
            let (mut planned, waypoints) =
                self.plan_subtask(&here, &spans, &mut rng).map_err(|reason| fatal(EnvError::Fatal { reason }))?;
            planned.first_step = plan.subtasks.iter().map(|s| s.waypoints.len()).sum();
            selected = Some(planned.src_demo);
            last_target = waypoints.last().map(|(w, _)| w.pose).or(last_target);
            plan.subtasks.push(planned);
        }
        Ok(plan)
    }

    fn check_overrides(&self, sources: &[Option<usize>]) -> Result<(), EngineError> {
        let num = self.dataset.demos.len();
        match sources.iter().enumerate().find_map(|(k, s)| s.filter(|&d| d >= num).map(|d| (k, d))) {
            Some((k, d)) => Err(EngineError::Config {
                file: String::new(),
                field: format!("sources[{k}]"),
                reason: format!("source demo {d} does not exist (the dataset has {num})"),
            }),
            None => Ok(()),
        }
    }

    /// Selects, transforms and bridges one subtask's segment (the part of an attempt before
    /// execution). Draws the selection's random numbers even when the source is forced.
    fn plan_subtask<R: Rng + ?Sized>(
        &self,
        here: &PlanInput,
        spans: &[Vec<Span>],
        rng: &mut R,
    ) -> Result<(SubtaskPlan, Vec<(Waypoint, WaypointKind)>), String> {
        let settings = &self.spec.generation;
        let subtask = &self.spec.subtasks[here.subtask];
        let is_first = here.subtask == 0;
        let demos = &self.dataset.demos;
        let world_from_obj_new = match &subtask.object_ref {
            Some(name) => Some(*here.objects.get(name).ok_or_else(|| {
                format!(
                    "environment reports no pose for object {name:?} (subtask {}); it has {:?}",
                    here.subtask,
                    here.objects.keys().collect::<Vec<_>>()
                )
            })?),
            None => None,
        };
        let (demo_index, distances) = match here.selected {
            Some(d) if !settings.select_src_per_subtask => (d, None),
            _ => {
                let scene = SceneContext { world_from_eef: &here.world_from_eef, world_from_obj: world_from_obj_new.as_ref() };
                let distances = source_distances(&subtask.selection, demos, spans, here.subtask, subtask.object_ref.as_deref(), scene);
                (pick_source(&subtask.selection, distances.as_deref(), demos.len(), rng), distances)
            }
        };
        let demo_index = here.forced.unwrap_or(demo_index);
        let demo = &demos[demo_index];
        let (start, end) = spans[demo_index][here.subtask];
        let mut source_poses = Vec::with_capacity(end - start + 1);
        let mut gripper: Vec<Vec<f64>> = Vec::with_capacity(end - start + 1);
        if is_first || settings.transform_first_robot_pose {
            source_poses.push(demo.eef_poses[start]);
            gripper.push(demo.gripper_actions.row(start).to_vec());
        }
        source_poses.extend_from_slice(&demo.target_poses[start..end]);
        gripper.extend((start..end).map(|t| demo.gripper_actions.row(t).to_vec()));
        let world_from_obj_src = subtask.object_ref.as_ref().map(|name| demo.object_poses[name][start]);
        let transformed = match (&world_from_obj_new, &world_from_obj_src) {
            (Some(new), Some(src)) => transform_segment(new, src, &source_poses),
            _ => source_poses.clone(),
        };
        let interp_start = match here.last_target {
            Some(pose) if settings.interpolate_from_last_target_pose && !is_first => pose,
            _ => here.world_from_eef,
        };
        let interp_noise = if subtask.apply_noise_during_interpolation { subtask.action_noise } else { 0.0 };
        let waypoints = subtask_waypoints(
            &interp_start,
            &transformed,
            &gripper,
            subtask.num_interpolation_steps,
            subtask.num_fixed_steps,
            subtask.action_noise,
            interp_noise,
        );
        let plan = SubtaskPlan {
            src_demo: demo_index,
            src_span: (start, end),
            source_distances: distances,
            source_poses,
            world_from_obj_src,
            world_from_obj_new,
            transformed_poses: transformed,
            waypoints: waypoints.iter().map(|(w, k)| (w.pose, *k)).collect(),
            first_step: 0,
        };
        Ok((plan, waypoints))
    }
}

/// What a caller forces in a planned or executed attempt; everything else is drawn as a run
/// draws it.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Overrides {
    /// The source demo of subtask `k` where `sources[k]` is `Some` (the selection picks otherwise).
    pub sources: Vec<Option<usize>>,
    /// Objects moved after the reset (the others stay where the reset put them).
    pub object_poses: BTreeMap<String, Pose>,
}

/// Where one subtask is planned from.
struct PlanInput {
    subtask: usize,
    world_from_eef: Pose,
    objects: BTreeMap<String, Pose>,
    last_target: Option<Pose>,
    /// The source demo of the previous subtask.
    selected: Option<usize>,
    /// A source demo the caller chose.
    forced: Option<usize>,
}

/// An attempt planned but not executed ([`Generator::plan`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Plan {
    /// The attempt index (its random stream).
    pub index: u64,
    /// `world_from_eef` in the sampled scene before the first action.
    pub world_from_eef: Pose,
    /// Object poses of the sampled scene.
    pub initial_object_poses: BTreeMap<String, Pose>,
    /// The simulator state of the sampled scene (to draw it).
    pub initial_state: Vec<f64>,
    /// Per-subtask plans; `first_step` counts planned waypoints.
    pub subtasks: Vec<SubtaskPlan>,
}

/// Labels attached to every recorded step.
#[derive(Debug, Clone, Copy)]
pub struct StepLabels {
    /// Source demo the step came from.
    pub src_demo: usize,
    /// Subtask the step belongs to.
    pub subtask: usize,
    /// Interpolation or transformed segment.
    pub kind: WaypointKind,
}

/// Converts a waypoint to an action (with the waypoint's noise, clipped to `[-1, 1]`), records the
/// step in `traj` as MimicGen records `datagen_info`, and applies it. Returns the signals recorded
/// before the action.
///
/// # Errors
/// The environment's error from stepping, or [`EnvError::Fatal`] if the gripper widths disagree.
pub fn execute_step<E: Environment + ?Sized, R: Rng + ?Sized>(
    env: &mut E,
    waypoint: &Waypoint,
    labels: StepLabels,
    traj: &mut Trajectory,
    rng: &mut R,
) -> Result<BTreeMap<String, i64>, EnvError> {
    let mut pose_action = env.target_pose_to_action(&waypoint.pose);
    if waypoint.noise > 0.0 {
        for a in &mut pose_action {
            let z: f64 = rng.sample(StandardNormal);
            *a = (*a + waypoint.noise * z).clamp(-1.0, 1.0);
        }
    }
    let mut action = Vec::with_capacity(POSE_ACTION_DIM + waypoint.gripper.len());
    action.extend_from_slice(&pose_action);
    action.extend_from_slice(&waypoint.gripper);
    if action.len() != env.action_dim() {
        return Err(EnvError::Fatal {
            reason: format!(
                "source gripper actions have {} values but the environment's actions have {} gripper values",
                waypoint.gripper.len(),
                env.action_dim() - POSE_ACTION_DIM.min(env.action_dim())
            ),
        });
    }
    let state = env.state();
    let shape = |e: EngineError| EnvError::Fatal { reason: e.to_string() };
    traj.states.push(&state).map_err(shape)?;
    traj.actions.push(&action).map_err(shape)?;
    traj.gripper_actions.push(&waypoint.gripper).map_err(shape)?;
    traj.eef_poses.push(env.eef_pose());
    traj.target_poses.push(env.action_to_target_pose(&action));
    for (name, pose) in env.object_poses() {
        traj.object_poses.entry(name).or_default().push(pose);
    }
    let signals = env.subtask_term_signals();
    for (name, value) in &signals {
        traj.subtask_term_signals.entry(name.clone()).or_default().push(*value);
    }
    traj.src_demo_labels.push(labels.src_demo);
    traj.subtask_labels.push(labels.subtask);
    traj.kinds.push(labels.kind);
    env.step(&action)?;
    Ok(signals)
}

/// Attempts and successes that used one source demo.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct DemoUse {
    /// Attempts in which this demo supplied at least one segment.
    pub attempts: usize,
    /// Of those, how many succeeded.
    pub successes: usize,
}

/// How many attempts failed in one subtask for one reason.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct FailureCount {
    /// The subtask.
    pub subtask: usize,
    /// The reason.
    pub reason: FailureReason,
    /// The count.
    pub count: usize,
}

/// Running statistics of a generation run.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct RunStats {
    /// Attempts accepted so far.
    pub attempts: usize,
    /// Successful attempts so far.
    pub successes: usize,
    /// Per source demo, by dataset index.
    pub per_source_demo: Vec<DemoUse>,
    /// Failures by subtask and reason, sorted.
    pub failures: Vec<FailureCount>,
}

impl RunStats {
    /// Statistics for a dataset of `num_demos` source demos.
    #[must_use]
    pub fn new(num_demos: usize) -> Self {
        Self { per_source_demo: vec![DemoUse::default(); num_demos], ..Self::default() }
    }

    /// The data generation rate: successes / attempts (0 before any attempt).
    #[must_use]
    pub fn rate(&self) -> f64 {
        #[allow(clippy::cast_precision_loss)] // counts are far below 2^52
        if self.attempts == 0 { 0.0 } else { self.successes as f64 / self.attempts as f64 }
    }

    /// Counts one attempt.
    pub fn record(&mut self, attempt: &Attempt) {
        self.record_outcome(attempt.success, &attempt.src_demo_per_subtask, attempt.failure.as_ref());
    }

    /// Counts one attempt from its outcome: whether it succeeded, the source demo of each subtask,
    /// and where it failed (what [`Self::record`] reads of an [`Attempt`]).
    pub fn record_outcome(&mut self, success: bool, sources: &[usize], failure: Option<&Failure>) {
        self.attempts += 1;
        self.successes += usize::from(success);
        let mut used: Vec<usize> = sources.to_vec();
        used.sort_unstable();
        used.dedup();
        for d in used {
            if d >= self.per_source_demo.len() {
                self.per_source_demo.resize(d + 1, DemoUse::default());
            }
            self.per_source_demo[d].attempts += 1;
            self.per_source_demo[d].successes += usize::from(success);
        }
        if let Some(failure) = failure {
            match self.failures.iter_mut().find(|f| f.subtask == failure.subtask && f.reason == failure.reason) {
                Some(f) => f.count += 1,
                None => {
                    self.failures.push(FailureCount { subtask: failure.subtask, reason: failure.reason.clone(), count: 1 });
                    self.failures.sort_by(|a, b| (a.subtask, &a.reason).cmp(&(b.subtask, &b.reason)));
                }
            }
        }
    }
}

/// One share of a run's attempt indices: those with `index % count == part`. Every attempt's
/// randomness depends only on the run seed and its index, so shards run anywhere make the
/// attempts a single run makes, and joined in index order they give its dataset.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Shard {
    /// Which share, `0..count`.
    pub part: usize,
    /// How many shares.
    pub count: usize,
}

impl Default for Shard {
    fn default() -> Self {
        Self::WHOLE
    }
}

impl Shard {
    /// Every index.
    pub const WHOLE: Self = Self { part: 0, count: 1 };

    /// Share `part` of `count`.
    ///
    /// # Errors
    /// A message when `count` is 0 or `part` is not below it.
    pub fn new(part: usize, count: usize) -> Result<Self, String> {
        if count == 0 || part >= count {
            return Err(format!("shard {part}/{count} does not exist: the shards of K are 0/K to {}/K", count.max(1) - 1));
        }
        Ok(Self { part, count })
    }

    /// Whether attempt `index` is in this share.
    #[must_use]
    pub fn contains(&self, index: usize) -> bool {
        index % self.count == self.part
    }

    /// The first index of this share at or after `start`.
    #[must_use]
    pub fn first_at_or_after(&self, start: usize) -> usize {
        start + (self.part + self.count - start % self.count) % self.count
    }
}

impl std::str::FromStr for Shard {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        let (part, count) = s.split_once('/').ok_or_else(|| format!("{s:?}: expected PART/COUNT, e.g. 0/4"))?;
        let number = |v: &str| v.trim().parse::<usize>().map_err(|e| format!("{s:?}: {v:?}: {e}"));
        Self::new(number(part)?, number(count)?)
    }
}

impl std::fmt::Display for Shard {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}/{}", self.part, self.count)
    }
}

/// Where a run starts and what can stop it early, beyond the spec's own stopping rule.
#[derive(Debug, Default)]
pub struct RunControl<'a> {
    /// Index of the first attempt to run (a resumed run starts where the interrupted one stopped).
    pub start: usize,
    /// Statistics of the attempts before `start`.
    pub stats: Option<RunStats>,
    /// Set to stop after the attempts already handed back: every attempt before the stop has been
    /// passed to the callback, in order, none after it.
    pub cancel: Option<&'a AtomicBool>,
    /// Run only this share of the attempt indices. With `guarantee`, the share stops at its own
    /// `num_trials` successes: then it holds every one of its attempts up to the single run's
    /// last (that run reaches its successes no later than any share does).
    pub shard: Shard,
}

/// How many attempts per worker may be finished and waiting for an earlier one.
pub const REORDER_WINDOW_PER_WORKER: usize = 4;

/// The oldest attempt index not yet handed on, which workers wait on.
struct Frontier {
    oldest: Mutex<usize>,
    moved: Condvar,
}

impl Frontier {
    /// Blocks until `index` is less than `window` past the oldest attempt not handed on; false
    /// when the run stops meanwhile.
    fn wait_until_within(&self, index: usize, window: usize, stop: &AtomicBool) -> bool {
        // A poisoned lock means the receiving side panicked: stop.
        let Ok(mut oldest) = self.oldest.lock() else { return false };
        while index >= oldest.saturating_add(window) && !stop.load(Ordering::Relaxed) {
            oldest = match self.moved.wait(oldest) {
                Ok(guard) => guard,
                Err(_) => return false,
            };
        }
        !stop.load(Ordering::Relaxed)
    }

    /// Records that every attempt before `index` has been handed on, waking the workers.
    fn advance_to(&self, index: usize) {
        if let Ok(mut oldest) = self.oldest.lock() {
            *oldest = index;
        }
        self.moved.notify_all();
    }
}

/// Runs attempts on every environment in `envs` in parallel (one worker thread each) and passes
/// them to `on_attempt` in index order, until the spec's stopping rule is met or `on_attempt`
/// breaks. The attempts seen, and so the dataset, do not depend on `envs.len()`.
///
/// # Errors
/// The first fatal environment error, or the error `on_attempt` breaks with.
pub fn run<E, F>(generator: &Generator, envs: &mut [E], mut on_attempt: F) -> Result<RunStats, EngineError>
where
    E: Environment + Send,
    F: FnMut(Attempt, &RunStats) -> ControlFlow<Result<(), EngineError>>,
{
    run_with(generator, envs, RunControl::default(), |_, _| Ok(()), |attempt, (), stats| on_attempt(attempt, stats))
}

/// [`run`], resumable and cancellable, with a step `finish` that each worker applies to its own
/// attempts on its own environment before handing them back (computing observations, say), so
/// that work runs in parallel too. `on_attempt` gets each attempt with what `finish` made of it.
///
/// # Errors
/// The first fatal environment error, the first error of `finish`, or the error `on_attempt`
/// breaks with.
pub fn run_with<E, P, W, F>(
    generator: &Generator,
    envs: &mut [E],
    control: RunControl<'_>,
    finish: W,
    mut on_attempt: F,
) -> Result<RunStats, EngineError>
where
    E: Environment + Send,
    P: Send,
    W: Fn(&mut E, &Attempt) -> Result<P, EngineError> + Sync,
    F: FnMut(Attempt, P, &RunStats) -> ControlFlow<Result<(), EngineError>>,
{
    let settings = &generator.spec.generation;
    let cap = settings.attempt_cap();
    let mut stats = control.stats.unwrap_or_else(|| RunStats::new(generator.dataset.demos.len()));
    if envs.is_empty() {
        return Err(EngineError::Config {
            file: String::new(),
            field: "workers".to_owned(),
            reason: "at least one environment is needed".to_owned(),
        });
    }
    let cancelled = || control.cancel.is_some_and(|c| c.load(Ordering::Relaxed));
    let done = |stats: &RunStats| settings.guarantee && stats.successes >= settings.num_trials;
    if done(&stats) || control.shard.first_at_or_after(control.start) >= cap || cancelled() {
        return Ok(stats);
    }
    let shard = control.shard;
    let first = shard.first_at_or_after(control.start);
    // Workers take this share's indices in order: `first`, `first + count`, ...
    let next = AtomicUsize::new(first);
    let stop = AtomicBool::new(false);
    // Attempts are handed on in index order, so a finished attempt waits for those before it. A
    // worker starts no attempt more than `window` shares past the oldest one not yet handed on:
    // one slow attempt cannot pile up the others' results (each with its images) without bound.
    let window = REORDER_WINDOW_PER_WORKER * envs.len() * shard.count;
    let frontier = Frontier { oldest: Mutex::new(first), moved: Condvar::new() };
    type Outcome<P> = Result<(Attempt, P), EngineError>;
    let (sender, receiver) = mpsc::sync_channel::<(usize, Outcome<P>)>(envs.len() * 2);
    std::thread::scope(|scope| {
        for (worker, env) in envs.iter_mut().enumerate() {
            let sender = sender.clone();
            let (next, stop, finish, frontier) = (&next, &stop, &finish, &frontier);
            let spawned = std::thread::Builder::new().name(format!("mimicgen-worker-{worker}")).spawn_scoped(scope, move || {
                loop {
                    let index = next.fetch_add(shard.count, Ordering::Relaxed);
                    if index >= cap || !frontier.wait_until_within(index, window, stop) {
                        break;
                    }
                    let result = generator.attempt(env, index as u64).and_then(|a| finish(env, &a).map(|p| (a, p)));
                    if sender.send((index, result)).is_err() {
                        break;
                    }
                }
            });
            if let Err(e) = spawned {
                stop.store(true, Ordering::Relaxed);
                frontier.advance_to(usize::MAX);
                return Err(EngineError::Io { path: "worker thread".to_owned(), reason: e.to_string() });
            }
        }
        drop(sender);
        let mut pending: BTreeMap<usize, Outcome<P>> = BTreeMap::new();
        let mut expected = first;
        let outcome = 'receive: loop {
            if expected >= cap || done(&stats) || cancelled() {
                break Ok(());
            }
            let (index, result) = match receiver.recv_timeout(std::time::Duration::from_millis(50)) {
                Ok(message) => message,
                Err(mpsc::RecvTimeoutError::Timeout) => continue,
                Err(mpsc::RecvTimeoutError::Disconnected) => break Ok(()),
            };
            pending.insert(index, result);
            while let Some(result) = pending.remove(&expected) {
                expected += shard.count;
                let (attempt, payload) = match result {
                    Ok(a) => a,
                    Err(e) => break 'receive Err(e),
                };
                stats.record(&attempt);
                if let ControlFlow::Break(result) = on_attempt(attempt, payload, &stats) {
                    break 'receive result;
                }
                frontier.advance_to(expected);
                if done(&stats) || cancelled() {
                    break 'receive Ok(());
                }
            }
        };
        stop.store(true, Ordering::Relaxed);
        frontier.advance_to(usize::MAX);
        // Drain so blocked workers can see `stop` and exit.
        while receiver.recv().is_ok() {}
        outcome
    })?;
    Ok(stats)
}
