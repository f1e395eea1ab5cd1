//! The run doctor's reasoning, without running anything: the changes a run's failure causes point
//! at ([`suggest`]), ranked by how many of its failures each addresses, and the paired comparison
//! that says whether a change helped ([`Paired`]). `mimicgen-pipeline` tests the suggestions in
//! simulation; the app and the CLI show both.

use mimicgen_engine::TaskSpec;
use mimicgen_engine::spec::{SelectionStrategy, Transit};
use serde::{Deserialize, Serialize};

use crate::{Report, RunConfig, Scoped, SpecOverrides};

/// A change to a run's spec, and why the run's failures point at it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Suggestion {
    /// The change, as spec fields over the run's (its flags: [`SpecOverrides::to_args`]).
    pub change: SpecOverrides,
    /// What it is, in words (`less action noise on subtask 1: 0.05 -> 0.02`).
    pub what: String,
    /// The failures it addresses (`grasp slipped 17 in subtask 1`).
    pub why: String,
    /// How many of the run's failed attempts have a cause it addresses.
    pub addresses: usize,
}

impl Suggestion {
    /// Its flags as one string (`--action-noise 1:0.02`).
    #[must_use]
    pub fn flags(&self) -> String {
        self.change.to_args().join(" ")
    }
}

/// The changes a run's failure causes point at, most failures addressed first (ties in the order
/// the rules are listed below), one per distinct change:
///
/// - source demos that never led to a success: exclude them;
/// - a grasp that missed or slipped, a success check unmet: half the action noise of that
///   subtask; a missed grasp on a subtask that picks its source at random: the nearest
///   neighbour (by the object's pose) instead;
/// - the arm lagging behind its targets: three times the interpolation steps into that subtask,
///   and planned transit where the subtask has an object to approach;
/// - the subtask's object knocked away before it: planned transit into that subtask;
/// - a subtask that ran out of steps before its signal (not the last): its end 10 to 20 steps later.
///
/// Changes the run already made (the same value) are not suggested again.
#[must_use]
pub fn suggest(report: &Report, spec: &TaskSpec) -> Vec<Suggestion> {
    let mut out: Vec<Suggestion> = Vec::new();
    let mut add = |change: SpecOverrides, what: String, why: String, addresses: usize| {
        if addresses == 0 {
            return;
        }
        match out.iter_mut().find(|s| s.change == change) {
            Some(s) => {
                s.addresses += addresses;
                s.why = format!("{}; {why}", s.why);
            }
            None => out.push(Suggestion { change, what, why, addresses }),
        }
    };
    let excluded = &spec.generation.exclude_sources;
    let drop: Vec<usize> = report.never_succeeded.iter().copied().filter(|d| !excluded.contains(d)).collect();
    if !drop.is_empty() {
        let failures: usize = report.per_source_demo.iter().filter(|d| drop.contains(&d.demo)).map(|d| d.attempts - d.successes).sum();
        let names: Vec<String> = drop.iter().map(|d| format!("{d}")).collect();
        add(
            SpecOverrides { exclude_source: drop.clone(), ..SpecOverrides::default() },
            format!("exclude source demo(s) {}", names.join(", ")),
            format!("{failures} failed attempts used them and none succeeded"),
            failures,
        );
    }
    let count = |cause: &str, subtask: usize| {
        report.causes.iter().filter(|c| c.cause == cause && c.subtask == subtask).map(|c| c.count).sum::<usize>()
    };
    let last = spec.subtasks.len().saturating_sub(1);
    for (k, sub) in spec.subtasks.iter().enumerate() {
        let (missed, slipped, unmet) = (count("grasp_missed", k), count("grasp_slipped", k), count("success_unmet", k));
        let (lagged, moved, out_of_steps) = (count("arm_lagged", k), count("object_moved", k), count("ran_out_of_steps", k));
        let words = |pairs: &[(&str, usize)]| {
            let parts: Vec<String> = pairs.iter().filter(|(_, n)| *n > 0).map(|(w, n)| format!("{w} {n}")).collect();
            format!("{} in subtask {k}", parts.join(", "))
        };
        let noise = sub.action_noise;
        if noise > 0.005 {
            let less = (noise * 500.0).round() / 1000.0;
            add(
                SpecOverrides { action_noise: vec![Scoped { subtask: Some(k), value: less }], ..SpecOverrides::default() },
                format!("less action noise on subtask {k}: {noise} -> {less}"),
                words(&[("grasp missed", missed), ("grasp slipped", slipped), ("success unmet", unmet)]),
                missed + slipped + unmet,
            );
        }
        if sub.selection == SelectionStrategy::Random && sub.object_ref.is_some() {
            add(
                SpecOverrides {
                    selection: vec![Scoped { subtask: Some(k), value: "nearest_neighbor_object".to_owned() }],
                    ..SpecOverrides::default()
                },
                format!("subtask {k}'s source chosen by the object's pose (nearest_neighbor_object, nn_k 3) instead of at random"),
                words(&[("grasp missed", missed)]),
                missed,
            );
        }
        let steps = sub.num_interpolation_steps;
        let more = (steps * 3).max(steps + 10);
        add(
            SpecOverrides { interpolation_steps: vec![Scoped { subtask: Some(k), value: more }], ..SpecOverrides::default() },
            format!("more interpolation steps into subtask {k}: {steps} -> {more}"),
            words(&[("arm lagged", lagged)]),
            lagged,
        );
        if sub.object_ref.is_some() && sub.transit != Transit::Plan {
            add(
                SpecOverrides { transit: vec![Scoped { subtask: Some(k), value: Transit::Plan }], ..SpecOverrides::default() },
                format!("planned transit into subtask {k} (a collision-free path to the approach)"),
                words(&[("arm lagged", lagged), ("object moved", moved)]),
                lagged + moved,
            );
        }
        if k < last && sub.term_signal.is_some() && sub.term_offset_range.is_none_or(|(_, hi)| hi < 10) {
            add(
                SpecOverrides {
                    offset_range: vec![Scoped { subtask: Some(k), value: crate::OffsetRange(10, 20) }],
                    ..SpecOverrides::default()
                },
                format!("subtask {k} ends 10 to 20 steps later"),
                words(&[("ran out of steps", out_of_steps)]),
                out_of_steps,
            );
        }
    }
    // Stable: equal counts keep the rules' order.
    out.sort_by_key(|s| std::cmp::Reverse(s.addresses));
    out
}

