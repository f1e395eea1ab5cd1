//! Attempts with two arms: each arm's subtasks planned as MimicGen plans one arm's (source
//! selection, the object-centric transform, interpolation) when the [`Schedule`] starts them,
//! both arms' actions in one vector (arm 0's pose and gripper, then arm 1's), and an arm that is
//! not running a subtask holding its last target.
//!
//! A coordinated pair is planned together: one source demo, one transform (the first subtask's
//! object pose in that demo), the shorter of the two padded with its last waypoint so that both
//! end on the same step.

use std::collections::BTreeMap;

use rand::{Rng, RngCore};

use super::{ArmStep, ArmSubtask, TwoArmSpec};
use crate::EngineError;
use crate::action::POSE_ACTION_DIM;
use crate::demo::{Rows, SourceDataset, SourceDemo};
use crate::env::EnvError;
use crate::generate::{FailureReason, Generator, PlanInput, SubtaskPlan, add_noise, attempt_rng};
use crate::pose::Pose;
use crate::segment::Span;
use crate::spec::Transit;
use crate::transform::{Waypoint, WaypointKind};

/// What the engine asks of a two-arm simulator: [`crate::Environment`] with every pose and
/// action per arm.
pub trait TwoArmEnvironment {
    /// Samples a new scene with `rng` and resets to it.
    ///
    /// # Errors
    /// [`EnvError`] if the scene cannot be built.
    fn reset(&mut self, rng: &mut dyn RngCore) -> Result<(), EnvError>;

    /// `world_from_eef` of `arm`.
    fn eef_pose(&self, arm: usize) -> Pose;

    /// `world_from_object` of every object the task names.
    fn object_poses(&self) -> BTreeMap<String, Pose>;

    /// Every subtask-end signal (nonzero = on), both arms' in one map.
    fn subtask_term_signals(&self) -> BTreeMap<String, i64>;

    /// Whether the task is achieved now.
    fn is_success(&self) -> bool;

    /// The parts of the success condition that do not hold now, in words.
    fn unmet_success(&self) -> Option<String> {
        None
    }

    /// The pose part of `arm`'s action towards `world_from_target`.
    fn target_pose_to_action(&self, arm: usize, world_from_target: &Pose) -> [f64; 6];

    /// The controller target `arm_action` (that arm's part of an action) implies now.
    fn action_to_target_pose(&self, arm: usize, arm_action: &[f64]) -> Pose;

    /// `arm`'s gripper values in the action vector.
    fn gripper_dim(&self, arm: usize) -> usize;

    /// Applies one action, both arms' parts in order.
    ///
    /// # Errors
    /// [`EnvError::Unstable`] if the physics blew up.
    fn step(&mut self, action: &[f64]) -> Result<(), EnvError>;

    /// The flattened simulator state.
    fn state(&self) -> Vec<f64>;
}

/// Where and why a two-arm attempt failed.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TwoArmFailure {
    /// The arm whose subtask went wrong; `None` when every subtask ran and the task was not
    /// achieved.
    pub arm: Option<usize>,
    /// Its subtask (the arm's last for an unachieved task, or arm 0's).
    pub subtask: usize,
    /// What went wrong.
    pub reason: FailureReason,
}

impl std::fmt::Display for TwoArmFailure {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self.arm {
            Some(arm) => write!(f, "arm {arm}: subtask {}: {}", self.subtask, self.reason),
            None => write!(f, "{}", self.reason),
        }
    }
}

/// One arm's part of an attempt, step-aligned with the attempt's actions.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ArmTrack {
    /// How each of its subtasks was planned (coordinated ones padded to their partner's length).
    pub plans: Vec<SubtaskPlan>,
    /// `world_from_eef` before each action.
    pub eef_poses: Vec<Pose>,
    /// The controller target its part of each action implies.
    pub target_poses: Vec<Pose>,
    /// Its gripper part of each action.
    pub gripper_actions: Rows,
    /// The source demo of each step (of the subtask it runs or last ran; 0 before its first).
    pub src_demo_labels: Vec<usize>,
    /// The subtask of each step: the one it runs, or the one it waits to start.
    pub subtask_labels: Vec<usize>,
    /// Whether it held its pose on each step (waiting or done).
    pub holding: Vec<bool>,
}

