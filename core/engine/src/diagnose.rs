//! Why an attempt failed, read from what it recorded: the cause behind the place
//! ([`FailureReason`] says which subtask and which check; a [`Cause`] says what happened there).
//!
//! Every cause comes from the attempt's own trajectory (hand, targets, gripper, objects) and, for
//! an object that moved, from the source segment it copied, so that a drawer the segment pulls
//! is not taken for a knocked one. The checks run in order; the first that holds names the cause:
//!
//! 1. the simulation failed (unstable, no transit path);
//! 2. the subtask's object moved from where its segment was planned before the hand took it,
//!    where the source's did not ([`Cause::ObjectMoved`]);
//! 3. the hand fell behind where the source's was ([`Cause::ArmLagged`]);
//! 4. an object that moved with the closed hand was lost from it ([`Cause::GraspSlipped`]);
//! 5. the gripper closed but nothing moved with it and the signal stayed off
//!    ([`Cause::GraspMissed`]);
//! 6. otherwise the segment ran out with its signal off ([`Cause::RanOutOfSteps`]), or the task's
//!    check failed at the end ([`Cause::SuccessUnmet`]).

use serde::{Deserialize, Serialize};

use crate::demo::{Rows, SourceDataset};
use crate::generate::{Attempt, FailureReason};
use crate::pose::Pose;
use crate::spec::TaskSpec;
use crate::transform::WaypointKind;

/// An object that moves this far (m) from where its segment was planned, while not held, moved.
pub const MOVED_M: f64 = 0.01;
/// ... or turns this far (deg).
pub const TURNED_DEG: f64 = 10.0;
/// The hand further than this (m) from where the source's hand was at the same point of its
/// segment ...
pub const LAG_M: f64 = 0.05;
/// ... for this many steps in a row (1.5 s at 20 Hz) fell behind. The first steps of a segment
/// often trail the source's hand by a few centimetres for a second, the lag the interpolation
/// left (measured on Mug Cleanup's successes: up to 22 steps over 3 cm, 13 cm at most).
pub const LAG_STEPS: usize = 30;
/// Steps over which "moves with the hand" is judged.
pub const HOLD_WINDOW: usize = 5;
/// The hand must move this far (m) over the window for a hold to show ...
pub const HOLD_MIN_TRAVEL_M: f64 = 0.01;
/// ... and the object stay within this of its place in the hand (m).
pub const HOLD_TOL_M: f64 = 0.005;
/// A held object this far (m) from its place in the hand, the gripper still closed, slipped.
pub const SLIP_M: f64 = 0.02;

/// What went wrong in the subtask an attempt failed in.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Cause {
    /// The subtask's object moved from where its segment was planned for before the hand took it
    /// (knocked by the arm or by what it carried, or it rolled), where in the source it stayed.
    ObjectMoved {
        /// The object.
        object: String,
        /// The step it had moved by then.
        step: usize,
        /// How far it had moved (m) and turned (deg).
        moved_m: f64,
        /// How far it had turned (deg).
        turned_deg: f64,
    },
    /// The hand fell behind where the source's hand was at the same point of the segment (a joint
    /// at its limit, a collision, too fast a move).
    ArmLagged {
        /// The first step of the longest stretch behind.
        step: usize,
        /// The largest distance from the source's hand in it (m).
        error_m: f64,
        /// The arm joint at its limit for most of the stretch, when the environment can tell
        /// ([`crate::Environment::joints_at_limit`]).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        joint: Option<String>,
    },
    /// An object moved with the closed hand, then was lost from it.
    GraspSlipped {
        /// The object.
        object: String,
        /// The first step it was seen moving with the hand.
        held_from: usize,
        /// The step it was first more than [`SLIP_M`] from its place in the hand.
        lost_at: usize,
    },
    /// The gripper closed, but the subtask's object never moved with the hand and the signal
    /// stayed off.
    GraspMissed {
        /// The object.
        object: String,
        /// The step the gripper closed.
        step: usize,
        /// How far the hand was there from where the source's hand closed, in the object's
        /// frame (m; `None` when the close is not in the transformed segment).
        off_source_m: Option<f64>,
    },
    /// The segment ran to its end with the signal off, none of the above seen.
    RanOutOfSteps {
        /// The subtask's steps.
        steps: usize,
    },
    /// Every subtask ran but a clause of the task's success check failed at the end.
    SuccessUnmet {
        /// The clause, when the environment names it.
        clause: Option<String>,
    },
    /// The simulation failed (unstable, or no collision-free transit).
    Simulation,
}

