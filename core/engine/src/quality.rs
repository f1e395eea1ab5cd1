//! What a user checks in a generated dataset before training on it, from its attempts: the pose
//! jump and the jerk at every stitch between pieces (where a subtask's bridge starts after the
//! previous subtask's segment, and where the transformed segment starts after the bridge), and
//! the pose actions against the controller's limits (OSC_POSE takes each of them in [-1, 1] and
//! clips beyond).

use serde::{Deserialize, Serialize};

use crate::action::POSE_ACTION_DIM;
use crate::generate::Attempt;
use crate::transform::WaypointKind;

/// Where in a subtask a stitch is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum StitchAt {
    /// The first step of the subtask's bridge (interpolation or planned transit), after the
    /// previous subtask's last step.
    InterpolationStart,
    /// The first step of the transformed segment, after the bridge.
    InterpolationEnd,
}

/// The stitches of one kind in one subtask over the attempts summarised.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StitchSummary {
    /// The subtask.
    pub subtask: usize,
    /// Which stitch.
    pub at: StitchAt,
    /// How many (one per attempt that reached it).
    pub count: usize,
    /// The commanded pose's jump across the stitch (waypoint to waypoint, as the transform and
    /// the bridge planned them, before the controller's limits), m: largest.
    pub jump_m_max: f64,
    /// 95th percentile of the jump, m.
    pub jump_m_p95: f64,
    /// The commanded orientation's jump across the stitch, degrees: largest.
    pub jump_deg_max: f64,
    /// 95th percentile of the orientation jump, degrees.
    pub jump_deg_p95: f64,
    /// The executed hand's jerk at the stitch (third difference of its position), m/s^3: largest.
    pub jerk_max: f64,
    /// 95th percentile of the jerk, m/s^3.
    pub jerk_p95: f64,
    /// For scale: the 95th percentile of the commanded pose's step-to-step change over every
    /// step of the subtask that is not a stitch, m.
    pub step_m_p95: f64,
}

/// The pose actions against the controller's limits.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ActionSummary {
    /// Steps counted.
    pub steps: usize,
    /// Steps with a pose action at its limit (|a| >= 1 in a dimension: clipped).
    pub saturated_steps: usize,
    /// Per pose dimension (x, y, z, rx, ry, rz): the largest |a|.
    pub max_abs: Vec<f64>,
    /// Per pose dimension: the 95th percentile of |a| (to 0.01).
    pub p95_abs: Vec<f64>,
}

/// One stitch's figures over the attempts: jumps (m), turns (deg), jerks (m/s^3).
#[derive(Debug, Clone, Default)]
struct Samples {
    jumps: Vec<f64>,
    turns: Vec<f64>,
    jerks: Vec<f64>,
}

/// Collects the figures of the attempts added; [`QualityStats::summary`] gives them.
#[derive(Debug, Clone, Default)]
pub struct QualityStats {
    attempts: usize,
    /// Per (subtask, stitch): what each attempt had there.
    stitches: std::collections::BTreeMap<(usize, StitchAt), Samples>,
    /// Per subtask: step-to-step changes off the stitches.
    steps: std::collections::BTreeMap<usize, Vec<f64>>,
    action_steps: usize,
    saturated: usize,
    max_abs: [f64; POSE_ACTION_DIM],
    /// Per pose dimension, |a| in 100 bins of 0.01 (the last holds 0.99 and above).
    histograms: Vec<[usize; 100]>,
}

/// The figures of the attempts added.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Quality {
    /// Attempts summarised.
    pub attempts: usize,
    /// Per subtask and stitch.
    pub stitches: Vec<StitchSummary>,
    /// The pose actions.
    pub actions: ActionSummary,
}

/// The `q`-quantile of `values` (nearest rank; 0 for none).
fn quantile(values: &[f64], q: f64) -> f64 {
    let mut sorted = values.to_vec();
    sorted.sort_by(f64::total_cmp);
    #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss, clippy::cast_precision_loss)] // an index into `sorted`
    let rank = ((q * sorted.len() as f64).ceil() as usize).saturating_sub(1);
    sorted.get(rank).copied().unwrap_or(0.0)
}

fn max(values: &[f64]) -> f64 {
    values.iter().copied().fold(0.0, f64::max)
}

