//! A robot on a mobile base (the paper's Mobile Kitchen; its appendix "Data Generation for Mobile
//! Manipulation Tasks"): the base's part of an action, how a source segment splits into arm and
//! base runs, how those runs are generated, and the scripted operator's drive.
//!
//! The action of a robot on a base is `[arm pose (6), gripper, base (3)]`. The base's three are
//! its forward, sideways and turning speeds in its own frame, each in `[-1, 1]` of its top speed
//! (robosuite's mobile bases take the same three). The arm's pose part is in the base's frame, so
//! an arm sent no motion rides along with the base.
//!
//! Generation follows the paper. The base and the arm do not move at once, so a segment whose
//! source drove the base splits into runs: arm, drive, arm (and a segment's end offset may cut a
//! drive in two, leaving its rest to the next segment). A drive's base actions are copied from the
//! source, not transformed, while the arm holds still on the base. An arm run is transformed with
//! the subtask's object as any segment is, behind an interpolation from where a drive left the
//! hand; but an arm run that leaves for a drive after which the arm works again in the same
//! segment (lifting the carrot out of the sink before the drive to the pan, backing away from the
//! stove before the drive to the sink) is replayed relative to the hand. That is a deliberate
//! difference from the paper, which transforms it with the subtask's object as well: the object
//! is across the room then (the sink's carrot while the hand is at the stove), and its turn at
//! reset would swing the hand by its distance times the angle (40 cm for the carrot's 30 degrees
//! at 0.8 m).
//!
//! The transform itself needs nothing of the base: `world_from_obj_new * world_from_obj_src^-1 *
//! world_from_eef_src` is the same in the world's frame as in the base's when every pose of a
//! scene is taken in one frame. What the base changes is reach: after a copied drive the base
//! stands where the source's stood relative to the kitchen, not to the object.

use crate::action::POSE_ACTION_DIM;
use crate::demo::SourceDemo;
use crate::env::Environment;
pub use crate::env::MobileBase;
use crate::pose::{Pose, Vec3, pose_from_parts, yaw_of};
use crate::transform::{Waypoint, WaypointKind, interpolate_poses, subtask_waypoints};

/// The base's share of an action: forward, sideways, turn.
pub const BASE_ACTION_DIM: usize = 3;

/// Waypoints to execute, each with its kind.
pub type Waypoints = Vec<(Waypoint, WaypointKind)>;

/// A base command smaller than this in every part is no motion.
const STILL: f64 = 1e-9;

/// How many base values each of `demo`'s actions ends with: [`BASE_ACTION_DIM`] when its actions
/// are exactly the pose, the gripper and a base's three; else 0 (an arm fixed in the world, one
/// arm's view of a two-arm demo whose actions hold both arms', a demo whose actions were not kept).
#[must_use]
pub fn base_dim(demo: &SourceDemo) -> usize {
    let actions = &demo.sim.actions;
    let with_base = POSE_ACTION_DIM + demo.gripper_actions.width() + BASE_ACTION_DIM;
    if actions.len() == demo.len() && actions.width() == with_base { BASE_ACTION_DIM } else { 0 }
}

/// The base part of `demo`'s action `t` (empty without a base).
#[must_use]
pub fn base_command(demo: &SourceDemo, t: usize) -> &[f64] {
    let from = POSE_ACTION_DIM + demo.gripper_actions.width();
    match base_dim(demo) {
        0 => &[],
        _ => demo.sim.actions.get(t).and_then(|row| row.get(from..)).unwrap_or_default(),
    }
}

/// Whether a base command moves the base.
#[must_use]
pub fn moves(command: &[f64]) -> bool {
    command.iter().any(|v| v.abs() > STILL)
}

/// A stretch of a source segment: steps `start..end`, in which the base moves (`base`) or the arm
/// does.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Run {
    /// First step.
    pub start: usize,
    /// One past the last step.
    pub end: usize,
    /// Whether the base moves in it (else the arm does).
    pub base: bool,
}