impl Cause {
    /// The cause's class, as reports count it (`object_moved`, `grasp_missed`, ...).
    #[must_use]
    pub fn class(&self) -> &'static str {
        match self {
            Self::ObjectMoved { .. } => "object_moved",
            Self::ArmLagged { .. } => "arm_lagged",
            Self::GraspSlipped { .. } => "grasp_slipped",
            Self::GraspMissed { .. } => "grasp_missed",
            Self::RanOutOfSteps { .. } => "ran_out_of_steps",
            Self::SuccessUnmet { .. } => "success_unmet",
            Self::Simulation => "simulation",
        }
    }
}

impl std::fmt::Display for Cause {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::ObjectMoved { object, step, moved_m, turned_deg } => write!(
                f,
                "{object} moved {:.1} cm and turned {turned_deg:.0} deg before the hand took it (by step {step})",
                moved_m * 100.0
            ),
            Self::ArmLagged { step, error_m, joint } => {
                write!(f, "the arm fell {:.1} cm behind the source's hand from step {step}", error_m * 100.0)?;
                match joint {
                    Some(joint) => write!(f, " ({joint} at its limit)"),
                    None => Ok(()),
                }
            }
            Self::GraspSlipped { object, held_from, lost_at } => {
                write!(f, "{object} slipped from the hand: held from step {held_from}, lost at step {lost_at}")
            }
            Self::GraspMissed { object, step, off_source_m: Some(off) } => write!(
                f,
                "the gripper closed at step {step} but {object} never moved with the hand ({:.1} cm from where the source's hand closed)",
                off * 100.0
            ),
            Self::GraspMissed { object, step, off_source_m: None } => {
                write!(f, "the gripper closed at step {step} but {object} never moved with the hand")
            }
            Self::RanOutOfSteps { steps } => write!(f, "the segment's {steps} steps ran out before its signal"),
            Self::SuccessUnmet { clause: Some(clause) } => write!(f, "the success check's {clause} failed at the end"),
            Self::SuccessUnmet { clause: None } => write!(f, "the success check failed at the end"),
            Self::Simulation => write!(f, "the simulation failed"),
        }
    }
}

/// A joint within this of its limit (rad) holds the arm there.
pub const AT_LIMIT: f64 = 0.01;

/// The arm joint `env` finds at its limit ([`AT_LIMIT`]) at the most steps of `steps` of
/// `attempt` (ties to the first in the arm's order), if any.
pub fn joint_at_limit<E: crate::Environment + ?Sized>(env: &E, attempt: &Attempt, steps: std::ops::Range<usize>) -> Option<String> {
    let mut counts: Vec<(String, usize)> = Vec::new();
    for t in steps {
        let Some(state) = attempt.trajectory.states.get(t) else { break };
        for joint in env.joints_at_limit(state, AT_LIMIT) {
            match counts.iter_mut().find(|(name, _)| *name == joint) {
                Some((_, n)) => *n += 1,
                None => counts.push((joint, 1)),
            }
        }
    }
    let most = counts.iter().map(|(_, n)| *n).max()?;
    counts.into_iter().find(|(_, n)| *n == most).map(|(name, _)| name)
}

