//! Spec fields set for one run (`mimicgen generate --action-noise 0.02`, the app's run form) over
//! the task spec's values, for every subtask or for one (`--action-noise 1:0.02`).

use std::fmt;
use std::str::FromStr;

use mimicgen_engine::spec::Transit;
use mimicgen_engine::{SelectionStrategy, SubtaskSpec, TaskSpec};
use serde::{Deserialize, Serialize};

use crate::RunError;

/// A value for every subtask (`VALUE`) or for subtask `K` only (`K:VALUE`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Scoped<T> {
    /// The subtask, or `None` for all.
    pub subtask: Option<usize>,
    /// The value.
    pub value: T,
}

impl<T> Scoped<T> {
    /// `value` for every subtask.
    pub fn all(value: T) -> Self {
        Self { subtask: None, value }
    }
}

impl<T: FromStr> FromStr for Scoped<T>
where
    T::Err: fmt::Display,
{
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        let (subtask, value) = match s.split_once(':') {
            Some((k, v)) if !k.is_empty() && k.bytes().all(|b| b.is_ascii_digit()) => {
                (Some(k.parse().map_err(|e| format!("subtask {k:?}: {e}"))?), v)
            }
            _ => (None, s),
        };
        let value = value.trim().parse().map_err(|e: T::Err| format!("{value:?}: {e}"))?;
        Ok(Self { subtask, value })
    }
}

impl<T: fmt::Display> fmt::Display for Scoped<T> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.subtask {
            Some(k) => write!(f, "{k}:{}", self.value),
            None => write!(f, "{}", self.value),
        }
    }
}

/// An inclusive range of steps added to a subtask's end, `LO,HI` (MimicGen's
/// `subtask_term_offset_range`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct OffsetRange(pub i64, pub i64);

impl FromStr for OffsetRange {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        let (lo, hi) = s.split_once(',').ok_or_else(|| "expected LO,HI (for example 0,10)".to_owned())?;
        let parse = |v: &str| v.trim().parse::<i64>().map_err(|e| format!("{v:?}: {e}"));
        Ok(Self(parse(lo)?, parse(hi)?))
    }
}

impl fmt::Display for OffsetRange {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{},{}", self.0, self.1)
    }
}

/// Spec fields that override the task spec's, applied in order (a later value for the same subtask
/// wins). Empty: the spec as it is.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct SpecOverrides {
    /// Source selection strategy: `random`, `nearest_neighbor_object` or
    /// `nearest_neighbor_robot_distance`.
    pub selection: Vec<Scoped<String>>,
    /// How many nearest demos the nearest-neighbour strategies draw from.
    pub nn_k: Vec<Scoped<usize>>,
    /// Standard deviation of the action noise.
    pub action_noise: Vec<Scoped<f64>>,
    /// Range of steps added to a subtask's end.
    pub offset_range: Vec<Scoped<OffsetRange>>,
    /// Intermediate poses of the interpolation segment.
    pub interpolation_steps: Vec<Scoped<usize>>,
    /// Steps holding the first pose of the transformed segment after interpolating.
    pub fixed_steps: Vec<Scoped<usize>>,
    /// Choose a source demo at each subtask (else once per attempt).
    pub select_src_per_subtask: Option<bool>,
    /// How the robot gets to each segment: `interpolate` (MimicGen) or `plan` (a collision-free
    /// path, SkillGen).
    pub transit: Vec<Scoped<Transit>>,
    /// With planned transit, how near the object (m) the replayed approach begins.
    pub approach_m: Vec<Scoped<f64>>,
    /// Source demos (indices, as the report counts them) no selection picks.
    pub exclude_source: Vec<usize>,
}

impl SpecOverrides {
    /// The fields' names (Python's `spec` keys; the flags are these with `--` and dashes).
    pub const FIELDS: [&str; 10] = [
        "selection",
        "nn_k",
        "action_noise",
        "offset_range",
        "interpolation_steps",
        "fixed_steps",
        "select_src_per_subtask",
        "transit",
        "approach_m",
        "exclude_source",
    ];