/// Two arms of the same attempts (same seed, same indices): where each succeeded.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Paired {
    /// Attempts in each arm.
    pub attempts: usize,
    /// Successes without the change.
    pub base_successes: usize,
    /// Successes with it.
    pub changed_successes: usize,
    /// Attempts that failed without the change and succeeded with it.
    pub gained: usize,
    /// Attempts that succeeded without it and failed with it.
    pub lost: usize,
    /// The change in success rate (changed minus base), a fraction.
    pub difference: f64,
    /// Half the width of its 95 % interval (normal approximation of the mean of the paired
    /// differences).
    pub half_width: f64,
}

/// What a paired comparison shows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Verdict {
    /// The whole interval is above zero.
    Helps,
    /// The whole interval is below zero.
    Hurts,
    /// The interval holds zero: not shown to matter at this many attempts.
    Unproven,
}

impl Verdict {
    /// In words.
    #[must_use]
    pub fn words(self) -> &'static str {
        match self {
            Self::Helps => "helps",
            Self::Hurts => "hurts",
            Self::Unproven => "not proven",
        }
    }
}

impl Paired {
    /// Compares the outcomes of the same attempts without (`base`) and with (`changed`) a change.
    /// Pairs past the shorter slice are left out.
    #[must_use]
    #[allow(clippy::cast_precision_loss)] // attempt counts are far below 2^52
    pub fn new(base: &[bool], changed: &[bool]) -> Self {
        let n = base.len().min(changed.len());
        let pairs = || base.iter().zip(changed);
        let gained = pairs().filter(|&(b, c)| !b && *c).count();
        let lost = pairs().filter(|&(b, c)| *b && !c).count();
        let (difference, half_width) = if n == 0 {
            (0.0, 0.0)
        } else {
            let mean = (gained as f64 - lost as f64) / n as f64;
            // Each difference is -1, 0 or 1: the squares sum to the discordant pairs.
            let variance = if n > 1 { ((gained + lost) as f64 - n as f64 * mean * mean) / (n - 1) as f64 } else { 0.0 };
            (mean, 1.96 * (variance.max(0.0) / n as f64).sqrt())
        };
        Self {
            attempts: n,
            base_successes: pairs().filter(|(b, _)| **b).count(),
            changed_successes: pairs().filter(|(_, c)| **c).count(),
            gained,
            lost,
            difference,
            half_width,
        }
    }