impl QualityStats {
    /// Adds an attempt: its plans' waypoints (what the transform and the bridge commanded) for
    /// the jumps, its executed hand for the jerk, its actions; `dt` is the control period (s).
    pub fn add(&mut self, attempt: &Attempt, dt: f64) {
        self.attempts += 1;
        let t = &attempt.trajectory;
        // The third difference of the executed position around step `i`.
        let jerk = |i: usize| match (
            i.checked_sub(2).and_then(|k| t.eef_poses.get(k)),
            i.checked_sub(1).and_then(|k| t.eef_poses.get(k)),
            t.eef_poses.get(i),
            t.eef_poses.get(i + 1),
        ) {
            (Some(p0), Some(p1), Some(p2), Some(p3)) => {
                let d = p3.translation.vector - 3.0 * p2.translation.vector + 3.0 * p1.translation.vector - p0.translation.vector;
                d.norm() / dt.powi(3)
            }
            _ => 0.0,
        };
        let mut previous: Option<crate::pose::Pose> = None;
        for (subtask, plan) in attempt.plans.iter().enumerate() {
            let mut last = previous;
            for (j, (pose, kind)) in plan.waypoints.iter().enumerate() {
                let Some(before) = last else {
                    last = Some(*pose);
                    continue;
                };
                let jump_m = (pose.translation.vector - before.translation.vector).norm();
                let before_kind = j.checked_sub(1).and_then(|k| plan.waypoints.get(k)).map(|w| w.1);
                let at = match before_kind {
                    None => Some(StitchAt::InterpolationStart),
                    Some(b) if *kind == WaypointKind::Transformed && b != WaypointKind::Transformed => Some(StitchAt::InterpolationEnd),
                    Some(_) => None,
                };
                last = Some(*pose);
                let Some(at) = at else {
                    self.steps.entry(subtask).or_default().push(jump_m);
                    continue;
                };
                let entry = self.stitches.entry((subtask, at)).or_default();
                entry.jumps.push(jump_m);
                entry.turns.push(before.rotation.angle_to(&pose.rotation).to_degrees());
                entry.jerks.push(jerk(plan.first_step + j));
            }
            previous = last;
        }
        if self.histograms.is_empty() {
            self.histograms = vec![[0; 100]; POSE_ACTION_DIM];
        }
        for row in 0..t.actions.len() {
            let action = t.actions.row(row);
            let mut saturated = false;
            for (d, &a) in action.iter().take(POSE_ACTION_DIM).enumerate() {
                let a = a.abs();
                saturated |= a >= 1.0 - 1e-9;
                if let Some(m) = self.max_abs.get_mut(d) {
                    *m = m.max(a);
                }
                #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)] // a bin of [0, 1]
                let bin = ((a * 100.0).floor() as usize).min(99);
                if let Some(h) = self.histograms.get_mut(d).and_then(|h| h.get_mut(bin)) {
                    *h += 1;
                }
            }
            self.action_steps += 1;
            self.saturated += usize::from(saturated);
        }
    }

    /// The figures.
    #[must_use]
    pub fn summary(&self) -> Quality {
        let stitches = self
            .stitches
            .iter()
            .map(|(&(subtask, at), s)| StitchSummary {
                subtask,
                at,
                count: s.jumps.len(),
                jump_m_max: max(&s.jumps),
                jump_m_p95: quantile(&s.jumps, 0.95),
                jump_deg_max: max(&s.turns),
                jump_deg_p95: quantile(&s.turns, 0.95),
                jerk_max: max(&s.jerks),
                jerk_p95: quantile(&s.jerks, 0.95),
                step_m_p95: self.steps.get(&subtask).map_or(0.0, |s| quantile(s, 0.95)),
            })
            .collect();
        let p95 = |h: &[usize; 100]| {
            let total: usize = h.iter().sum();
            let mut seen = 0;
            for (bin, &count) in h.iter().enumerate() {
                seen += count;
                if total > 0 && 100 * seen >= 95 * total {
                    #[allow(clippy::cast_precision_loss)] // a bin index below 100
                    return (bin + 1) as f64 / 100.0;
                }
            }
            0.0
        };
        Quality {
            attempts: self.attempts,
            stitches,
            actions: ActionSummary {
                steps: self.action_steps,
                saturated_steps: self.saturated,
                max_abs: self.max_abs.to_vec(),
                p95_abs: self.histograms.iter().map(p95).collect(),
            },
        }
    }
}
