//! Planned transit between segments (SkillGen, Garrett et al. 2024): instead of interpolating
//! straight to the next segment's first pose, the robot gets there by a collision-free path.
//!
//! The planner is RRT-Connect (Kuffner and LaValle 2000) in joint space, then random
//! shortcutting, then a time parameterisation to the controller's rate: the path is handed back as
//! end-effector poses, one per control step, which the generator executes as delta-pose actions
//! like every other step. The engine knows no simulator: a [`TransitSpace`] answers "is this
//! configuration free?", forward and inverse kinematics. `mimicgen-sim` implements it over
//! MuJoCo's collision detection (held objects carried along); [`crate::kinematic`] implements it
//! for a free-flying gripper among spheres, for tests.
//!
//! Every random number comes from the caller's generator (the attempt's stream), and the budget is
//! a number of samples, not a time: the same seed gives the same path on any machine and with any
//! number of workers.
#![allow(
    clippy::indexing_slicing,
    reason = "indices are the planner's own: a tree's node and parent indices are ones it handed out (every node is pushed \
              with its parent), shortcut and time_parameterise index paths of at least two configurations (the start and \
              the goal, kept by shortcutting), and `cumulative` has one entry per configuration"
)]

use std::time::Instant;

use rand::Rng;
use serde::{Deserialize, Serialize};

use crate::pose::Pose;

/// A robot's configuration space as the planner sees it.
pub trait TransitSpace {
    /// `[lower, upper]` of every planned joint.
    fn joint_limits(&self) -> Vec<[f64; 2]>;

    /// The joint positions the robot is at now (where the path starts).
    fn joints(&self) -> Vec<f64>;

    /// Whether configuration `q` touches nothing it must not: the robot and anything it holds
    /// against the rest of the scene. Contacts present where the path starts are allowed.
    fn is_free(&mut self, q: &[f64]) -> bool;

    /// `world_from_eef` at configuration `q`.
    fn eef_pose_at(&mut self, q: &[f64]) -> Pose;

    /// A configuration whose end effector is at `world_from_eef`, searched from `seed`; `None`
    /// when the search does not converge.
    fn inverse_kinematics(&mut self, world_from_eef: &Pose, seed: &[f64]) -> Option<Vec<f64>>;

    /// The configuration the robot's controller would hold with its end effector where it is at
    /// `q` (a redundant arm tracking poses settles its elbow where its posture term pulls it);
    /// `None` when there is none. The planner grows its trees through such configurations only,
    /// so that the arm follows the planned path when it is executed as poses. The default keeps
    /// `q` (a robot without redundancy).
    fn settle(&mut self, q: &[f64]) -> Option<Vec<f64>> {
        Some(q.to_vec())
    }
}

/// How the planner searches and how fast the planned path is executed.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PlannerSettings {
    /// Random configurations drawn before giving up (the budget; a count, so that plans do not
    /// depend on the machine's speed).
    pub max_samples: usize,
    /// Longest step (rad, Euclidean in joint space) a tree grows by.
    pub extend_rad: f64,
    /// Collision-check resolution along an edge (rad, largest joint change between checks).
    pub check_rad: f64,
    /// Random shortcut tries on the found path.
    pub shortcut_tries: usize,
    /// Inverse-kinematics starts tried for the goal (the robot's joints, then random ones).
    pub ik_tries: usize,
    /// Largest end-effector travel per control step (m) at cruising speed.
    pub max_step_m: f64,
    /// Largest end-effector turn per control step (rad).
    pub max_step_turn_rad: f64,
    /// Largest joint change per control step (rad).
    pub max_step_joint_rad: f64,
    /// Control steps the goal is held at the path's end, for the arm to catch up with it.
    pub hold_steps: usize,
}

impl Default for PlannerSettings {
    fn default() -> Self {
        Self {
            max_samples: 2000,
            extend_rad: 0.3,
            check_rad: 0.03,
            shortcut_tries: 60,
            ik_tries: 12,
            max_step_m: 0.015,
            max_step_turn_rad: 0.08,
            max_step_joint_rad: 0.05,
            hold_steps: 2,
        }
    }
}