    /// The difference with its interval, in points: `+13.3 points [-7.1, +33.8]`.
    #[must_use]
    pub fn interval(&self) -> String {
        format!(
            "{:+.1} points [{:+.1}, {:+.1}]",
            100.0 * self.difference,
            100.0 * (self.difference - self.half_width),
            100.0 * (self.difference + self.half_width)
        )
    }

    /// Whether the interval lies above zero, below it, or holds it.
    #[must_use]
    pub fn verdict(&self) -> Verdict {
        if self.difference - self.half_width > 0.0 {
            Verdict::Helps
        } else if self.difference + self.half_width < 0.0 {
            Verdict::Hurts
        } else {
            Verdict::Unproven
        }
    }
}

/// One suggestion tested on the same attempts as the run without it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Trial {
    /// The change.
    pub suggestion: Suggestion,
    /// The comparison.
    pub paired: Paired,
    /// What it shows.
    pub verdict: Verdict,
    /// The `mimicgen generate` command that makes the run again with the change.
    pub command: String,
}

/// What `mimicgen doctor` found: the run's suggestions, ranked, and the best few tested.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Diagnosis {
    /// The report read.
    pub report: String,
    /// Task.
    pub task: String,
    /// Variant.
    pub variant: String,
    /// The run's rate.
    pub run_rate: f64,
    /// The run seed the trials used.
    pub seed: u64,
    /// The first attempt index tested (the run's attempt count: attempts the run did not make).
    pub first_attempt: usize,
    /// Attempts per arm.
    pub attempts: usize,
    /// Successes of the run's own spec on the tested attempts.
    pub base_successes: usize,
    /// Every suggestion, most failures addressed first.
    pub suggestions: Vec<Suggestion>,
    /// The tested ones, in rank order.
    pub trials: Vec<Trial>,
    /// The trial that helped most, if one was shown to help.
    pub winner: Option<usize>,
    /// The winner (else the trial with the largest difference) checked on fresh attempts, when
    /// asked for.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub check: Option<Check>,
}

/// A tested change run again on attempts neither the run nor the trials saw: another seed.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Check {
    /// The trial checked (an index into [`Diagnosis::trials`]).
    pub trial: usize,
    /// The seed (the run's plus one).
    pub seed: u64,
    /// The comparison on attempts `0..paired.attempts` of that seed.
    pub paired: Paired,
    /// What it shows.
    pub verdict: Verdict,
}

impl Diagnosis {
    /// The winning trial.
    #[must_use]
    pub fn best(&self) -> Option<&Trial> {
        self.trials.get(self.winner?)
    }

    /// The trial to check on fresh attempts: the winner, else the one with the largest
    /// difference (the first of equals).
    #[must_use]
    pub fn to_check(trials: &[Trial]) -> Option<usize> {
        Self::pick_winner(trials).or_else(|| {
            let mut best: Option<usize> = None;
            for (i, t) in trials.iter().enumerate() {
                if best.and_then(|b| trials.get(b)).is_none_or(|b| t.paired.difference > b.paired.difference) {
                    best = Some(i);
                }
            }
            best
        })
    }