    /// Whether it changes nothing.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        *self == Self::default()
    }

    /// These overrides, then `later` over them: a field `later` sets for a subtask wins there.
    #[must_use]
    pub fn then(&self, later: &Self) -> Self {
        fn joined<T: Clone>(a: &[T], b: &[T]) -> Vec<T> {
            [a, b].concat()
        }
        let mut exclude_source = joined(&self.exclude_source, &later.exclude_source);
        exclude_source.sort_unstable();
        exclude_source.dedup();
        Self {
            selection: joined(&self.selection, &later.selection),
            nn_k: joined(&self.nn_k, &later.nn_k),
            action_noise: joined(&self.action_noise, &later.action_noise),
            offset_range: joined(&self.offset_range, &later.offset_range),
            interpolation_steps: joined(&self.interpolation_steps, &later.interpolation_steps),
            fixed_steps: joined(&self.fixed_steps, &later.fixed_steps),
            select_src_per_subtask: later.select_src_per_subtask.or(self.select_src_per_subtask),
            transit: joined(&self.transit, &later.transit),
            approach_m: joined(&self.approach_m, &later.approach_m),
            exclude_source,
        }
    }

    /// The `mimicgen generate` flags that give these overrides.
    #[must_use]
    pub fn to_args(&self) -> Vec<String> {
        fn push<T: fmt::Display>(args: &mut Vec<String>, flag: &str, values: &[Scoped<T>]) {
            for v in values {
                args.push(flag.to_owned());
                args.push(v.to_string());
            }
        }
        let mut args = Vec::new();
        push(&mut args, "--selection", &self.selection);
        push(&mut args, "--nn-k", &self.nn_k);
        push(&mut args, "--action-noise", &self.action_noise);
        push(&mut args, "--offset-range", &self.offset_range);
        push(&mut args, "--interpolation-steps", &self.interpolation_steps);
        push(&mut args, "--fixed-steps", &self.fixed_steps);
        push(&mut args, "--transit", &self.transit);
        push(&mut args, "--approach-m", &self.approach_m);
        if let Some(on) = self.select_src_per_subtask {
            args.push("--select-src-per-subtask".to_owned());
            args.push(on.to_string());
        }
        if !self.exclude_source.is_empty() {
            args.push("--exclude-source".to_owned());
            args.push(self.exclude_source.iter().map(ToString::to_string).collect::<Vec<_>>().join(","));
        }
        args
    }

    /// Applies the overrides to `spec`.
    ///
    /// # Errors
    /// [`RunError::Flag`] naming the flag: a subtask the spec does not have, an unknown
    /// strategy, `--nn-k` on a subtask with random selection, a negative or non-finite noise, an
    /// empty offset range.
    pub fn apply(&self, spec: &mut TaskSpec) -> Result<(), RunError> {
        for s in &self.selection {
            for (_, sub) in scoped(&mut spec.subtasks, "--selection", s.subtask)? {
                let (nn_k, pos_weight, rot_weight) = match sub.selection {
                    SelectionStrategy::Random => (3, 1.0, 1.0),
                    SelectionStrategy::NearestNeighborObject { nn_k, pos_weight, rot_weight }
                    | SelectionStrategy::NearestNeighborRobotDistance { nn_k, pos_weight, rot_weight } => (nn_k, pos_weight, rot_weight),
                };
                sub.selection = match s.value.as_str() {
                    "random" => SelectionStrategy::Random,
                    "nearest_neighbor_object" => SelectionStrategy::NearestNeighborObject { nn_k, pos_weight, rot_weight },
                    "nearest_neighbor_robot_distance" => SelectionStrategy::NearestNeighborRobotDistance { nn_k, pos_weight, rot_weight },
                    other => {
                        return Err(RunError::flag(
                            "--selection",
                            format!("unknown strategy {other:?}; use random, nearest_neighbor_object or nearest_neighbor_robot_distance"),
                        ));
                    }
                };
            }
        }
        for s in &self.nn_k {
            if s.value == 0 {
                return Err(RunError::flag("--nn-k", "must be at least 1"));
            }
            for (k, sub) in scoped(&mut spec.subtasks, "--nn-k", s.subtask)? {
                match &mut sub.selection {
                    SelectionStrategy::Random => {
                        // Applied to all subtasks, it is meant for those that use a neighbour strategy.
                        if s.subtask.is_some() {
                            return Err(RunError::flag(
                                "--nn-k",
                                format!("subtask {k} selects its source at random; set --selection {k}:nearest_neighbor_object first"),
                            ));
                        }
                    }
                    SelectionStrategy::NearestNeighborObject { nn_k, .. }
                    | SelectionStrategy::NearestNeighborRobotDistance { nn_k, .. } => {
                        *nn_k = s.value;
                    }
                }
            }
        }
        for s in &self.action_noise {
            if !s.value.is_finite() || s.value < 0.0 {
                return Err(RunError::flag("--action-noise", format!("must be a finite standard deviation >= 0, got {}", s.value)));
            }
            for (_, sub) in scoped(&mut spec.subtasks, "--action-noise", s.subtask)? {
                sub.action_noise = s.value;
            }
        }
        for s in &self.offset_range {
            let OffsetRange(lo, hi) = s.value;
            if lo > hi {
                return Err(RunError::flag("--offset-range", format!("{lo},{hi} is empty (LO must not exceed HI)")));
            }
            for (_, sub) in scoped(&mut spec.subtasks, "--offset-range", s.subtask)? {
                sub.term_offset_range = Some((lo, hi));
            }
        }
        for s in &self.interpolation_steps {
            for (_, sub) in scoped(&mut spec.subtasks, "--interpolation-steps", s.subtask)? {
                sub.num_interpolation_steps = s.value;
            }
        }
        for s in &self.fixed_steps {
            for (_, sub) in scoped(&mut spec.subtasks, "--fixed-steps", s.subtask)? {
                sub.num_fixed_steps = s.value;
            }
        }
        for s in &self.transit {
            for (k, sub) in scoped(&mut spec.subtasks, "--transit", s.subtask)? {
                if s.value == Transit::Plan && sub.object_ref.is_none() {
                    return Err(RunError::flag("--transit", format!("subtask {k} has no object_ref to approach; plan only the others")));
                }
                sub.transit = s.value;
            }
        }
        for s in &self.approach_m {
            if !s.value.is_finite() || s.value <= 0.0 {
                return Err(RunError::flag("--approach-m", format!("must be a positive distance in metres, got {}", s.value)));
            }
            for (_, sub) in scoped(&mut spec.subtasks, "--approach-m", s.subtask)? {
                sub.approach_m = s.value;
            }
        }
        if let Some(on) = self.select_src_per_subtask {
            spec.generation.select_src_per_subtask = on;
        }
        let excluded = &mut spec.generation.exclude_sources;
        excluded.extend(&self.exclude_source);
        excluded.sort_unstable();
        excluded.dedup();
        Ok(())
    }
}