/// A planned transit.
#[derive(Debug, Clone, PartialEq)]
pub struct TransitPath {
    /// One configuration per control step, the goal's last.
    pub joints: Vec<Vec<f64>>,
    /// `world_from_eef` of each, the goal pose itself last.
    pub poses: Vec<Pose>,
    /// What finding it cost.
    pub stats: TransitStats,
}

/// What planning one transit cost.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct TransitStats {
    /// Random configurations drawn (0 when the straight path was free).
    pub samples: usize,
    /// Configurations checked for collision.
    pub checks: usize,
    /// Wall time (s): for reports only, never for decisions.
    pub seconds: f64,
}

/// Why no transit was planned.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TransitError {
    /// No collision-free configuration reaches the goal pose.
    #[error("the goal pose has no collision-free inverse-kinematics solution ({tries} starts tried)")]
    GoalUnreachable {
        /// Inverse-kinematics starts tried.
        tries: usize,
        /// What it cost.
        stats: TransitStats,
    },
    /// The trees did not meet within the sample budget.
    #[error("the search drew {} samples without connecting start and goal", .stats.samples)]
    NoPath {
        /// What it cost.
        stats: TransitStats,
    },
}

impl TransitError {
    /// What the failed search cost.
    #[must_use]
    pub fn stats(&self) -> TransitStats {
        match self {
            Self::GoalUnreachable { stats, .. } | Self::NoPath { stats } => *stats,
        }
    }
}

/// Counts collision checks.
struct Checker<'a, S: TransitSpace + ?Sized> {
    space: &'a mut S,
    checks: usize,
    check_rad: f64,
}

impl<S: TransitSpace + ?Sized> Checker<'_, S> {
    fn free(&mut self, q: &[f64]) -> bool {
        self.checks += 1;
        self.space.is_free(q)
    }

    /// Whether the straight joint-space edge `a -> b` is free (`a` assumed checked).
    fn edge_free(&mut self, a: &[f64], b: &[f64]) -> bool {
        let n = steps_between(a, b, self.check_rad);
        (1..=n).all(|k| {
            #[allow(clippy::cast_precision_loss)] // step counts are far below 2^52
            let q = lerp(a, b, k as f64 / n as f64);
            self.free(&q)
        })
    }
}

/// Plans a collision-free path from the robot's joints to a configuration at `world_from_goal`.
///
/// # Errors
/// [`TransitError`] when the goal has no free configuration or the budget runs out.
pub fn plan_transit<S: TransitSpace + ?Sized, R: Rng + ?Sized>(
    space: &mut S,
    world_from_goal: &Pose,
    settings: &PlannerSettings,
    rng: &mut R,
) -> Result<TransitPath, TransitError> {
    let started = Instant::now();
    let limits = space.joint_limits();
    let start = space.joints();
    let mut checker = Checker { space, checks: 0, check_rad: settings.check_rad.max(1e-4) };
    let stats = |checker: &Checker<S>, samples| TransitStats { samples, checks: checker.checks, seconds: started.elapsed().as_secs_f64() };

    let mut goal = None;
    for attempt in 0..settings.ik_tries.max(1) {
        let seed = if attempt == 0 { start.clone() } else { sample(&limits, rng) };
        if let Some(q) = checker.space.inverse_kinematics(world_from_goal, &seed)
            && within(&q, &limits)
            && checker.free(&q)
        {
            goal = Some(q);
            break;
        }
    }
    let Some(goal) = goal else {
        return Err(TransitError::GoalUnreachable { tries: settings.ik_tries.max(1), stats: stats(&checker, 0) });
    };

    let (path, samples) = if checker.edge_free(&start, &goal) {
        (vec![start, goal], 0)
    } else {
        match rrt_connect(&mut checker, &limits, &start, goal, settings, rng) {
            Ok(found) => found,
            Err(samples) => return Err(TransitError::NoPath { stats: stats(&checker, samples) }),
        }
    };
    let path = shortcut(&mut checker, path, settings.shortcut_tries, rng);
    let joints = time_parameterise(checker.space, &path, settings);
    let mut poses: Vec<Pose> = joints.iter().map(|q| checker.space.eef_pose_at(q)).collect();
    if let Some(last) = poses.last_mut() {
        *last = *world_from_goal;
    }
    Ok(TransitPath { joints, poses, stats: stats(&checker, samples) })
}

