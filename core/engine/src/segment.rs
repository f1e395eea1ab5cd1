//! Splitting source demos into object-centric subtask segments (paper Sec. 3.1).
//!
//! A subtask ends just after the first step at which its signal turns on (0 -> 1) at or after the
//! previous boundary, so that step belongs to the subtask: `[start, t + 1)`, as MimicGen's
//! `parse_source_dataset` reads it. A hand-annotated boundary overrides the signal; the last
//! subtask ends with the demo.
//!
//! Where we differ from the reference on purpose: it takes the first *change* of the signal in
//! either direction, so a signal that starts on and turns off ends the subtask at the fall; we
//! wait for the first rise, which is what "the subtask is done" means.
//! Each attempt then shifts every boundary but the last by an offset drawn from the subtask's
//! `term_offset_range`, so segments vary a little from attempt to attempt, as MimicGen does.

use rand::Rng;

use crate::EngineError;
use crate::demo::SourceDemo;
use crate::spec::{TaskSpec, Transit};

/// Half-open step range `[start, end)` of one subtask in one demo.
pub type Span = (usize, usize);

/// First step `t >= from` (and `t >= 1`) where `signal[t-1] == 0` and `signal[t] != 0`.
#[must_use]
pub fn first_rising_edge(signal: &[i64], from: usize) -> Option<usize> {
    // Window i holds steps i and i + 1; t = i + 1 >= max(from, 1).
    signal.windows(2).enumerate().skip(from.saturating_sub(1)).find_map(|(i, w)| matches!(w, &[0, now] if now != 0).then_some(i + 1))
}

/// The end (exclusive) of a subtask that starts at `start` and whose signal is `signal`: one past
/// the first step at or after `start` where the signal turns on, as MimicGen's segmentation
/// reads it. `None` when the signal never turns on there.
#[must_use]
pub fn subtask_end_from_signal(signal: &[i64], start: usize) -> Option<usize> {
    first_rising_edge(signal, start).map(|t| t + 1)
}

/// Nominal subtask boundaries of every demo, before per-attempt offsets.
#[derive(Debug, Clone, PartialEq)]
pub struct Segmentation {
    /// `ends[d][i]`: nominal end step of subtask `i` in demo `d` (the last equals the demo length).
    ends: Vec<Vec<usize>>,
    offsets: Vec<(i64, i64)>,
    /// `approaches[d][i]`: where the approach to subtask `i`'s object begins in demo `d`, for the
    /// subtasks whose transit is planned (the segment starts there, not at the previous end).
    approaches: Vec<Vec<Option<usize>>>,
}

impl Segmentation {
    /// Parses every demo with the spec's signals (or the demo's manual boundaries), and checks that
    /// even the most extreme offsets leave every segment non-empty.
    ///
    /// # Errors
    /// [`EngineError::Segmentation`] naming the demo and subtask.
    pub fn new(demos: &[SourceDemo], spec: &TaskSpec) -> Result<Self, EngineError> {
        let num = spec.subtasks.len();
        let offsets: Vec<(i64, i64)> = spec
            .subtasks
            .iter()
            .enumerate()
            .map(|(i, s)| if i + 1 == num { (0, 0) } else { s.term_offset_range.unwrap_or((0, 0)) })
            .collect();
        let mut ends = Vec::with_capacity(demos.len());
        let mut approaches = Vec::with_capacity(demos.len());
        for demo in demos {
            let fail = |subtask: usize, reason: String| EngineError::Segmentation { demo: demo.name.clone(), subtask, reason };
            let mut demo_ends = Vec::with_capacity(num);
            if let Some(manual) = &demo.manual_subtask_ends {
                if manual.len() + 1 != num {
                    return Err(fail(0, format!("{} manual boundaries given, the task needs {}", manual.len(), num.saturating_sub(1))));
                }
                demo_ends.extend_from_slice(manual);
            } else {
                let mut prev = 0;
                for (i, s) in spec.subtasks.iter().enumerate().take(num.saturating_sub(1)) {
                    let name = s
                        .term_signal
                        .as_deref()
                        .ok_or_else(|| fail(i, "has no term_signal and the demo has no manual boundaries".to_owned()))?;
                    let signal = demo.subtask_term_signals.get(name).ok_or_else(|| fail(i, format!("demo has no signal {name:?}")))?;
                    let end = subtask_end_from_signal(signal, prev)
                        .ok_or_else(|| fail(i, format!("signal {name:?} never turns on at or after step {prev}")))?;
                    demo_ends.push(end);
                    prev = end;
                }
            }
            demo_ends.push(demo.len());
            let mut start_latest = 0i64;
            for (i, (&end, &(lo, hi))) in demo_ends.iter().zip(&offsets).enumerate() {
                let end = i64::try_from(end).unwrap_or(i64::MAX);
                let end_earliest = end + lo;
                if end_earliest <= start_latest {
                    return Err(fail(
                        i,
                        format!("segment can be empty: it starts as late as step {start_latest} and may end at step {end_earliest}"),
                    ));
                }
                let end_latest = end + hi;
                if end_latest > i64::try_from(demo.len()).unwrap_or(i64::MAX) {
                    return Err(fail(i, format!("boundary {end} plus offset {hi} runs past the demo's {} steps", demo.len())));
                }
                start_latest = end_latest;
            }
            approaches.push(approach_starts(demo, spec, &demo_ends, &offsets).map_err(|(i, reason)| fail(i, reason))?);
            ends.push(demo_ends);
        }
        Ok(Self { ends, offsets, approaches })
    }

