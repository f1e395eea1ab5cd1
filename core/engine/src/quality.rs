//! What a user checks in a generated dataset before training on it, from its attempts: the pose
//! jump and the jerk at every stitch between pieces (where a subtask's bridge starts after the
//! previous subtask's segment, and where the transformed segment starts after the bridge), and
//! the pose actions against the controller's limits (OSC_POSE takes each of them in [-1, 1] and
//! clips beyond).

use std::collections::BTreeMap;

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

/// One stitch in one attempt.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StitchFigure {
    /// The subtask.
    pub subtask: usize,
    /// Which stitch.
    pub at: StitchAt,
    /// The commanded pose's jump across it, m.
    pub jump_m: f64,
    /// The commanded orientation's jump across it, degrees.
    pub turn_deg: f64,
    /// The executed hand's jerk there, m/s^3.
    pub jerk: f64,
}

/// Counts per bin: `(bin, count)`, bins without a count left out.
pub type Bins = Vec<(u32, usize)>;

/// One attempt's figures, what [`QualityStats`] sums: small and serializable, so that a run's
/// attempt log carries them and a merged or resumed run sums them again to the same report.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct AttemptFigures {
    /// Its stitches.
    pub stitches: Vec<StitchFigure>,
    /// Per subtask: the commanded pose's step-to-step changes off the stitches, in bins of
    /// 0.1 mm.
    pub step_bins: Vec<(usize, Bins)>,
    /// Control steps.
    pub action_steps: usize,
    /// Steps with a pose action at its limit.
    pub saturated_steps: usize,
    /// Per pose dimension: the largest |a|.
    pub action_max_abs: Vec<f64>,
    /// Per pose dimension: |a| in bins of 0.01 (the last, 99, holds 0.99 and above).
    pub action_bins: Vec<Bins>,
}

/// Bins of the step-to-step changes per metre (0.1 mm wide).
pub const STEP_BINS_PER_M: f64 = 10_000.0;

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
    stitches: BTreeMap<(usize, StitchAt), Samples>,
    /// Per subtask: step-to-step changes off the stitches, counts per bin of 0.1 mm.
    steps: BTreeMap<usize, BTreeMap<u32, usize>>,
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

/// `value` to `decimals` places: short enough (15 significant digits at most for the figures'
/// sizes) that JSON gives back the same number, so that a merged or resumed run's report, summed
/// from the attempt log, equals the one summed as the attempts ran.
fn stored(value: f64, decimals: i32) -> f64 {
    let scale = 10f64.powi(decimals);
    (value * scale).round() / scale
}

/// The bin of `value` in bins `1 / per_unit` wide from 0 (the last bin, `last`, holds the rest).
fn bin(value: f64, per_unit: f64, last: u32) -> u32 {
    #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)] // clamped to [0, last]
    let bin = (value * per_unit).floor().clamp(0.0, f64::from(last)) as u32;
    bin
}

/// Adds `count` to `bin` of a sparse histogram.
fn count_into(bins: &mut BTreeMap<u32, usize>, bin: u32, count: usize) {
    *bins.entry(bin).or_default() += count;
}