    /// The index of the trial that helps most (largest difference among those whose interval is
    /// above zero; the first of equals).
    #[must_use]
    pub fn pick_winner(trials: &[Trial]) -> Option<usize> {
        let mut best: Option<usize> = None;
        for (i, t) in trials.iter().enumerate() {
            if t.verdict == Verdict::Helps && best.and_then(|b| trials.get(b)).is_none_or(|b| t.paired.difference > b.paired.difference) {
                best = Some(i);
            }
        }
        best
    }
}

/// The run `report` describes, made again with `change` on top of its own spec fields: the same
/// task, variant, sources, spec file, arm, seed and attempt count, into `out`.
#[must_use]
pub fn rerun_config(report: &Report, change: &SpecOverrides, out: std::path::PathBuf) -> RunConfig {
    RunConfig {
        task: Some(report.task.clone()),
        variant: Some(report.variant.clone()),
        config: report.config.as_ref().map(Into::into),
        source: Some(report.source.clone().into()),
        robot: report.robot.clone(),
        seed: Some(report.seed),
        num_demos: Some(report.attempts),
        early_abort: report.early_abort,
        workers: report.workers.max(1),
        spec: report.spec_overrides.then(change),
        out,
        ..RunConfig::default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{CauseReport, DemoReport};

    fn spec() -> TaskSpec {
        mimicgen_engine::kinematic::pick_place_spec(100, 1)
    }

    fn report(causes: &[(usize, &str, usize)], never: &[usize]) -> Report {
        let demo = |demo, attempts, successes| DemoReport { demo, attempts, successes };
        Report {
            task: "stack".into(),
            variant: "D0".into(),
            seed: 3,
            workers: 1,
            source: "s.hdf5".into(),
            config: None,
            robot: None,
            output: "out.hdf5".into(),
            failed_output: None,
            attempts: 100,
            successes: 60,
            generation_rate: 0.6,
            wall_time_s: 0.0,
            attempts_per_s: 0.0,
            control_steps: 0,
            per_source_demo: vec![demo(0, 50, 40), demo(1, 30, 20), demo(2, 20, 0)],
            per_subtask_source: Vec::new(),
            never_succeeded: never.to_vec(),
            per_object_instance: Vec::new(),
            peak_rss_mib: None,
            failures: Vec::new(),
            causes: causes.iter().map(|&(subtask, cause, count)| CauseReport { subtask, cause: cause.into(), count }).collect(),
            cancelled: false,
            resumed_from: 0,
            early_abort: false,
            spec_overrides: SpecOverrides::default(),
            shard: None,
            quality: None,
            transit: mimicgen_engine::generate::TransitTotals::default(),
        }
    }

    #[test]
    fn suggestions_follow_the_causes_most_failures_first() {
        let r = report(&[(0, "grasp_missed", 12), (1, "arm_lagged", 25), (1, "object_moved", 3)], &[2]);
        let s = suggest(&r, &spec());
        let flags: Vec<String> = s.iter().map(Suggestion::flags).collect();
        // Lagged 25 + moved 3 into subtask 1: planned transit addresses 28, more steps 25, the
        // excluded demo's 20 failures, then the missed grasps.
        assert_eq!(flags[0], "--transit 1:plan", "{flags:?}");
        assert_eq!(s[0].addresses, 28);
        assert_eq!(flags[1], "--interpolation-steps 1:15");
        assert_eq!((flags[2].as_str(), s[2].addresses), ("--exclude-source 2", 20));
        assert!(flags[3..].contains(&"--action-noise 0:0.025".to_owned()), "{flags:?}");
        assert!(s.iter().all(|x| x.addresses > 0), "no suggestion without a failure behind it");
        // A cause the run did not have suggests nothing for it.
        assert!(!flags.iter().any(|f| f.contains("offset-range")), "{flags:?}");
        // Nothing failed: nothing to suggest.
        assert!(suggest(&report(&[], &[]), &spec()).is_empty());
    }

    #[test]
    fn a_change_the_run_already_made_is_not_suggested_again() {
        let mut spec = spec();
        spec.generation.exclude_sources = vec![2];
        for sub in &mut spec.subtasks {
            sub.transit = Transit::Plan;
        }
        let s = suggest(&report(&[(1, "object_moved", 9)], &[2]), &spec);
        assert!(s.is_empty(), "{s:?}");
    }

    #[test]
    fn paired_outcomes_give_the_difference_and_its_interval() {
        // 100 pairs: 20 gained, 5 lost, the rest equal.
        let base: Vec<bool> = (0..100).map(|i| (20..60).contains(&i)).collect();
        let changed: Vec<bool> = (0..100).map(|i| i < 55).collect();
        let p = Paired::new(&base, &changed);
        assert_eq!((p.attempts, p.base_successes, p.changed_successes, p.gained, p.lost), (100, 40, 55, 20, 5));
        assert!((p.difference - 0.15).abs() < 1e-12);
        // sd of the differences: sqrt((25 - 100 * 0.0225) / 99) = 0.4794; half = 1.96 * 0.04794.
        assert!((p.half_width - 0.093_97).abs() < 1e-4, "{}", p.half_width);
        assert_eq!(p.interval(), "+15.0 points [+5.6, +24.4]");
        assert_eq!(p.verdict(), Verdict::Helps);
        assert_eq!(Paired::new(&changed, &base).verdict(), Verdict::Hurts);
        let same = Paired::new(&base, &base);
        assert_eq!((same.difference, same.half_width, same.verdict()), (0.0, 0.0, Verdict::Unproven));
        // A single gained pair in a hundred proves nothing.
        let mut one = base.clone();
        one[0] = true;
        assert_eq!(Paired::new(&base, &one).verdict(), Verdict::Unproven);
    }

    #[test]
    fn the_winner_is_the_largest_proven_gain() {
        let trial = |difference, verdict| Trial {
            suggestion: Suggestion { change: SpecOverrides::default(), what: String::new(), why: String::new(), addresses: 1 },
            paired: Paired { attempts: 10, base_successes: 0, changed_successes: 0, gained: 0, lost: 0, difference, half_width: 0.01 },
            verdict,
            command: String::new(),
        };
        let trials = [trial(0.3, Verdict::Unproven), trial(0.1, Verdict::Helps), trial(0.2, Verdict::Helps), trial(-0.2, Verdict::Hurts)];
        assert_eq!(Diagnosis::pick_winner(&trials), Some(2));
        assert_eq!(Diagnosis::pick_winner(&trials[..1]), None);
        // Checked on fresh attempts: the winner, else the largest difference.
        assert_eq!(Diagnosis::to_check(&trials), Some(2));
        assert_eq!(Diagnosis::to_check(&[trial(-0.1, Verdict::Unproven), trial(0.05, Verdict::Unproven)]), Some(1));
        assert_eq!(Diagnosis::to_check(&[]), None);
    }

    #[test]
    fn the_rerun_keeps_the_run_and_adds_the_change() {
        let mut r = report(&[], &[]);
        r.spec_overrides.action_noise = vec![Scoped::all(0.02)];
        r.config = Some("my.toml".into());
        let change = SpecOverrides { exclude_source: vec![2], ..SpecOverrides::default() };
        let config = rerun_config(&r, &change, "out_doctor.hdf5".into());
        let args = config.to_args().join(" ");
        for part in [
            "--task stack",
            "--variant D0",
            "--config my.toml",
            "--source s.hdf5",
            "--seed 3",
            "--num-demos 100",
            "--action-noise 0.02",
            "--exclude-source 2",
        ] {
            assert!(args.contains(part), "{part} missing from {args}");
        }
    }
}