    /// Where the approach to each planned subtask's object begins in demo `d` (`None` for
    /// interpolated subtasks): the segment of such a subtask is replayed from there. Empty for a
    /// demo the segmentation does not have.
    #[must_use]
    pub fn approach_starts(&self, d: usize) -> &[Option<usize>] {
        self.approaches.get(d).map_or(&[], Vec::as_slice)
    }

    /// Number of demos.
    #[must_use]
    pub fn num_demos(&self) -> usize {
        self.ends.len()
    }

    /// Nominal spans of demo `d`, one per subtask (none for a demo the segmentation does not have).
    #[must_use]
    pub fn nominal_spans(&self, d: usize) -> Vec<Span> {
        self.ends.get(d).map(|ends| spans_from_ends(ends)).unwrap_or_default()
    }

    /// Spans of every demo with freshly drawn boundary offsets (one draw per demo per subtask).
    /// A planned subtask's span starts at its approach (when that is later than the previous end).
    pub fn draw_spans<R: Rng + ?Sized>(&self, rng: &mut R) -> Vec<Vec<Span>> {
        self.ends
            .iter()
            .zip(&self.approaches)
            .map(|(ends, approaches)| {
                let shifted: Vec<usize> = ends
                    .iter()
                    .zip(&self.offsets)
                    .map(|(&end, &(lo, hi))| {
                        let offset = if lo == hi { lo } else { rng.random_range(lo..=hi) };
                        // `new` checked that every shifted boundary stays inside the demo.
                        usize::try_from(i64::try_from(end).unwrap_or(i64::MAX) + offset).unwrap_or(end)
                    })
                    .collect();
                let mut spans = spans_from_ends(&shifted);
                for (span, approach) in spans.iter_mut().zip(approaches) {
                    if let Some(a) = approach {
                        span.0 = span.0.max(*a).min(span.1.saturating_sub(1));
                    }
                }
                spans
            })
            .collect()
    }
}

/// Fewest steps a planned subtask's segment keeps after its approach start (a hand-marked start
/// must leave them too).
pub const MIN_APPROACH_STEPS: usize = 2;