/// Steps `start..end` of `demo` cut into maximal runs in which the base moves or stands.
#[must_use]
pub fn runs(demo: &SourceDemo, start: usize, end: usize) -> Vec<Run> {
    let mut out: Vec<Run> = Vec::new();
    for t in start..end {
        let base = moves(base_command(demo, t));
        match out.last_mut() {
            Some(run) if run.base == base => run.end = t + 1,
            _ => out.push(Run { start: t, end: t + 1, base }),
        }
    }
    out
}

/// How a segment whose source drove the base is generated (see the module's notes): the
/// planned pose of each source step, and the waypoints to execute. `None` when the base stood
/// still through `start..end`.
///
/// `last` is where the hand's target is when the segment starts; `object` the subtask's object,
/// `(world_from_obj_new, world_from_obj_src)`. The drive's poses are planned as if the base moves
/// as the source's did from where the source's stood; [`hold_on_base`] corrects them as they run.
#[allow(clippy::too_many_arguments, reason = "the same settings as subtask_waypoints, and the split's own inputs")]
#[must_use]
pub fn plan_segment(
    demo: &SourceDemo,
    (start, end): (usize, usize),
    last: &Pose,
    object: Option<(&Pose, &Pose)>,
    num_interp: usize,
    num_fixed: usize,
    noise: f64,
    interp_noise: f64,
) -> Option<(Vec<Pose>, Waypoints)> {
    let runs = runs(demo, start, end);
    if !runs.iter().any(|r| r.base) {
        return None;
    }
    let source = |t: usize| demo.target_poses.get(t).copied().unwrap_or(*last);
    let gripper = |t: usize| demo.gripper_actions.get(t).map(<[f64]>::to_vec).unwrap_or_default();
    // The source's target just before a run stands for where the hand is when it starts.
    let before = |t: usize| if t > 0 { source(t - 1) } else { demo.eef_poses.get(t).copied().unwrap_or(*last) };
    let by_object = object.map_or_else(Pose::identity, |(new, src)| new * src.inverse());
    let (mut planned, mut waypoints) = (Vec::with_capacity(end - start), Vec::with_capacity(end - start + num_interp + num_fixed));
    let mut hand = *last;
    for (k, run) in runs.iter().enumerate() {
        // An arm run that leaves for a drive after which the arm works again (backing away from
        // the stove before driving to the sink) is the hand's; any other is the object's.
        let later = runs.get(k + 1..).unwrap_or_default();
        let leaving = later.iter().position(|r| r.base).is_some_and(|b| later.iter().skip(b).any(|r| !r.base));
        if run.base {
            // The hand rides with the base: the source's target moved as its base did.
            let (anchor, from) = (before(run.start), hand);
            for t in run.start..run.end {
                let pose = source(t) * anchor.inverse() * from;
                let waypoint = Waypoint { pose, gripper: gripper(t), noise, base: base_command(demo, t).to_vec() };
                planned.push(pose);
                waypoints.push((waypoint, WaypointKind::Base));
                hand = pose;
            }
        } else if leaving {
            let by_hand = hand * before(run.start).inverse();
            for t in run.start..run.end {
                let pose = by_hand * source(t);
                planned.push(pose);
                waypoints.push((Waypoint { pose, gripper: gripper(t), noise, base: Vec::new() }, WaypointKind::Transformed));
                hand = pose;
            }
        } else {
            let poses: Vec<Pose> = (run.start..run.end).map(|t| by_object * source(t)).collect();
            let grippers: Vec<Vec<f64>> = (run.start..run.end).map(gripper).collect();
            waypoints.extend(subtask_waypoints(&hand, &poses, &grippers, num_interp, num_fixed, noise, interp_noise));
            hand = poses.last().copied().unwrap_or(hand);
            planned.extend(poses);
        }
    }
    Some((planned, waypoints))
}