/// The record of one two-arm attempt.
#[derive(Debug, Clone, PartialEq)]
pub struct TwoArmAttempt {
    /// Index in the run (its random stream).
    pub index: u64,
    /// Whether the task was achieved at any step.
    pub success: bool,
    /// Where and why it failed, if it did.
    pub failure: Option<TwoArmFailure>,
    /// Object poses of the sampled scene.
    pub initial_object_poses: BTreeMap<String, Pose>,
    /// The simulator state of the sampled scene.
    pub initial_state: Vec<f64>,
    /// Simulator state before each action.
    pub states: Rows,
    /// The actions, both arms' in one row each.
    pub actions: Rows,
    /// `world_from_object` before each action.
    pub object_poses: BTreeMap<String, Vec<Pose>>,
    /// Signals before each action.
    pub subtask_term_signals: BTreeMap<String, Vec<i64>>,
    /// Per arm.
    pub arms: Vec<ArmTrack>,
}

impl TwoArmAttempt {
    /// Where it failed, its subtask numbered through both arms (arm `a`'s subtask `k` is
    /// `counts[..a].sum() + k`, `counts` the subtasks per arm); an unachieved task at arm 0's.
    #[must_use]
    pub fn flat_failure(&self, counts: &[usize]) -> Option<crate::generate::Failure> {
        self.failure.as_ref().map(|f| crate::generate::Failure {
            subtask: counts.iter().take(f.arm.unwrap_or(0)).sum::<usize>() + f.subtask,
            reason: f.reason.clone(),
        })
    }

    /// Each planned subtask's source demo as `(subtask, demo)`, numbered through both arms as
    /// [`Self::flat_failure`] numbers them.
    pub fn flat_sources(&self, counts: &[usize]) -> impl Iterator<Item = (usize, usize)> + '_ {
        let offsets: Vec<usize> = (0..self.arms.len()).map(|arm| counts.iter().take(arm).sum()).collect();
        self.arms.iter().zip(offsets).flat_map(|(track, offset)| track.plans.iter().enumerate().map(move |(k, p)| (offset + k, p.src_demo)))
    }

    /// Counts this attempt into `stats`, the subtasks numbered through both arms
    /// ([`Self::flat_failure`]).
    pub fn record_into(&self, stats: &mut crate::RunStats, counts: &[usize]) {
        stats.record_sources(self.success, self.flat_sources(counts), self.flat_failure(counts).as_ref(), None);
    }

    /// The attempt as a source demo named `name`, one view per arm (its poses, targets and
    /// gripper; the objects and signals the same in each): what [`TwoArmGenerator::new`] takes,
    /// and what a two-arm source file reads back as.
    #[must_use]
    pub fn arm_views(&self, name: &str) -> Vec<SourceDemo> {
        self.arms
            .iter()
            .map(|track| SourceDemo {
                name: name.to_owned(),
                eef_poses: track.eef_poses.clone(),
                target_poses: track.target_poses.clone(),
                gripper_actions: track.gripper_actions.clone(),
                object_poses: self.object_poses.clone(),
                subtask_term_signals: self.subtask_term_signals.clone(),
                manual_subtask_ends: None,
                manual_subtask_starts: None,
                sim: crate::demo::SimPayload { actions: self.actions.clone(), states: self.states.clone(), model_xml: None },
            })
            .collect()
    }
}

/// A two-arm spec bound to its source demos, one view per arm (each arm's poses, targets and
/// grippers; the objects and signals the same in both).
#[derive(Debug, Clone)]
pub struct TwoArmGenerator {
    spec: TwoArmSpec,
    /// Per arm: the one-arm generator of its subtasks (`None` for an arm with none).
    arms: Vec<Option<Generator>>,
    /// Per arm: the gripper it holds before its first subtask (its first demo's first).
    rest_grippers: Vec<Vec<f64>>,
}

/// A subtask planned as the schedule starts it.
struct Planned {
    subtask: ArmSubtask,
    plan: SubtaskPlan,
    waypoints: Vec<(Waypoint, WaypointKind)>,
}

/// One arm as an attempt runs.
struct ArmRun {
    waypoints: Vec<(Waypoint, WaypointKind)>,
    selected: Option<usize>,
    last_target: Option<Pose>,
    hold: Option<Pose>,
    hold_gripper: Vec<f64>,
    signal_seen: bool,
}