/// A tree of configurations, each with its parent's index (the root's is its own).
struct Tree {
    nodes: Vec<Vec<f64>>,
    parents: Vec<usize>,
}

impl Tree {
    fn new(root: Vec<f64>) -> Self {
        Self { nodes: vec![root], parents: vec![0] }
    }

    fn nearest(&self, q: &[f64]) -> usize {
        let mut best = (0, f64::INFINITY);
        for (i, node) in self.nodes.iter().enumerate() {
            let d = distance(node, q);
            if d < best.1 {
                best = (i, d);
            }
        }
        best.0
    }

    /// The configurations from the root to node `i`.
    fn path_to(&self, mut i: usize) -> Vec<Vec<f64>> {
        let mut path = vec![self.nodes[i].clone()];
        while self.parents[i] != i {
            i = self.parents[i];
            path.push(self.nodes[i].clone());
        }
        path.reverse();
        path
    }
}

enum Extend {
    Trapped,
    Advanced(usize),
    Reached(usize),
}

/// Grows `tree` one step (at most `step` rad) from its node nearest `target` towards it.
fn extend<S: TransitSpace + ?Sized>(checker: &mut Checker<S>, tree: &mut Tree, target: &[f64], step: f64) -> Extend {
    let near = tree.nearest(target);
    let from = tree.nodes[near].clone();
    let d = distance(&from, target);
    let (to, reached) = if d <= step { (target.to_vec(), true) } else { (lerp(&from, target, step / d), false) };
    if !checker.edge_free(&from, &to) {
        return Extend::Trapped;
    }
    tree.nodes.push(to);
    tree.parents.push(near);
    let new = tree.nodes.len() - 1;
    if reached { Extend::Reached(new) } else { Extend::Advanced(new) }
}

/// RRT-Connect: two trees, from the start and from the goal, each grown towards random samples and
/// then greedily towards the other's newest node. `Err(samples)` when the budget runs out.
fn rrt_connect<S: TransitSpace + ?Sized, R: Rng + ?Sized>(
    checker: &mut Checker<S>,
    limits: &[[f64; 2]],
    start: &[f64],
    goal: Vec<f64>,
    settings: &PlannerSettings,
    rng: &mut R,
) -> Result<(Vec<Vec<f64>>, usize), usize> {
    let mut trees = [Tree::new(start.to_vec()), Tree::new(goal)];
    let step = settings.extend_rad.max(1e-3);
    for samples in 1..=settings.max_samples {
        let Some(target) = checker.space.settle(&sample(limits, rng)) else { continue };
        let [a, b] = &mut trees;
        let new = match extend(checker, a, &target, step) {
            Extend::Trapped => {
                trees.swap(0, 1);
                continue;
            }
            Extend::Advanced(i) | Extend::Reached(i) => i,
        };
        let q_new = a.nodes[new].clone();
        loop {
            match extend(checker, b, &q_new, step) {
                Extend::Advanced(_) => {}
                Extend::Trapped => break,
                Extend::Reached(j) => {
                    let mut from_a = a.path_to(new);
                    let mut from_b = b.path_to(j);
                    from_b.pop();
                    from_b.reverse();
                    from_a.extend(from_b);
                    // `a` is the start's tree or the goal's, as the swaps left it.
                    if from_a.first().map(Vec::as_slice) != Some(start) {
                        from_a.reverse();
                    }
                    return Ok((from_a, samples));
                }
            }
        }
        trees.swap(0, 1);
    }
    Err(settings.max_samples)
}