/// Before executing waypoint `i` of a segment on a mobile base, puts the waypoint where the base
/// now is: a drive's waypoint holds the hand where it was on the base when the drive began
/// (`held`, `base_from_target`), and the interpolation after a drive starts from where the drive
/// left the hand. `last` is the target commanded last (a waypoint's pose, not the target an
/// action clipped to its limit reached: a hand lifting fast is held where it was sent). Does
/// nothing without a base.
pub fn hold_on_base<E: Environment + ?Sized>(
    env: &E,
    waypoints: &mut [(Waypoint, WaypointKind)],
    i: usize,
    held: &mut Option<Pose>,
    last: Option<Pose>,
) {
    let Some(base) = env.mobile_base() else { return };
    let last = last.unwrap_or_else(|| env.eef_pose());
    let kind = waypoints.get(i).map(|(_, k)| *k);
    let after_drive = held.is_some();
    match kind {
        Some(WaypointKind::Base) => {
            let base_from_target = *held.get_or_insert_with(|| base.world_from_base.inverse() * last);
            if let Some((waypoint, _)) = waypoints.get_mut(i) {
                waypoint.pose = base.world_from_base * base_from_target;
            }
        }
        Some(WaypointKind::Interpolation) if after_drive => {
            *held = None;
            let end = waypoints.iter().skip(i).position(|(_, k)| *k != WaypointKind::Interpolation).map_or(waypoints.len(), |n| i + n);
            let Some(goal) = waypoints.get(end - 1).map(|(w, _)| w.pose) else { return };
            let poses = interpolate_poses(&last, &goal, (end - i).saturating_sub(1));
            for ((waypoint, _), pose) in waypoints.iter_mut().take(end).skip(i).zip(poses.into_iter().skip(1)) {
                waypoint.pose = pose;
            }
        }
        _ => *held = None,
    }
}

/// The base command (each part in `[-1, 1]`) that drives `base` towards `goal` (`[x, y, yaw]` in
/// the world, m and rad) at up to `speed` of its top speed, slowing over the last stretch; zero
/// once there.
#[must_use]
pub fn drive_command(base: &MobileBase, goal: [f64; 3], speed: f64) -> [f64; BASE_ACTION_DIM] {
    let here = base.world_from_base;
    let world_error = Vec3::new(goal[0] - here.translation.x, goal[1] - here.translation.y, 0.0);
    let error = here.rotation.inverse() * world_error;
    let turn = wrap_angle(goal[2] - yaw_of(&here));
    // A proportional approach: a tenth of the way per step, capped.
    let gain = 0.25;
    let clamp = |v: f64| v.clamp(-speed, speed);
    [clamp(gain * error.x / base.max_step_m), clamp(gain * error.y / base.max_step_m), clamp(gain * turn / base.max_turn_rad)]
}

/// Whether `base` stands at `goal` (`[x, y, yaw]`) within `tolerance_m` and `tolerance_rad`.
#[must_use]
pub fn at_goal(base: &MobileBase, goal: [f64; 3], tolerance_m: f64, tolerance_rad: f64) -> bool {
    let here = base.world_from_base;
    let off = Vec3::new(goal[0] - here.translation.x, goal[1] - here.translation.y, 0.0).norm();
    off < tolerance_m && wrap_angle(goal[2] - yaw_of(&here)).abs() < tolerance_rad
}

/// An angle in `[-pi, pi)`.
fn wrap_angle(a: f64) -> f64 {
    (a + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI
}

/// `world_from_base` of a base standing at `[x, y, yaw]` with its frame `height_m` up.
#[must_use]
pub fn base_pose(at: [f64; 3], height_m: f64) -> Pose {
    pose_from_parts(Vec3::new(at[0], at[1], height_m), crate::pose::Rot::from_axis_angle(&Vec3::z_axis(), at[2]))
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::indexing_slicing)]
mod tests {
    use super::*;
    use crate::demo::{Rows, SimPayload};
    use crate::pose::Rot;