impl TwoArmGenerator {
    /// Checks the spec against each arm's view of the source demos.
    ///
    /// # Errors
    /// As [`Generator::new`] for each arm (naming it), and [`EngineError::Config`] when the views
    /// are not of the same demos.
    pub fn new(spec: TwoArmSpec, sources: Vec<SourceDataset>) -> Result<Self, EngineError> {
        spec.check("two-arm spec")?;
        let config = |field: &str, reason: String| EngineError::Config { file: "source demos".to_owned(), field: field.to_owned(), reason };
        if sources.len() != spec.arms.len() {
            return Err(config("arms", format!("{} views of the source demos for {} arms", sources.len(), spec.arms.len())));
        }
        let names = |d: &SourceDataset| d.demos.iter().map(|demo| (demo.name.clone(), demo.len())).collect::<Vec<_>>();
        let first = sources.first().map(names).unwrap_or_default();
        if let Some(other) = sources.iter().position(|d| names(d) != first) {
            return Err(config("demos", format!("arm {other}'s view has other demos (or lengths) than arm 0's")));
        }
        let mut arms = Vec::new();
        let mut rest_grippers = Vec::new();
        for (arm, dataset) in sources.into_iter().enumerate() {
            rest_grippers.push(dataset.demos.first().map(|d| d.gripper_actions.row(0).to_vec()).unwrap_or_default());
            let Some(arm_spec) = spec.arm_spec(arm).filter(|s| !s.subtasks.is_empty()) else {
                arms.push(None);
                continue;
            };
            let generator = Generator::new(arm_spec, dataset).map_err(|e| match e {
                EngineError::Config { file, field, reason } => EngineError::Config { file, field: format!("arm[{arm}].{field}"), reason },
                other => other,
            })?;
            arms.push(Some(generator));
        }
        Ok(Self { spec, arms, rest_grippers })
    }

    /// The spec.
    #[must_use]
    pub fn spec(&self) -> &TwoArmSpec {
        &self.spec
    }