/// Random shortcutting: joins two random nodes of the path directly when the edge is free.
fn shortcut<S: TransitSpace + ?Sized, R: Rng + ?Sized>(
    checker: &mut Checker<S>,
    mut path: Vec<Vec<f64>>,
    tries: usize,
    rng: &mut R,
) -> Vec<Vec<f64>> {
    for _ in 0..tries {
        if path.len() < 3 {
            break;
        }
        let i = rng.random_range(0..path.len() - 2);
        let j = rng.random_range(i + 2..path.len());
        if checker.edge_free(&path[i], &path[j]) {
            path.drain(i + 1..j);
        }
    }
    path
}

/// One configuration per control step along `path`: each edge is given the steps its largest
/// joint change, end-effector travel and turn need at the settings' speeds, and the whole path
/// is traversed with a smooth start and stop (smoothstep timing, peak speed 1.5 x the mean).
fn time_parameterise<S: TransitSpace + ?Sized>(space: &mut S, path: &[Vec<f64>], settings: &PlannerSettings) -> Vec<Vec<f64>> {
    let poses: Vec<Pose> = path.iter().map(|q| space.eef_pose_at(q)).collect();
    let mut cumulative = vec![0.0];
    for (k, pair) in path.windows(2).enumerate() {
        let joint = pair[0].iter().zip(&pair[1]).map(|(a, b)| (b - a).abs()).fold(0.0, f64::max);
        let travel = (poses[k + 1].translation.vector - poses[k].translation.vector).norm();
        let turn = poses[k].rotation.angle_to(&poses[k + 1].rotation);
        let cost = (joint / settings.max_step_joint_rad.max(1e-6))
            .max(travel / settings.max_step_m.max(1e-6))
            .max(turn / settings.max_step_turn_rad.max(1e-6));
        cumulative.push(cumulative[cumulative.len() - 1] + cost);
    }
    let total = cumulative[cumulative.len() - 1];
    #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)] // a small positive count
    let steps = (1.5 * total).ceil().max(1.0) as usize;
    (1..=steps)
        .map(|k| {
            #[allow(clippy::cast_precision_loss)] // step counts are far below 2^52
            let t = k as f64 / steps as f64;
            let s = total * t * t * (3.0 - 2.0 * t);
            let edge = cumulative.partition_point(|&c| c < s).clamp(1, path.len() - 1);
            let (c0, c1) = (cumulative[edge - 1], cumulative[edge]);
            let u = if c1 > c0 { ((s - c0) / (c1 - c0)).clamp(0.0, 1.0) } else { 1.0 };
            lerp(&path[edge - 1], &path[edge], u)
        })
        .collect()
}

fn sample<R: Rng + ?Sized>(limits: &[[f64; 2]], rng: &mut R) -> Vec<f64> {
    limits.iter().map(|&[lo, hi]| if hi > lo { rng.random_range(lo..hi) } else { lo }).collect()
}

fn within(q: &[f64], limits: &[[f64; 2]]) -> bool {
    q.len() == limits.len() && q.iter().zip(limits).all(|(v, [lo, hi])| v.is_finite() && *v >= lo - 1e-9 && *v <= hi + 1e-9)
}

fn distance(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum::<f64>().sqrt()
}

fn lerp(a: &[f64], b: &[f64], s: f64) -> Vec<f64> {
    a.iter().zip(b).map(|(x, y)| x + (y - x) * s).collect()
}

/// Checks needed along `a -> b` so that no joint moves more than `resolution` between two.
fn steps_between(a: &[f64], b: &[f64], resolution: f64) -> usize {
    let largest = a.iter().zip(b).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max);
    #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)] // a small positive count
    let n = (largest / resolution).ceil() as usize;
    n.max(1)
}

#[cfg(test)]
mod tests {
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    use super::*;
    use crate::pose::{Rot, Vec3, pose_from_parts};

    /// A point in the unit-ish box `[-1, 1]^2` with a wall at x = 0 from y = -1 to `gap_y`.
    struct Wall {
        at: Vec<f64>,
        gap_y: f64,
    }