    fn at(x: f64, y: f64) -> Pose {
        pose_from_parts(Vec3::new(x, y, 1.0), Rot::identity())
    }

    /// A source demo of 30 steps: the arm moves +x for 10, the base drives +y 1 cm a step for
    /// 10 (the hand riding along), the arm moves -z for 10.
    fn demo() -> SourceDemo {
        let mut targets = Vec::new();
        let mut actions = Vec::new();
        for t in 0..30_u32 {
            let t = f64::from(t);
            let (x, y, z) = if t < 10.0 {
                (0.01 * t, 0.0, 1.0)
            } else if t < 20.0 {
                (0.1, 0.01 * (t - 9.0), 1.0)
            } else {
                (0.1, 0.1, 1.0 - 0.01 * (t - 19.0))
            };
            targets.push(pose_from_parts(Vec3::new(x, y, z), Rot::identity()));
            let base = if (10.0..20.0).contains(&t) { [0.0, 0.5, 0.0] } else { [0.0; 3] };
            actions.extend([0.0; 6]);
            actions.push(1.0);
            actions.extend(base);
        }
        SourceDemo {
            name: "demo_0".to_owned(),
            eef_poses: targets.clone(),
            target_poses: targets,
            gripper_actions: Rows::from_vec(1, vec![1.0; 30], "gripper").unwrap(),
            sim: SimPayload { actions: Rows::from_vec(10, actions, "actions").unwrap(), ..SimPayload::default() },
            ..SourceDemo::default()
        }
    }

    #[test]
    fn a_segment_splits_where_the_base_starts_and_stops() {
        let d = demo();
        assert_eq!(base_dim(&d), 3);
        assert_eq!(
            runs(&d, 0, 30),
            vec![Run { start: 0, end: 10, base: false }, Run { start: 10, end: 20, base: true }, Run { start: 20, end: 30, base: false }]
        );
        // A fixed arm's demo has no base: its actions are the pose and the gripper. Nor has one
        // arm's view of a two-arm demo, whose actions hold both arms' (14 wide, moving).
        for width in [7, 14] {
            let mut fixed = d.clone();
            fixed.sim.actions = Rows::from_vec(width, vec![0.5; width * 30], "actions").unwrap();
            assert_eq!(base_dim(&fixed), 0);
            assert_eq!(runs(&fixed, 0, 30).len(), 1);
            assert!(plan_segment(&fixed, (0, 30), &at(0.0, 0.0), None, 5, 0, 0.05, 0.0).is_none());
        }
    }

    #[test]
    fn the_drive_is_copied_the_run_before_follows_the_hand_and_the_run_after_the_object() {
        let d = demo();
        // The hand is 0.3 m further along x than the source's; the object moved 0.05 m in x.
        let last = at(0.3, 0.0);
        let (obj_new, obj_src) = (at(0.55, 0.1), at(0.5, 0.1));
        let (planned, waypoints) = plan_segment(&d, (1, 30), &last, Some((&obj_new, &obj_src)), 4, 0, 0.05, 0.0).unwrap();
        assert_eq!(planned.len(), 29);
        let kinds: Vec<WaypointKind> = waypoints.iter().map(|(_, k)| *k).collect();
        // 9 arm steps, 10 drive steps, 4 + 1 interpolation, then the other 9 after-drive steps.
        assert_eq!(kinds.iter().filter(|k| **k == WaypointKind::Base).count(), 10);
        assert_eq!(kinds.iter().filter(|k| **k == WaypointKind::Interpolation).count(), 5);
        assert_eq!(waypoints.len(), 9 + 10 + 5 + 9);
        // Before the drive: the source's motion from where the hand is (+0.01 x per step).
        assert!((waypoints[0].0.pose.translation.x - 0.31).abs() < 1e-12);
        assert!(waypoints[0].0.base.is_empty());
        // The drive: the source's base commands, the hand moving with the base.
        for (w, _) in waypoints.iter().filter(|(_, k)| *k == WaypointKind::Base) {
            assert_eq!(w.base, vec![0.0, 0.5, 0.0]);
        }
        let drive_end = waypoints.iter().rposition(|(_, k)| *k == WaypointKind::Base).unwrap();
        let hand = waypoints[drive_end].0.pose.translation.vector;
        assert!((hand - Vec3::new(0.4, 0.1, 1.0)).norm() < 1e-12, "{hand:?}");
        // After: with the object's move (x + 0.05), reached by interpolation from the hand.
        let last_pose = waypoints.last().unwrap().0.pose.translation.vector;
        assert!((last_pose - Vec3::new(0.15, 0.1, 0.9)).norm() < 1e-12, "{last_pose:?}");
        assert!(waypoints.iter().skip(drive_end + 1).all(|(w, _)| w.base.is_empty()));
    }