/// The cause of `attempt`'s failure (`None` for a success), made from `spec`'s subtasks and the
/// `sources` its segments came from.
#[must_use]
pub fn cause(spec: &TaskSpec, sources: &SourceDataset, attempt: &Attempt) -> Option<Cause> {
    let failure = attempt.failure.as_ref()?;
    if matches!(failure.reason, FailureReason::Unstable { .. } | FailureReason::NoTransitPath { .. }) {
        return Some(Cause::Simulation);
    }
    let trajectory = &attempt.trajectory;
    let s = failure.subtask;
    let start = attempt.plans.get(s).map_or(0, |p| p.first_step);
    let end = attempt.plans.get(s + 1).map_or(trajectory.len(), |p| p.first_step).min(trajectory.len());
    if start >= end {
        return Some(fallback(&failure.reason, 0));
    }
    let gripper = &trajectory.gripper_actions;
    let close_step = first_close(gripper, start..end);
    let object = spec.subtasks.get(s).and_then(|sub| sub.object_ref.clone());
    let poses = |name: &str| trajectory.object_poses.get(name);

    if let (Some(name), Some(plan)) = (&object, attempt.plans.get(s))
        && let Some(obj) = poses(name)
        && let Some(moved) = moved_before_taken(trajectory, obj, start, close_step.unwrap_or(end))
        && !source_moved(sources, plan.src_demo, plan.src_span, name)
    {
        let (step, moved_m, turned_deg) = moved;
        return Some(Cause::ObjectMoved { object: name.clone(), step, moved_m, turned_deg });
    }
    if let Some(lag) = lagged(sources, attempt, s) {
        return Some(lag);
    }
    // An object held in this subtask or carried into it (from the last close before its end).
    let hold_from = first_close(gripper, (0..end).rev()).unwrap_or(start);
    for (name, obj) in &trajectory.object_poses {
        if let Some((held_from, lost_at)) = slipped(trajectory, obj, hold_from, end, start) {
            return Some(Cause::GraspSlipped { object: name.clone(), held_from, lost_at });
        }
    }
    if let (FailureReason::SignalNeverOn { .. }, Some(step), Some(name)) = (&failure.reason, close_step, &object)
        && let Some(obj) = poses(name)
        && first_held(trajectory, obj, step, end).is_none()
    {
        let off_source_m = tracking_errors(sources, attempt, s).into_iter().find(|(t, _)| *t + 1 >= step).map(|(_, m)| m);
        return Some(Cause::GraspMissed { object: name.clone(), step, off_source_m });
    }
    Some(fallback(&failure.reason, end - start))
}

fn fallback(reason: &FailureReason, steps: usize) -> Cause {
    match reason {
        FailureReason::TaskNotAchieved { unmet } => Cause::SuccessUnmet { clause: unmet.clone() },
        FailureReason::SignalNeverOn { .. } => Cause::RanOutOfSteps { steps },
        FailureReason::Unstable { .. } | FailureReason::NoTransitPath { .. } => Cause::Simulation,
    }
}

/// How far `b` is from `a`: metres and degrees.
fn apart(a: &Pose, b: &Pose) -> (f64, f64) {
    ((b.translation.vector - a.translation.vector).norm(), a.rotation.angle_to(&b.rotation).to_degrees())
}

/// `(metres, degrees)` from `a` to `b` when that is more than [`MOVED_M`] or [`TURNED_DEG`].
fn moved(a: &Pose, b: &Pose) -> Option<(f64, f64)> {
    let (m, deg) = apart(a, b);
    (m > MOVED_M || deg > TURNED_DEG).then_some((m, deg))
}

/// Whether `gripper`'s command at step `t` closes it, as subtask detection reads a command.
fn closed(gripper: &Rows, t: usize) -> bool {
    gripper.get(t).and_then(|g| g.first()).is_some_and(|&g| crate::detect::closed(g))
}

/// The first of `steps` at which `gripper` switches to closed.
fn first_close(gripper: &Rows, mut steps: impl Iterator<Item = usize>) -> Option<usize> {
    steps.find(|&t| closed(gripper, t) && (t == 0 || !closed(gripper, t - 1)))
}

/// The first step in `start..until` at which `obj` had moved [`MOVED_M`] or turned [`TURNED_DEG`]
/// from its pose at `start` without being held: `(step, metres, degrees)`.
fn moved_before_taken(trajectory: &crate::generate::Trajectory, obj: &[Pose], start: usize, until: usize) -> Option<(usize, f64, f64)> {
    let first = obj.get(start)?;
    (start..until.min(obj.len())).find_map(|t| {
        let (m, deg) = moved(first, obj.get(t)?)?;
        let held = closed(&trajectory.gripper_actions, t) && first_held(trajectory, obj, t.saturating_sub(HOLD_WINDOW), t + 1).is_some();
        (!held).then_some((t, m, deg))
    })
}

/// Whether `name` moved [`MOVED_M`] or turned [`TURNED_DEG`] over source demo `demo`'s `span`
/// before its gripper closed there (a segment that pushes or pulls it: its moving is the plan).
fn source_moved(sources: &SourceDataset, demo: usize, span: (usize, usize), name: &str) -> bool {
    let Some(source) = sources.demos.get(demo) else { return false };
    let Some(obj) = source.object_poses.get(name) else { return false };
    let Some(first) = obj.get(span.0) else { return false };
    let until = first_close(&source.gripper_actions, span.0 + 1..span.1).unwrap_or(span.1);
    obj.iter().take(until.min(obj.len())).skip(span.0).any(|p| moved(first, p).is_some())
}