/// The approach start of every subtask of `demo` whose transit is planned: where the demo's
/// hand-marked start says (`manual_subtask_starts`), else the first step at which the end effector
/// comes within `approach_m` of the subtask's object (it starts where the previous subtask ended
/// when it is that close already), and at least two steps before the subtask's earliest end.
/// `Err((subtask, reason))` for a hand-marked start outside its subtask.
fn approach_starts(
    demo: &SourceDemo,
    spec: &TaskSpec,
    ends: &[usize],
    offsets: &[(i64, i64)],
) -> Result<Vec<Option<usize>>, (usize, String)> {
    let mut prev_end = 0;
    let mut out = Vec::with_capacity(spec.subtasks.len());
    for (i, ((s, &end), &(lo, _))) in spec.subtasks.iter().zip(ends).zip(offsets).enumerate() {
        let start = prev_end;
        prev_end = end;
        if s.transit != Transit::Plan {
            out.push(None);
            continue;
        }
        let latest_start = usize::try_from(i64::try_from(end).unwrap_or(i64::MAX) + lo).unwrap_or(end).saturating_sub(MIN_APPROACH_STEPS);
        let marked = demo.manual_subtask_starts.as_ref().and_then(|m| m.get(i).copied().flatten());
        if let Some(m) = marked {
            if m < start || m > latest_start {
                return Err((i, format!("hand-marked start {m} is outside the subtask's steps {start}..={latest_start}")));
            }
            out.push(Some(m));
            continue;
        }
        let Some(poses) = s.object_ref.as_deref().and_then(|o| demo.object_poses.get(o)) else {
            out.push(None);
            continue;
        };
        let distance = |t: usize| match (demo.eef_poses.get(t), poses.get(t)) {
            (Some(eef), Some(obj)) => Some((eef.translation.vector - obj.translation.vector).norm()),
            _ => None,
        };
        out.push(Some(approach_start(start..end, latest_start, s.approach_m, distance)));
    }
    Ok(out)
}

/// Where the approach to a subtask's object begins among its `steps`: the first step at which the
/// end effector's `distance` to the object is within `approach_m` (the first step when it never
/// is, or is that close already), and no later than `latest`. The auto-detected segment start,
/// which the app proposes and a hand-marked start overrides.
#[must_use]
pub fn approach_start(steps: std::ops::Range<usize>, latest: usize, approach_m: f64, distance: impl Fn(usize) -> Option<f64>) -> usize {
    let first = steps.start;
    let approach = steps.clone().find(|&t| distance(t).is_some_and(|d| d <= approach_m)).unwrap_or(first);
    approach.min(latest).max(first)
}