    #[test]
    fn a_segment_that_ends_in_a_drive_is_the_objects_up_to_it() {
        // The grasp, then the start of the drive the end offset cut into: the grasp is the
        // object's (moved 0.05 m in x), the drive copied.
        let d = demo();
        let (obj_new, obj_src) = (at(0.55, 0.1), at(0.5, 0.1));
        let (_, waypoints) = plan_segment(&d, (1, 15), &at(0.0, 0.0), Some((&obj_new, &obj_src)), 4, 0, 0.05, 0.0).unwrap();
        let first_arm = waypoints.iter().position(|(_, k)| *k == WaypointKind::Transformed).unwrap();
        assert_eq!(first_arm, 5, "reached by the interpolation");
        let x = |i: usize| waypoints[i].0.pose.translation.x;
        assert!((x(first_arm) - 0.07).abs() < 1e-12, "source x 0.02 + 0.05: {}", x(first_arm));
        assert_eq!(waypoints.iter().filter(|(_, k)| *k == WaypointKind::Base).count(), 5);
        assert!(waypoints.iter().rev().take(5).all(|(w, k)| *k == WaypointKind::Base && w.base == vec![0.0, 0.5, 0.0]));
    }

    #[test]
    fn a_drive_command_heads_for_the_goal_in_the_bases_frame_and_stops_there() {
        // The base faces +y: a goal 1 m along world +y is straight ahead.
        let base = MobileBase {
            world_from_base: base_pose([0.0, 0.0, std::f64::consts::FRAC_PI_2], 0.9),
            max_step_m: 0.0125,
            max_turn_rad: 0.025,
        };
        let command = drive_command(&base, [0.0, 1.0, std::f64::consts::FRAC_PI_2], 0.8);
        assert!((command[0] - 0.8).abs() < 1e-12 && command[1].abs() < 1e-9 && command[2].abs() < 1e-12, "{command:?}");
        assert!(!at_goal(&base, [0.0, 1.0, std::f64::consts::FRAC_PI_2], 0.005, 0.01));
        assert!(at_goal(&base, [0.001, 0.0, std::f64::consts::FRAC_PI_2 + 0.001], 0.005, 0.01));
        assert!(!at_goal(&base, [0.001, 0.0, std::f64::consts::FRAC_PI_2 + 0.02], 0.005, 0.01));
        let near = drive_command(&base, [0.0, 0.001, std::f64::consts::FRAC_PI_2], 0.8);
        assert!(near[0] > 0.0 && near[0] < 0.1, "slows near the goal: {near:?}");
        // A turn the short way round.
        // From +90 deg, -172 deg is 98 deg further counter-clockwise.
        let turn = drive_command(&base, [0.0, 0.0, -3.0], 1.0);
        assert!(turn[2] > 0.0, "{turn:?}");
    }
}