/// How far the hand was, after each step of `subtask`'s transformed segment, from where the source
/// demo's hand was at the same point of its segment, carried into the new scene by the same
/// transform (m), by step of the attempt. The segment replays the source's targets, so a hand that
/// follows as the source's did stays within noise of it; one held back (a joint at its limit, a
/// collision) falls behind.
#[must_use]
pub fn tracking_errors(sources: &SourceDataset, attempt: &Attempt, subtask: usize) -> Vec<(usize, f64)> {
    let Some(plan) = attempt.plans.get(subtask) else { return Vec::new() };
    let Some(source) = sources.demos.get(plan.src_demo) else { return Vec::new() };
    let new_from_src = match (plan.world_from_obj_new, plan.world_from_obj_src) {
        (Some(new), Some(src)) => new * src.inverse(),
        _ => Pose::identity(),
    };
    let eef = &attempt.trajectory.eef_poses;
    plan.waypoints
        .iter()
        .enumerate()
        .filter(|(_, (_, kind))| *kind == WaypointKind::Transformed)
        .enumerate()
        .filter_map(|(j, (i, _))| {
            let t = plan.first_step + i;
            let there = new_from_src * source.eef_poses.get(plan.src_span.0 + j + 1)?;
            Some((t, (eef.get(t + 1)?.translation.vector - there.translation.vector).norm()))
        })
        .collect()
}

/// The longest stretch of at least [`LAG_STEPS`] steps of `subtask` with the hand more than
/// [`LAG_M`] from where the source's was ([`tracking_errors`]), as a cause.
fn lagged(sources: &SourceDataset, attempt: &Attempt, subtask: usize) -> Option<Cause> {
    let errors = tracking_errors(sources, attempt, subtask);
    let mut best: Option<(usize, usize, f64)> = None;
    let mut run: Option<(usize, f64)> = None;
    let end = errors.last().map_or(0, |(t, _)| t + 1);
    for (t, e) in errors.into_iter().chain([(end, 0.0)]) {
        if e > LAG_M {
            let (from, worst) = run.unwrap_or((t, 0.0));
            run = Some((from, worst.max(e)));
        } else if let Some((from, worst)) = run.take() {
            let len = t - from;
            if len >= LAG_STEPS && best.is_none_or(|(_, l, _)| len > l) {
                best = Some((from, len, worst));
            }
        }
    }
    best.map(|(step, _, error_m)| Cause::ArmLagged { step, error_m, joint: None })
}

/// The object's place in the hand at `t`.
fn in_hand(trajectory: &crate::generate::Trajectory, obj: &[Pose], t: usize) -> Option<Pose> {
    Some(trajectory.eef_poses.get(t)?.inverse() * obj.get(t)?)
}

/// The first step in `from..to` at which `obj` moved with the closed hand over the
/// [`HOLD_WINDOW`] steps before it.
fn first_held(trajectory: &crate::generate::Trajectory, obj: &[Pose], from: usize, to: usize) -> Option<usize> {
    let gripper = &trajectory.gripper_actions;
    (from.max(HOLD_WINDOW)..to).find(|&t| {
        let before = t - HOLD_WINDOW;
        let (Some(eef_then), Some(eef_now)) = (trajectory.eef_poses.get(before), trajectory.eef_poses.get(t)) else {
            return false;
        };
        let travel = (eef_now.translation.vector - eef_then.translation.vector).norm();
        let (Some(then), Some(now)) = (in_hand(trajectory, obj, before), in_hand(trajectory, obj, t)) else {
            return false;
        };
        closed(gripper, before) && closed(gripper, t) && travel >= HOLD_MIN_TRAVEL_M && apart(&then, &now).0 < HOLD_TOL_M
    })
}

/// `(held from, lost at)` when `obj`, seen moving with the closed hand from some step in
/// `from..to`, is more than [`SLIP_M`] from that place in the hand at a step of `start..to` with
/// the gripper still closed.
fn slipped(trajectory: &crate::generate::Trajectory, obj: &[Pose], from: usize, to: usize, start: usize) -> Option<(usize, usize)> {
    let held = first_held(trajectory, obj, from, to)?;
    let place = in_hand(trajectory, obj, held)?;
    let lost = (held.max(start)..to)
        .take_while(|&t| closed(&trajectory.gripper_actions, t))
        .find(|&t| in_hand(trajectory, obj, t).is_some_and(|p| apart(&place, &p).0 > SLIP_M))?;
    Some((held, lost))
}