    /// Runs attempt `index`: samples a scene, then steps both arms through their subtasks as the
    /// schedule starts and ends them.
    ///
    /// # Errors
    /// Only [`EnvError::Fatal`] problems; a failed attempt is an `Ok` record.
    #[allow(clippy::too_many_lines)] // one loop: plan what starts, act, record, end what ends
    pub fn attempt<E: TwoArmEnvironment + ?Sized>(&self, env: &mut E, index: u64) -> Result<TwoArmAttempt, EngineError> {
        let settings = &self.spec.generation;
        let mut rng = attempt_rng(settings.seed, index);
        let fatal = |e: EnvError| EngineError::Env { attempt: index, source: e };
        let arms = self.arms.len();
        let action_dim: usize = (0..arms).map(|a| POSE_ACTION_DIM + env.gripper_dim(a)).sum();
        let mut attempt = TwoArmAttempt {
            index,
            success: false,
            failure: None,
            initial_object_poses: BTreeMap::new(),
            initial_state: Vec::new(),
            states: Rows::new(0),
            actions: Rows::new(action_dim),
            object_poses: BTreeMap::new(),
            subtask_term_signals: BTreeMap::new(),
            arms: (0..arms).map(|a| ArmTrack { gripper_actions: Rows::new(env.gripper_dim(a)), ..ArmTrack::default() }).collect(),
        };
        let unstable = |e: EnvError, arm: Option<usize>, subtask: usize| match e {
            EnvError::Unstable { reason } => Ok(TwoArmFailure { arm, subtask, reason: FailureReason::Unstable { reason } }),
            other => Err(fatal(other)),
        };
        if let Err(e) = env.reset(&mut rng) {
            attempt.failure = Some(unstable(e, None, 0)?);
            return Ok(attempt);
        }
        attempt.initial_object_poses = env.object_poses();
        attempt.initial_state = env.state();
        attempt.states = Rows::new(attempt.initial_state.len());
        let spans: Vec<Option<Vec<Vec<Span>>>> =
            self.arms.iter().map(|g| g.as_ref().map(|g| g.segmentation().draw_spans(&mut rng))).collect();
        let mut schedule = self.spec.schedule().map_err(|e| EngineError::Config {
            file: "two-arm spec".to_owned(),
            field: "coordination".to_owned(),
            reason: e.0,
        })?;
        let mut runs: Vec<ArmRun> = (0..arms)
            .map(|a| ArmRun {
                waypoints: Vec::new(),
                selected: None,
                last_target: None,
                hold: None,
                hold_gripper: self.rest_grippers.get(a).cloned().unwrap_or_default(),
                signal_seen: false,
            })
            .collect();
        loop {
            while let Some(group) = schedule.ready().into_iter().next() {
                let planned = self.plan_group(env, &group, &runs, &spans, &mut rng).map_err(fatal)?;
                let lengths: Vec<(ArmSubtask, usize)> = planned.iter().map(|p| (p.subtask, p.waypoints.len())).collect();
                schedule.start(&lengths).map_err(|reason| fatal(EnvError::Fatal { reason }))?;
                for Planned { subtask: (arm, _), mut plan, waypoints } in planned {
                    let (Some(run), Some(track)) = (runs.get_mut(arm), attempt.arms.get_mut(arm)) else { continue };
                    plan.first_step = attempt.actions.len();
                    run.selected = Some(plan.src_demo);
                    run.signal_seen = false;
                    run.waypoints = waypoints;
                    track.plans.push(plan);
                }
            }
            if schedule.is_done() {
                break;
            }
            let steps = schedule.steps();
            let mut action = Vec::with_capacity(action_dim);
            let state = env.state();
            let signals = env.subtask_term_signals();
            for (arm, step) in steps.iter().enumerate() {
                let (Some(run), Some(track)) = (runs.get_mut(arm), attempt.arms.get_mut(arm)) else { continue };
                let (pose, gripper, noise, src, subtask) = match *step {
                    ArmStep::Run { subtask, step } => {
                        let (w, _) =
                            run.waypoints.get(step).ok_or_else(|| fatal(EnvError::Fatal { reason: "step past the segment".to_owned() }))?;
                        let src = track.plans.last().map_or(0, |p| p.src_demo);
                        (w.pose, w.gripper.clone(), w.noise, src, subtask)
                    }
                    ArmStep::Hold => {
                        let pose = *run.hold.get_or_insert_with(|| env.eef_pose(arm));
                        let waiting_for = track.plans.len().min(schedule.counts().get(arm).copied().unwrap_or(1).saturating_sub(1));
                        (pose, run.hold_gripper.clone(), 0.0, track.plans.last().map_or(0, |p| p.src_demo), waiting_for)
                    }
                };
                let mut pose_action = env.target_pose_to_action(arm, &pose);
                add_noise(&mut pose_action, noise, &mut rng);
                if gripper.len() != env.gripper_dim(arm) {
                    return Err(fatal(EnvError::Fatal {
                        reason: format!(
                            "arm {arm}: source gripper actions have {} values but the environment's have {}",
                            gripper.len(),
                            env.gripper_dim(arm)
                        ),
                    }));
                }
                let arm_action: Vec<f64> = pose_action.iter().copied().chain(gripper.iter().copied()).collect();
                let shape = |e: EngineError| fatal(EnvError::Fatal { reason: e.to_string() });
                track.eef_poses.push(env.eef_pose(arm));
                track.target_poses.push(env.action_to_target_pose(arm, &arm_action));
                track.gripper_actions.push(&gripper).map_err(shape)?;
                track.src_demo_labels.push(src);
                track.subtask_labels.push(subtask);
                track.holding.push(matches!(step, ArmStep::Hold));
                if let ArmStep::Run { subtask, .. } = *step
                    && let Some(signal) = self.signal(arm, subtask)
                {
                    run.signal_seen |= signals.get(signal).is_some_and(|&v| v != 0);
                }
                action.extend(arm_action);
            }
            let shape = |e: EngineError| fatal(EnvError::Fatal { reason: e.to_string() });
            attempt.states.push(&state).map_err(shape)?;
            attempt.actions.push(&action).map_err(shape)?;
            for (name, pose) in env.object_poses() {
                attempt.object_poses.entry(name).or_default().push(pose);
            }
            for (name, value) in &signals {
                attempt.subtask_term_signals.entry(name.clone()).or_default().push(*value);
            }
            if let Err(e) = env.step(&action) {
                let running = steps.iter().position(|s| matches!(s, ArmStep::Run { .. }));
                let subtask =
                    running.and_then(|a| steps.get(a)).map_or(0, |s| if let ArmStep::Run { subtask, .. } = s { *subtask } else { 0 });
                attempt.failure = Some(unstable(e, running, subtask)?);
                return Ok(attempt);
            }
            attempt.success |= env.is_success();
            for (arm, k) in schedule.advance() {
                let Some(run) = runs.get_mut(arm) else { continue };
                if let Some((w, _)) = run.waypoints.last() {
                    run.hold = Some(w.pose);
                    run.last_target = Some(w.pose);
                    run.hold_gripper.clone_from(&w.gripper);
                }
                if let Some(signal) = self.signal(arm, k) {
                    run.signal_seen |= env.subtask_term_signals().get(signal).is_some_and(|&v| v != 0);
                    if !run.signal_seen && attempt.failure.is_none() {
                        let reason = FailureReason::SignalNeverOn { signal: signal.to_owned() };
                        attempt.failure = Some(TwoArmFailure { arm: Some(arm), subtask: k, reason });
                        if settings.early_abort && !attempt.success {
                            return Ok(attempt);
                        }
                    }
                }
            }
        }
        if attempt.success {
            attempt.failure = None;
        } else if attempt.failure.is_none() {
            let reason = FailureReason::TaskNotAchieved { unmet: env.unmet_success() };
            let subtask = schedule.counts().first().map_or(0, |n| n.saturating_sub(1));
            attempt.failure = Some(TwoArmFailure { arm: None, subtask, reason });
        }
        Ok(attempt)
    }

