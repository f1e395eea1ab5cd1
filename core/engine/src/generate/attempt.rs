//! How one attempt runs: the generator plans every subtask (source choice, transform,
//! interpolation) and executes it step by step with noise in an [`Environment`].
//!
//! Planning and executing one attempt share the generator's state and the attempt's random
//! stream, so both live here.

use std::collections::BTreeMap;

use rand::Rng;
use rand_distr::StandardNormal;

use super::attempt_rng;
use super::records::{Attempt, Failure, FailureReason, SubtaskPlan, Trajectory};
use crate::EngineError;
use crate::action::POSE_ACTION_DIM;
use crate::base::{BASE_ACTION_DIM, hold_on_base};
use crate::demo::{SourceDataset, SubtaskMarks};
use crate::env::{EnvError, Environment};
use crate::pose::Pose;
use crate::segment::{Segmentation, Span};
use crate::select::{SceneContext, pick_source, source_distances};
use crate::spec::{TaskSpec, Transit};
use crate::transform::{Waypoint, WaypointKind, subtask_waypoints, transform_segment};
use crate::transit::plan_transit;

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
        let demos = dataset.demos.len();
        let excluded = &spec.generation.exclude_sources;
        let refuse = |reason: String| {
            Err(EngineError::Config { file: "task spec".to_owned(), field: "generation.exclude_sources".to_owned(), reason })
        };
        if let Some(d) = excluded.iter().find(|&&d| d >= demos) {
            return refuse(format!("names source demo {d}, but the source file has {demos} (0 to {})", demos.saturating_sub(1)));
        }
        if (0..demos).all(|d| excluded.contains(&d)) {
            return refuse(format!("excludes all {demos} source demos; keep at least one"));
        }
        Ok(Self { spec, dataset, segmentation })
    }

    /// The same generator with the hand-made `marks`: subtask ends in place of the signals, and
    /// segment starts in place of the approach detector, for the demos each names.
    ///
    /// # Errors
    /// [`EngineError::UnknownName`] for a demo that does not exist, [`EngineError::Segmentation`]
    /// for ends or starts that do not fit the demo.
    pub fn with_marks(&self, marks: &SubtaskMarks) -> Result<Self, EngineError> {
        let mut dataset = self.dataset.clone();
        let unknown = |field: &str, name: &String| EngineError::UnknownName {
            field: field.to_owned(),
            name: name.clone(),
            available: self.dataset.demos.iter().map(|d| d.name.clone()).collect(),
        };
        for (name, demo_ends) in &marks.ends {
            let demo = dataset.demos.iter_mut().find(|d| &d.name == name).ok_or_else(|| unknown("subtask ends", name))?;
            demo.manual_subtask_ends = Some(demo_ends.clone());
        }
        for (name, demo_starts) in &marks.starts {
            let demo = dataset.demos.iter_mut().find(|d| &d.name == name).ok_or_else(|| unknown("segment starts", name))?;
            demo.manual_subtask_starts = Some(demo_starts.clone());
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
        let mut attempt = self.run_attempt(env, index, overrides)?;
        attempt.cause = crate::diagnose::cause(&self.spec, &self.dataset, &attempt);
        if let Some(crate::diagnose::Cause::ArmLagged { step, .. }) = &attempt.cause {
            let found = crate::diagnose::joint_at_limit(env, &attempt, *step..*step + crate::diagnose::LAG_STEPS);
            if let Some(crate::diagnose::Cause::ArmLagged { joint, .. }) = &mut attempt.cause {
                *joint = found;
            }
        }
        Ok(attempt)
    }

    /// [`Generator::attempt_with`] but for its failure's cause.
    fn run_attempt<E: Environment + ?Sized>(&self, env: &mut E, index: u64, overrides: &Overrides) -> Result<Attempt, EngineError> {
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
            obstacle_contact_steps: 0,
            cause: None,
        };
        if let Err(e) = env.reset(&mut rng) {
            attempt.failure = Some(unstable(e, 0)?);
            return Ok(attempt);
        }
        env.place_objects(&overrides.object_poses).map_err(fatal)?;
        attempt.initial_object_poses = env.object_poses();
        attempt.initial_state = env.state();
        attempt.trajectory = Trajectory::for_env(&*env);
        let spans = self.segmentation.draw_spans(&mut rng);
        let mut selected: Option<usize> = None;
        let mut last_target: Option<Pose> = None;
        // A mobile base's drive in progress: the hand's target on the base (it may run on into
        // the next subtask).
        let mut held_on_base = None;
        for (subtask_index, subtask) in self.spec.subtasks.iter().enumerate() {
            let here = PlanInput {
                subtask: subtask_index,
                world_from_eef: env.eef_pose(),
                objects: env.object_poses(),
                last_target,
                selected,
                forced: sources.get(subtask_index).copied().flatten(),
                world_from_obj_src: None,
            };
            let (mut plan, mut waypoints) =
                self.plan_subtask(&here, &spans, &mut rng).map_err(|reason| fatal(EnvError::Fatal { reason }))?;
            if subtask.transit == Transit::Plan {
                let planned = self.bridge_by_plan(env, subtask_index, &mut plan, &mut waypoints, &mut rng).map_err(fatal)?;
                if let Err(reason) = planned {
                    attempt.src_demo_per_subtask.push(plan.src_demo);
                    attempt.plans.push(SubtaskPlan { first_step: attempt.trajectory.len(), ..plan });
                    attempt.failure = Some(Failure { subtask: subtask_index, reason });
                    return Ok(attempt);
                }
            }
            selected = Some(plan.src_demo);
            attempt.src_demo_per_subtask.push(plan.src_demo);
            let labels = StepLabels { src_demo: plan.src_demo, subtask: subtask_index, kind: WaypointKind::Transformed };
            attempt.plans.push(SubtaskPlan { first_step: attempt.trajectory.len(), ..plan });
            let mut signal_seen = false;
            let signal = if subtask_index + 1 < self.spec.subtasks.len() { subtask.term_signal.as_deref() } else { None };
            // After a planned transit the segment starts from the object's pose then.
            let segment_start = waypoints.iter().position(|(_, k)| *k != WaypointKind::Transit).filter(|&i| i > 0);
            for i in 0..waypoints.len() {
                if Some(i) == segment_start
                    && let Some(plan) = attempt.plans.last_mut()
                {
                    follow_object(env, subtask.object_ref.as_deref(), plan, &mut waypoints, i);
                }
                // The target commanded last (not the one recorded, which the action's clipping may
                // have cut short of it while the arm was lifting fast).
                let commanded = i.checked_sub(1).and_then(|j| waypoints.get(j)).map(|(w, _)| w.pose).or(last_target);
                hold_on_base(&*env, &mut waypoints, i, &mut held_on_base, commanded);
                let Some((waypoint, kind)) = waypoints.get(i) else { break };
                let signals = match execute_step(env, waypoint, StepLabels { kind: *kind, ..labels }, &mut attempt.trajectory, &mut rng) {
                    Ok(signals) => signals,
                    Err(e) => {
                        attempt.failure = Some(unstable(e, subtask_index)?);
                        return Ok(attempt);
                    }
                };
                signal_seen |= signal.is_some_and(|s| signals.get(s).is_some_and(|&v| v != 0));
                attempt.success |= env.is_success();
                if env.obstacle_contacts() > 0 {
                    attempt.obstacle_contact_steps += 1;
                }
            }
            last_target = waypoints.last().map(|(w, _)| w.pose).or(last_target);
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
                world_from_obj_src: None,
            };
            let (mut planned, mut waypoints) =
                self.plan_subtask(&here, &spans, &mut rng).map_err(|reason| fatal(EnvError::Fatal { reason }))?;
            if subtask == 0 && self.spec.subtasks.first().is_some_and(|s| s.transit == Transit::Plan) {
                // Only the first transit can be planned ahead: the robot's joints at a later
                // subtask's start are known once the attempt gets there.
                let _ = self.bridge_by_plan(env, subtask, &mut planned, &mut waypoints, &mut rng).map_err(fatal)?;
            }
            planned.first_step = plan.subtasks.iter().map(|s| s.waypoints.len()).sum();
            selected = Some(planned.src_demo);
            last_target = waypoints.last().map(|(w, _)| w.pose).or(last_target);
            plan.subtasks.push(planned);
        }
        Ok(plan)
    }

    /// Plans a collision-free transit from the robot's present state to the segment's first pose
    /// and puts it before the segment (in `waypoints` and `plan`). `Ok(Err(reason))` when no path
    /// was found (the attempt fails with that reason); `Err` only when the environment cannot plan.
    fn bridge_by_plan<E: Environment + ?Sized, R: Rng + ?Sized>(
        &self,
        env: &mut E,
        subtask: usize,
        plan: &mut SubtaskPlan,
        waypoints: &mut Vec<(Waypoint, WaypointKind)>,
        rng: &mut R,
    ) -> Result<Result<(), FailureReason>, EnvError> {
        let Some((goal, _)) = waypoints.first().cloned() else { return Ok(Ok(())) };
        let planned = plan_transit(env.transit_space()?.as_mut(), &goal.pose, &self.spec.generation.planner, rng);
        let path = match planned {
            Ok(path) => path,
            Err(e) => {
                plan.transit = Some(e.stats());
                return Ok(Err(FailureReason::NoTransitPath { samples: e.stats().samples, detail: e.to_string() }));
            }
        };
        plan.transit = Some(path.stats);
        let noise = self.spec.subtasks.get(subtask).map_or(0.0, crate::SubtaskSpec::bridge_noise);
        // The path ends at the goal, held a few steps for the arm to catch up with it.
        let hold = std::iter::repeat_n(goal.pose, self.spec.generation.planner.hold_steps);
        let bridge = path
            .poses
            .iter()
            .copied()
            .chain(hold)
            .map(|pose| (Waypoint { pose, gripper: goal.gripper.clone(), noise, base: Vec::new() }, WaypointKind::Transit));
        waypoints.splice(0..0, bridge);
        plan.waypoints = waypoints.iter().map(|(w, k)| (w.pose, *k)).collect();
        Ok(Ok(()))
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
    #[allow(
        clippy::indexing_slicing,
        reason = "a span lies inside its demo, start < end <= len (Segmentation::new checks every boundary against the \
                  demo's length), and a validated demo has every per-step field len long (Generator::new validates)"
    )]
    pub(crate) fn plan_subtask<R: Rng + ?Sized>(
        &self,
        here: &PlanInput,
        spans: &[Vec<Span>],
        rng: &mut R,
    ) -> Result<(SubtaskPlan, Vec<(Waypoint, WaypointKind)>), String> {
        let settings = &self.spec.generation;
        let subtask = self.spec.subtasks.get(here.subtask).ok_or_else(|| format!("the spec has no subtask {}", here.subtask))?;
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
                // The object that picks the demo: `selection_object`, else the subtask's own.
                let (measured, world_from_measured) = match &subtask.selection_object {
                    Some(name) => (Some(name.as_str()), here.objects.get(name).copied()),
                    None => (subtask.object_ref.as_deref(), world_from_obj_new),
                };
                let scene = SceneContext { world_from_eef: &here.world_from_eef, world_from_obj: world_from_measured.as_ref() };
                let distances = source_distances(&subtask.selection, demos, spans, here.subtask, measured, scene);
                (pick_source(&subtask.selection, distances.as_deref(), demos.len(), &settings.exclude_sources, rng), distances)
            }
        };
        let demo_index = here.forced.unwrap_or(demo_index);
        let (demo, &(start, end)) = demos
            .get(demo_index)
            .zip(spans.get(demo_index).and_then(|s| s.get(here.subtask)))
            .ok_or_else(|| format!("source demo {demo_index} has no span for subtask {}", here.subtask))?;
        let mut source_poses = Vec::with_capacity(end - start + 1);
        let mut gripper: Vec<Vec<f64>> = Vec::with_capacity(end - start + 1);
        if is_first || settings.transform_first_robot_pose {
            source_poses.push(demo.eef_poses[start]);
            gripper.push(demo.gripper_actions.row(start).to_vec());
        }
        source_poses.extend_from_slice(&demo.target_poses[start..end]);
        gripper.extend((start..end).map(|t| demo.gripper_actions.row(t).to_vec()));
        let world_from_obj_src = match here.world_from_obj_src {
            Some(pose) => Some(pose),
            None => subtask
                .object_ref
                .as_ref()
                .map(|name| {
                    demo.object_poses
                        .get(name)
                        .and_then(|poses| poses.get(start))
                        .copied()
                        .ok_or_else(|| format!("{} has no pose of {name:?}", demo.name))
                })
                .transpose()?,
        };
        let interp_start = match here.last_target {
            Some(pose) if settings.interpolate_from_last_target_pose && !is_first => pose,
            _ => here.world_from_eef,
        };
        let interp_noise = subtask.bridge_noise();
        // A planned transit replaces the interpolation (it is planned when the attempt gets here).
        let num_interp = if subtask.transit == Transit::Plan { 0 } else { subtask.num_interpolation_steps };
        let object = world_from_obj_new.as_ref().zip(world_from_obj_src.as_ref());
        let (transformed, waypoints) = match crate::base::plan_segment(
            demo,
            (start, end),
            &interp_start,
            object,
            num_interp,
            subtask.num_fixed_steps,
            subtask.action_noise,
            interp_noise,
        ) {
            // The source drove a mobile base here: its poses one per source step.
            Some((planned, waypoints)) => {
                source_poses = demo.target_poses[start..end].to_vec();
                (planned, waypoints)
            }
            None => {
                let transformed = match object {
                    Some((new, src)) => transform_segment(new, src, &source_poses),
                    None => source_poses.clone(),
                };
                let waypoints = subtask_waypoints(
                    &interp_start,
                    &transformed,
                    &gripper,
                    num_interp,
                    subtask.num_fixed_steps,
                    subtask.action_noise,
                    interp_noise,
                );
                (transformed, waypoints)
            }
        };
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
            transit: None,
        };
        Ok((plan, waypoints))
    }
}