fn spans_from_ends(ends: &[usize]) -> Vec<Span> {
    let mut start = 0;
    ends.iter()
        .map(|&end| {
            let span = (start, end);
            start = end;
            span
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    use super::*;
    use crate::spec::{SelectionStrategy, SubtaskSpec, TaskSpec, Transit};
    use crate::testing::demo_with_object_at;

    fn spec(offsets: Option<(i64, i64)>) -> TaskSpec {
        let sub = |signal: Option<&str>, offsets| SubtaskSpec {
            object_ref: Some("cube".into()),
            term_signal: signal.map(str::to_owned),
            term_offset_range: offsets,
            selection: SelectionStrategy::Random,
            action_noise: 0.0,
            num_interpolation_steps: 0,
            num_fixed_steps: 0,
            apply_noise_during_interpolation: false,
            transit: crate::spec::Transit::Interpolate,
            approach_m: 0.1,
            selection_object: None,
        };
        TaskSpec {
            name: "t".into(),
            env_name: None,
            generation: Default::default(),
            source: Default::default(),
            subtasks: vec![sub(Some("on"), offsets), sub(None, None)],
        }
    }

    #[test]
    fn rising_edge_after_the_previous_boundary() {
        let s = [1, 1, 0, 0, 1, 1, 0, 1];
        assert_eq!(first_rising_edge(&s, 0), Some(4));
        assert_eq!(first_rising_edge(&s, 4), Some(4));
        assert_eq!(first_rising_edge(&s, 5), Some(7));
        assert_eq!(first_rising_edge(&s, 8), None);
        assert_eq!(first_rising_edge(&[0, 0, 0], 0), None);
        // The step where the signal turns on belongs to the subtask that ends there.
        assert_eq!(subtask_end_from_signal(&s, 0), Some(5));
        assert_eq!(subtask_end_from_signal(&s, 5), Some(8));
        assert_eq!(subtask_end_from_signal(&[1, 1, 0], 0), None);
    }

    #[test]
    fn signals_split_demos_and_the_last_subtask_runs_to_the_end() {
        let demos = vec![demo_with_object_at("cube", 0.0)];
        let seg = Segmentation::new(&demos, &spec(None)).unwrap();
        assert_eq!(seg.nominal_spans(0), vec![(0, 5), (5, 10)]);
    }

    #[test]
    fn manual_boundaries_override_signals() {
        let mut demo = demo_with_object_at("cube", 0.0);
        demo.manual_subtask_ends = Some(vec![7]);
        let seg = Segmentation::new(&[demo], &spec(None)).unwrap();
        assert_eq!(seg.nominal_spans(0), vec![(0, 7), (7, 10)]);
    }

    #[test]
    fn offsets_are_drawn_within_range_and_keep_segments_contiguous() {
        let demos = vec![demo_with_object_at("cube", 0.0), demo_with_object_at("cube", 1.0)];
        let seg = Segmentation::new(&demos, &spec(Some((-2, 3)))).unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(0);
        let mut ends = std::collections::BTreeSet::new();
        for _ in 0..200 {
            for spans in seg.draw_spans(&mut rng) {
                assert_eq!(spans[0].0, 0);
                assert_eq!(spans[0].1, spans[1].0);
                assert_eq!(spans[1].1, 10);
                ends.insert(spans[0].1);
            }
        }
        assert_eq!(ends.into_iter().collect::<Vec<_>>(), vec![3, 4, 5, 6, 7, 8]);
    }

    #[test]
    fn planned_subtasks_start_at_the_approach_or_where_marked() {
        let mut plan = spec(None);
        for sub in &mut plan.subtasks {
            sub.transit = Transit::Plan;
            sub.approach_m = 0.035;
        }
        // The gripper descends 1 cm a step from 10 cm above the object: within 3.5 cm at step 7,
        // in the second subtask; the first never comes that near and starts where it did.
        let demo = demo_with_object_at("cube", 0.0);
        let seg = Segmentation::new(std::slice::from_ref(&demo), &plan).unwrap();
        assert_eq!(seg.approach_starts(0), &[Some(0), Some(7)]);
        assert_eq!(seg.draw_spans(&mut ChaCha8Rng::seed_from_u64(0))[0], vec![(0, 5), (7, 10)]);
        let mut marked = demo.clone();
        marked.manual_subtask_starts = Some(vec![Some(1), None]);
        let seg = Segmentation::new(std::slice::from_ref(&marked), &plan).unwrap();
        assert_eq!(seg.approach_starts(0), &[Some(1), Some(7)]);
        marked.manual_subtask_starts = Some(vec![None, Some(9)]);
        let err = Segmentation::new(&[marked], &plan).unwrap_err().to_string();
        assert!(err.contains("subtask 1") && err.contains("hand-marked start 9"), "{err}");
        // Interpolated subtasks keep MimicGen's segments.
        assert_eq!(Segmentation::new(&[demo], &spec(None)).unwrap().approach_starts(0), &[None, None]);
    }

    #[test]
    fn errors_name_the_demo_and_subtask() {
        let mut never = demo_with_object_at("cube", 0.0);
        never.name = "demo_7".into();
        never.subtask_term_signals.insert("on".into(), vec![0; 10]);
        let err = Segmentation::new(&[never], &spec(None)).unwrap_err().to_string();
        assert!(err.contains("demo_7") && err.contains("subtask 0") && err.contains("never turns on"), "{err}");

        let demo = demo_with_object_at("cube", 0.0);
        let err = Segmentation::new(std::slice::from_ref(&demo), &spec(Some((-5, 0)))).unwrap_err().to_string();
        assert!(err.contains("can be empty"), "{err}");
        let err = Segmentation::new(std::slice::from_ref(&demo), &spec(Some((0, 6)))).unwrap_err().to_string();
        assert!(err.contains("can be empty") || err.contains("past the demo"), "{err}");

        let mut manual = demo;
        manual.manual_subtask_ends = Some(vec![10]);
        let err = Segmentation::new(&[manual], &spec(None)).unwrap_err().to_string();
        assert!(err.contains("subtask 1") && err.contains("can be empty"), "{err}");
    }
}