impl AttemptFigures {
    /// The figures of `attempt`: its plans' waypoints (what the transform and the bridge
    /// commanded) for the jumps, its executed hand for the jerk, its actions; `dt` is the
    /// control period (s).
    #[must_use]
    pub fn of(attempt: &Attempt, dt: f64) -> Self {
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
        let mut stitches = Vec::new();
        let mut steps: BTreeMap<usize, BTreeMap<u32, usize>> = BTreeMap::new();
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
                match at {
                    Some(at) => stitches.push(StitchFigure {
                        subtask,
                        at,
                        jump_m: stored(jump_m, 9),
                        turn_deg: stored(before.rotation.angle_to(&pose.rotation).to_degrees(), 9),
                        jerk: stored(jerk(plan.first_step + j), 6),
                    }),
                    None => count_into(steps.entry(subtask).or_default(), bin(jump_m, STEP_BINS_PER_M, u32::MAX), 1),
                }
            }
            previous = last;
        }
        let mut max_abs = vec![0.0; POSE_ACTION_DIM];
        let mut histograms = vec![BTreeMap::new(); POSE_ACTION_DIM];
        let mut saturated_steps = 0;
        for row in 0..t.actions.len() {
            let action = t.actions.row(row);
            let mut saturated = false;
            for (d, &a) in action.iter().take(POSE_ACTION_DIM).enumerate() {
                let a = a.abs();
                saturated |= a >= 1.0 - 1e-9;
                if let Some(m) = max_abs.get_mut(d) {
                    *m = f64::max(*m, a);
                }
                if let Some(h) = histograms.get_mut(d) {
                    count_into(h, bin(a, 100.0, 99), 1);
                }
            }
            saturated_steps += usize::from(saturated);
        }
        let sparse = |h: BTreeMap<u32, usize>| h.into_iter().collect::<Bins>();
        Self {
            stitches,
            step_bins: steps.into_iter().map(|(subtask, h)| (subtask, sparse(h))).collect(),
            action_steps: t.actions.len(),
            saturated_steps,
            action_max_abs: max_abs.into_iter().map(|m| stored(m, 9)).collect(),
            action_bins: histograms.into_iter().map(sparse).collect(),
        }
    }
}

/// The upper edge of the bin where `q` of the counts lie at or below (0 for none); the bins are
/// `1 / per_unit` wide (divided, not multiplied, so that the edge is the short decimal it names).
fn binned_quantile<'a>(bins: impl Iterator<Item = (&'a u32, &'a usize)> + Clone, q: f64, per_unit: f64) -> f64 {
    let total: usize = bins.clone().map(|(_, c)| c).sum();
    let mut seen = 0;
    for (&bin, &count) in bins {
        seen += count;
        #[allow(clippy::cast_precision_loss)] // counts of steps
        if total > 0 && seen as f64 >= q * total as f64 - 1e-9 {
            return (f64::from(bin) + 1.0) / per_unit;
        }
    }
    0.0
}

impl QualityStats {
    /// Adds an attempt ([`AttemptFigures::of`]); `dt` is the control period (s).
    pub fn add(&mut self, attempt: &Attempt, dt: f64) {
        self.add_figures(&AttemptFigures::of(attempt, dt));
    }

    /// Adds an attempt's figures.
    pub fn add_figures(&mut self, figures: &AttemptFigures) {
        self.attempts += 1;
        for s in &figures.stitches {
            let entry = self.stitches.entry((s.subtask, s.at)).or_default();
            entry.jumps.push(s.jump_m);
            entry.turns.push(s.turn_deg);
            entry.jerks.push(s.jerk);
        }
        for (subtask, bins) in &figures.step_bins {
            let steps = self.steps.entry(*subtask).or_default();
            for &(bin, count) in bins {
                count_into(steps, bin, count);
            }
        }
        self.action_steps += figures.action_steps;
        self.saturated += figures.saturated_steps;
        for (m, &a) in self.max_abs.iter_mut().zip(&figures.action_max_abs) {
            *m = m.max(a);
        }
        if self.histograms.is_empty() {
            self.histograms = vec![[0; 100]; POSE_ACTION_DIM];
        }
        for (h, bins) in self.histograms.iter_mut().zip(&figures.action_bins) {
            for &(bin, count) in bins {
                if let Some(c) = usize::try_from(bin).ok().and_then(|b| h.get_mut(b)) {
                    *c += count;
                }
            }
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
                step_m_p95: self.steps.get(&subtask).map_or(0.0, |h| binned_quantile(h.iter(), 0.95, STEP_BINS_PER_M)),
            })
            .collect();
        let p95 = |h: &[usize; 100]| {
            let indexed: BTreeMap<u32, usize> = (0u32..).zip(h.iter().copied()).filter(|&(_, c)| c > 0).collect();
            binned_quantile(indexed.iter(), 0.95, 100.0)
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