/// Moves the segment (its waypoints from `from` on, and `plan`'s transformed poses) with its
/// reference object, if the object moved since the segment was transformed: it may settle while a
/// planned transit runs (a nut dropped at the reset lands), and the segment is relative to it.
fn follow_object<E: Environment + ?Sized>(
    env: &E,
    object: Option<&str>,
    plan: &mut SubtaskPlan,
    waypoints: &mut [(Waypoint, WaypointKind)],
    from: usize,
) {
    let (Some(name), Some(planned)) = (object, plan.world_from_obj_new) else { return };
    let Some(now) = env.object_poses().get(name).copied() else { return };
    let moved = now * planned.inverse();
    for (w, _) in waypoints.iter_mut().skip(from) {
        w.pose = moved * w.pose;
    }
    for pose in &mut plan.transformed_poses {
        *pose = moved * *pose;
    }
    for (pose, _) in plan.waypoints.iter_mut().skip(from) {
        *pose = moved * *pose;
    }
    plan.world_from_obj_new = Some(now);
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
pub(crate) struct PlanInput {
    pub(crate) subtask: usize,
    pub(crate) world_from_eef: Pose,
    pub(crate) objects: BTreeMap<String, Pose>,
    pub(crate) last_target: Option<Pose>,
    /// The source demo of the previous subtask.
    pub(crate) selected: Option<usize>,
    /// A source demo the caller chose.
    pub(crate) forced: Option<usize>,
    /// The reference object's source pose to transform from, in place of the demo's at the
    /// segment's start (two arms coordinated: one transform for both).
    pub(crate) world_from_obj_src: Option<Pose>,
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

/// Adds Gaussian noise of standard deviation `noise` to each pose dimension of an action, clipped
/// to `[-1, 1]`; draws nothing when `noise` is 0 (an arm holding still keeps the stream as it is).
pub(crate) fn add_noise<R: Rng + ?Sized>(pose_action: &mut [f64; 6], noise: f64, rng: &mut R) {
    if noise > 0.0 {
        for a in pose_action {
            let z: f64 = rng.sample(StandardNormal);
            *a = (*a + noise * z).clamp(-1.0, 1.0);
        }
    }
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
    add_noise(&mut pose_action, waypoint.noise, rng);
    let base_dim = if env.mobile_base().is_some() { BASE_ACTION_DIM } else { 0 };
    let mut action = Vec::with_capacity(POSE_ACTION_DIM + waypoint.gripper.len() + base_dim);
    action.extend_from_slice(&pose_action);
    action.extend_from_slice(&waypoint.gripper);
    if action.len() + base_dim != env.action_dim() {
        return Err(EnvError::Fatal {
            reason: format!(
                "source gripper actions have {} values but the environment's actions have {} gripper values",
                waypoint.gripper.len(),
                env.action_dim().saturating_sub(POSE_ACTION_DIM + base_dim)
            ),
        });
    }
    match (base_dim, waypoint.base.len()) {
        (_, 0) => action.extend(std::iter::repeat_n(0.0, base_dim)),
        (dim, given) if dim == given => action.extend_from_slice(&waypoint.base),
        (dim, given) => {
            return Err(EnvError::Fatal {
                reason: format!("the source's actions move a mobile base with {given} values, but this robot's base takes {dim}"),
            });
        }
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

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)] // tests fail loudly by design

    use std::collections::BTreeMap;

    use rand::SeedableRng;

    use super::{Generator, PlanInput};
    use crate::TaskSpec;
    use crate::demo::SourceDataset;
    use crate::pose::{Pose, Rot, Vec3, pose_from_parts};

    /// `selection_object` picks the source demo by that object's pose, not the subtask's own:
    /// demo 0 is nearest by `a`, demo 1 by `b`.
    #[test]
    fn a_selection_object_picks_the_source_by_another_objects_pose() {
        let at = |x: f64| pose_from_parts(Vec3::new(x, 0.0, 0.0), Rot::identity());
        let demo = |a: f64, b: f64| {
            let mut d = crate::testing::demo_with_object_at("a", a);
            d.object_poses.insert("b".to_owned(), vec![at(b); 10]);
            d
        };
        let picked = |selection_object: &str| {
            let toml = format!(
                "[[subtask]]\nobject_ref = \"a\"\nselection = {{ strategy = \"nearest_neighbor_object\", nn_k = 1 }}\n{selection_object}"
            );
            let spec = TaskSpec::from_toml_str(&toml, "t.toml").unwrap();
            let dataset = SourceDataset { demos: vec![demo(0.0, 1.0), demo(1.0, 0.0)], env_args: None };
            let generator = Generator::new(spec, dataset).unwrap();
            let here = PlanInput {
                subtask: 0,
                world_from_eef: Pose::identity(),
                objects: BTreeMap::from([("a".to_owned(), at(0.0)), ("b".to_owned(), at(0.0))]),
                last_target: None,
                selected: None,
                forced: None,
                world_from_obj_src: None,
            };
            let spans = vec![vec![(0, 10)], vec![(0, 10)]];
            generator.plan_subtask(&here, &spans, &mut rand_chacha::ChaCha8Rng::seed_from_u64(1)).unwrap().0.src_demo
        };
        assert_eq!(picked(""), 0);
        assert_eq!(picked("selection_object = \"b\"\n"), 1);
        // A selection object the scene lacks is named by check_names.
        let spec = TaskSpec::from_toml_str("[[subtask]]\nobject_ref = \"a\"\nselection_object = \"c\"\n", "t.toml").unwrap();
        let err = spec.check_names(&["a".to_owned()], &[]).unwrap_err().to_string();
        assert!(err.contains("subtask[0].selection_object") && err.contains('c'), "{err}");
    }
}