    /// Plans a group the schedule starts: one subtask, or a coordinated pair (the second taking
    /// the first's source demo and source object pose; the shorter padded with its last
    /// waypoint).
    fn plan_group<E: TwoArmEnvironment + ?Sized, R: Rng + ?Sized>(
        &self,
        env: &E,
        group: &[ArmSubtask],
        runs: &[ArmRun],
        spans: &[Option<Vec<Vec<Span>>>],
        rng: &mut R,
    ) -> Result<Vec<Planned>, EnvError> {
        let mut planned: Vec<Planned> = Vec::new();
        for &(arm, k) in group {
            let generator = self.generator(arm).map_err(|e| EnvError::Fatal { reason: e.to_string() })?;
            let run = runs.get(arm).ok_or_else(|| EnvError::Fatal { reason: format!("no arm {arm}") })?;
            let partner = planned.first();
            let here = PlanInput {
                subtask: k,
                world_from_eef: env.eef_pose(arm),
                objects: env.object_poses(),
                last_target: run.last_target,
                selected: run.selected,
                forced: partner.map(|p| p.plan.src_demo),
                world_from_obj_src: partner.and_then(|p| p.plan.world_from_obj_src),
            };
            let arm_spans = spans.get(arm).and_then(Option::as_ref).map_or(&[][..], Vec::as_slice);
            let (plan, waypoints) = generator.plan_subtask(&here, arm_spans, rng).map_err(|reason| EnvError::Fatal { reason })?;
            planned.push(Planned { subtask: (arm, k), plan, waypoints });
        }
        if planned.len() > 1 {
            let longest = planned.iter().map(|p| p.waypoints.len()).max().unwrap_or(0);
            for p in &mut planned {
                if let Some(last) = p.waypoints.last().cloned() {
                    p.waypoints.resize(longest, last);
                }
                p.plan.waypoints = p.waypoints.iter().map(|(w, k)| (w.pose, *k)).collect();
            }
        }
        Ok(planned)
    }

    fn generator(&self, arm: usize) -> Result<&Generator, EngineError> {
        self.arms.get(arm).and_then(Option::as_ref).ok_or_else(|| EngineError::Config {
            file: "two-arm spec".to_owned(),
            field: format!("arm[{arm}]"),
            reason: "the schedule started a subtask of an arm that has none".to_owned(),
        })
    }

    /// The signal that ends `arm`'s subtask `k`, but for its last (which ends with the demo).
    fn signal(&self, arm: usize, k: usize) -> Option<&str> {
        let subtasks = &self.spec.arms.get(arm)?.subtasks;
        (k + 1 < subtasks.len()).then(|| subtasks.get(k)?.term_signal.as_deref()).flatten()
    }
}

/// Planned transit needs a one-arm collision space; a two-arm spec refuses it ([`TwoArmSpec::check`]).
pub(crate) fn refuses_planned_transit(spec: &TwoArmSpec) -> Option<String> {
    spec.arms
        .iter()
        .enumerate()
        .find_map(|(a, arm)| arm.subtasks.iter().position(|s| s.transit == Transit::Plan).map(|k| format!("arm[{a}].subtask[{k}].transit")))
}