    impl TransitSpace for Wall {
        fn joint_limits(&self) -> Vec<[f64; 2]> {
            vec![[-1.0, 1.0]; 2]
        }
        fn joints(&self) -> Vec<f64> {
            self.at.clone()
        }
        fn is_free(&mut self, q: &[f64]) -> bool {
            !(q[0].abs() < 0.05 && q[1] < self.gap_y)
        }
        fn eef_pose_at(&mut self, q: &[f64]) -> Pose {
            pose_from_parts(Vec3::new(q[0], q[1], 0.0), Rot::identity())
        }
        fn inverse_kinematics(&mut self, world_from_eef: &Pose, _seed: &[f64]) -> Option<Vec<f64>> {
            let t = world_from_eef.translation.vector;
            Some(vec![t.x, t.y])
        }
    }

    fn goal(x: f64, y: f64) -> Pose {
        pose_from_parts(Vec3::new(x, y, 0.0), Rot::identity())
    }

    fn every_step_free(space: &mut Wall, path: &TransitPath) -> bool {
        let mut prev = space.joints();
        path.joints.iter().all(|q| {
            let n = steps_between(&prev, q, 0.005);
            #[allow(clippy::cast_precision_loss)]
            let ok = (0..=n).all(|k| space.is_free(&lerp(&prev, q, k as f64 / n as f64)));
            prev.clone_from(q);
            ok
        })
    }

    #[test]
    fn a_free_straight_line_is_taken_without_sampling() {
        let mut space = Wall { at: vec![-0.5, 0.9], gap_y: 0.5 };
        let path = plan_transit(&mut space, &goal(0.5, 0.9), &PlannerSettings::default(), &mut ChaCha8Rng::seed_from_u64(1)).unwrap();
        assert_eq!(path.stats.samples, 0);
        assert!(path.joints.iter().all(|q| (q[1] - 0.9).abs() < 1e-9), "{:?}", path.joints);
        assert_eq!(path.poses.last(), Some(&goal(0.5, 0.9)));
    }

    #[test]
    fn the_path_goes_round_the_wall_and_every_step_is_free_and_bounded() {
        let mut space = Wall { at: vec![-0.5, -0.8], gap_y: 0.6 };
        let settings = PlannerSettings::default();
        let path = plan_transit(&mut space, &goal(0.5, -0.8), &settings, &mut ChaCha8Rng::seed_from_u64(3)).unwrap();
        assert!(path.stats.samples > 0);
        assert!(path.joints.iter().any(|q| q[1] >= 0.6), "never went through the gap: {:?}", path.joints);
        assert!(every_step_free(&mut space, &path));
        let mut prev = space.joints();
        for q in &path.joints {
            let step = q.iter().zip(&prev).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
            assert!(step <= 1.5 * settings.max_step_joint_rad + 1e-9, "step of {step} rad");
            prev.clone_from(q);
        }
        assert!((path.joints.last().unwrap()[0] - 0.5).abs() < 1e-9);
    }

    #[test]
    fn the_same_seed_gives_the_same_path_and_another_seed_another() {
        let plan = |seed| {
            let mut space = Wall { at: vec![-0.5, -0.8], gap_y: 0.6 };
            plan_transit(&mut space, &goal(0.5, -0.8), &PlannerSettings::default(), &mut ChaCha8Rng::seed_from_u64(seed)).unwrap().joints
        };
        assert_eq!(plan(7), plan(7));
        assert_ne!(plan(7), plan(8));
    }

    #[test]
    fn a_closed_wall_exhausts_the_budget_and_a_goal_inside_it_is_unreachable() {
        let settings = PlannerSettings { max_samples: 200, ..PlannerSettings::default() };
        let mut space = Wall { at: vec![-0.5, -0.8], gap_y: 2.0 };
        let err = plan_transit(&mut space, &goal(0.5, -0.8), &settings, &mut ChaCha8Rng::seed_from_u64(1)).unwrap_err();
        assert!(matches!(err, TransitError::NoPath { stats } if stats.samples == 200 && stats.checks > 200), "{err:?}");
        let err = plan_transit(&mut space, &goal(0.0, 0.0), &settings, &mut ChaCha8Rng::seed_from_u64(1)).unwrap_err();
        assert!(matches!(err, TransitError::GoalUnreachable { .. }), "{err:?}");
        assert!(err.to_string().contains("inverse-kinematics"), "{err}");
    }
}