/// The subtasks a flag scoped to `subtask` sets (every one for `None`), each with its index.
fn scoped<'a>(
    subtasks: &'a mut [SubtaskSpec],
    flag: &str,
    subtask: Option<usize>,
) -> Result<impl Iterator<Item = (usize, &'a mut SubtaskSpec)>, RunError> {
    let count = subtasks.len();
    let (skip, take) = match subtask {
        None => (0, count),
        Some(k) if k < count => (k, 1),
        Some(k) => {
            return Err(RunError::flag(flag, format!("names subtask {k}, but the task has {count} (0 to {})", count.saturating_sub(1))));
        }
    };
    Ok(subtasks.iter_mut().enumerate().skip(skip).take(take))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec() -> TaskSpec {
        TaskSpec::from_toml_str(include_str!("../../sim/tasks/stack.toml"), "stack").unwrap()
    }

    #[test]
    fn scoped_values_parse_and_print_back() {
        let all: Scoped<f64> = "0.02".parse().unwrap();
        assert_eq!(all, Scoped { subtask: None, value: 0.02 });
        let one: Scoped<OffsetRange> = "1:-5,10".parse().unwrap();
        assert_eq!(one, Scoped { subtask: Some(1), value: OffsetRange(-5, 10) });
        assert_eq!(one.to_string(), "1:-5,10");
        let negative: Scoped<OffsetRange> = "-5,10".parse().unwrap();
        assert_eq!(negative.subtask, None);
        assert!("1:abc".parse::<Scoped<f64>>().unwrap_err().contains("abc"));
        assert!("0,".parse::<OffsetRange>().is_err());
    }

    #[test]
    fn overrides_change_the_subtasks_they_name() {
        let mut s = spec();
        let overrides = SpecOverrides {
            selection: vec![Scoped::all("nearest_neighbor_object".to_owned()), Scoped { subtask: Some(1), value: "random".to_owned() }],
            nn_k: vec![Scoped::all(5)],
            action_noise: vec![Scoped::all(0.02), Scoped { subtask: Some(1), value: 0.1 }],
            offset_range: vec![Scoped { subtask: Some(0), value: OffsetRange(0, 10) }],
            interpolation_steps: vec![Scoped::all(7)],
            fixed_steps: vec![Scoped { subtask: Some(1), value: 2 }],
            select_src_per_subtask: Some(true),
            transit: vec![Scoped { subtask: Some(1), value: Transit::Plan }],
            approach_m: vec![Scoped::all(0.08)],
            exclude_source: vec![3, 1],
        };
        overrides.apply(&mut s).unwrap();
        assert_eq!(s.generation.exclude_sources, [1, 3]);
        // Later overrides win where they set a field; exclusions add up.
        let later = SpecOverrides {
            action_noise: vec![Scoped { subtask: Some(1), value: 0.0 }],
            exclude_source: vec![1, 4],
            ..SpecOverrides::default()
        };
        let mut t = spec();
        overrides.then(&later).apply(&mut t).unwrap();
        assert_eq!((t.subtasks[0].action_noise, t.subtasks[1].action_noise), (0.02, 0.0));
        assert_eq!(t.generation.exclude_sources, [1, 3, 4]);
        assert_eq!(s.subtasks.iter().map(|t| t.transit).collect::<Vec<_>>(), [Transit::Interpolate, Transit::Plan]);
        assert_eq!(s.subtasks.iter().map(|t| t.approach_m).collect::<Vec<_>>(), [0.08, 0.08]);
        assert!(matches!(s.subtasks[0].selection, SelectionStrategy::NearestNeighborObject { nn_k: 5, .. }));
        assert_eq!(s.subtasks[1].selection, SelectionStrategy::Random);
        assert_eq!((s.subtasks[0].action_noise, s.subtasks[1].action_noise), (0.02, 0.1));
        assert_eq!(s.subtasks[0].term_offset_range, Some((0, 10)));
        assert_eq!(s.subtasks.iter().map(|t| t.num_interpolation_steps).collect::<Vec<_>>(), [7, 7]);
        assert_eq!(s.subtasks.iter().map(|t| t.num_fixed_steps).collect::<Vec<_>>(), [0, 2]);
        assert!(s.generation.select_src_per_subtask);
        // The flags read back as the same overrides.
        let args = overrides.to_args();
        assert_eq!(args[..4], ["--selection", "nearest_neighbor_object", "--selection", "1:random"]);
        assert!(args.windows(2).any(|w| w == ["--select-src-per-subtask", "true"]));
        assert!(args.windows(2).any(|w| w == ["--transit", "1:plan"]));
        let parsed: Scoped<Transit> = "1:plan".parse().unwrap();
        assert_eq!(parsed, Scoped { subtask: Some(1), value: Transit::Plan });
        assert!("teleport".parse::<Scoped<Transit>>().unwrap_err().contains("interpolate"));
    }

    #[test]
    fn bad_overrides_name_the_flag() {
        let cases = [
            (SpecOverrides { action_noise: vec![Scoped { subtask: Some(7), value: 0.1 }], ..Default::default() }, "--action-noise"),
            (SpecOverrides { selection: vec![Scoped::all("closest".to_owned())], ..Default::default() }, "--selection"),
            (SpecOverrides { action_noise: vec![Scoped::all(f64::NAN)], ..Default::default() }, "--action-noise"),
            (SpecOverrides { offset_range: vec![Scoped::all(OffsetRange(5, 1))], ..Default::default() }, "--offset-range"),
            (SpecOverrides { approach_m: vec![Scoped::all(-0.1)], ..Default::default() }, "--approach-m"),
            (SpecOverrides { transit: vec![Scoped { subtask: Some(2), value: Transit::Plan }], ..Default::default() }, "--transit"),
            (
                SpecOverrides {
                    selection: vec![Scoped::all("random".to_owned())],
                    nn_k: vec![Scoped { subtask: Some(0), value: 4 }],
                    ..Default::default()
                },
                "--nn-k",
            ),
        ];
        for (overrides, flag) in cases {
            let err = overrides.apply(&mut spec()).unwrap_err().to_string();
            assert!(err.contains(flag), "{err}");
        }
    }
}
