//! Task specs and generation settings: what to generate and how.
//!
//! Two file formats load into the same types: our TOML (see `TaskSpec::from_toml_str` for an
//! example) and the reference MimicGen's experiment JSON (its `task.task_spec` and
//! `experiment.generation` sections), so existing configs keep working.

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::EngineError;
use crate::pose::PoseDistanceWeights;

/// How the source demo for a subtask is chosen (paper appendix "Reference Segment Selection").
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "strategy", rename_all = "snake_case", deny_unknown_fields)]
pub enum SelectionStrategy {
    /// Uniformly at random.
    Random,
    /// Uniformly among the `nn_k` demos whose reference object pose at the segment start is
    /// closest to the object's pose in the new scene.
    NearestNeighborObject {
        /// How many nearest demos to draw from.
        #[serde(default = "default_nn_k")]
        nn_k: usize,
        /// Weight on position distance (per metre).
        #[serde(default = "one")]
        pos_weight: f64,
        /// Weight on rotation angle (per radian).
        #[serde(default = "one")]
        rot_weight: f64,
    },
    /// Uniformly among the `nn_k` demos whose transformed first end-effector pose is closest to the
    /// robot's current end-effector pose (least travel for the interpolation segment).
    NearestNeighborRobotDistance {
        /// How many nearest demos to draw from.
        #[serde(default = "default_nn_k")]
        nn_k: usize,
        /// Weight on position distance (per metre).
        #[serde(default = "one")]
        pos_weight: f64,
        /// Weight on rotation angle (per radian).
        #[serde(default = "one")]
        rot_weight: f64,
    },
}

fn default_nn_k() -> usize {
    3
}
fn one() -> f64 {
    1.0
}

impl SelectionStrategy {
    /// The strategy's short name, as MimicGen spells it.
    #[must_use]
    pub fn name(&self) -> &'static str {
        match self {
            Self::Random => "random",
            Self::NearestNeighborObject { .. } => "nearest_neighbor_object",
            Self::NearestNeighborRobotDistance { .. } => "nearest_neighbor_robot_distance",
        }
    }

    /// Distance weights of the nearest-neighbour strategies.
    #[must_use]
    pub fn weights(&self) -> PoseDistanceWeights {
        match self {
            Self::Random => PoseDistanceWeights::default(),
            Self::NearestNeighborObject { pos_weight, rot_weight, .. }
            | Self::NearestNeighborRobotDistance { pos_weight, rot_weight, .. } => {
                PoseDistanceWeights { position: *pos_weight, rotation: *rot_weight }
            }
        }
    }
}

/// One object-centric subtask.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SubtaskSpec {
    /// Object whose frame the subtask's motion is relative to (`None` only for a last subtask that
    /// is replayed in the world frame).
    pub object_ref: Option<String>,
    /// Signal whose first 0 -> 1 transition ends the subtask (`None` on the last subtask).
    #[serde(default)]
    pub term_signal: Option<String>,
    /// Inclusive range of steps added to the end boundary, drawn per attempt.
    #[serde(default)]
    pub term_offset_range: Option<(i64, i64)>,
    /// How the source demo for this subtask is chosen.
    #[serde(default = "default_selection")]
    pub selection: SelectionStrategy,
    /// Standard deviation of Gaussian noise on the six pose dimensions of each action.
    #[serde(default = "default_noise")]
    pub action_noise: f64,
    /// Intermediate poses of the interpolation segment.
    #[serde(default = "default_interp")]
    pub num_interpolation_steps: usize,
    /// Steps holding the first pose of the transformed segment after interpolating.
    #[serde(default)]
    pub num_fixed_steps: usize,
    /// Whether the interpolation segment's actions get noise too.
    #[serde(default)]
    pub apply_noise_during_interpolation: bool,
    /// How the robot gets to the segment: MimicGen's interpolation, or a planned collision-free
    /// path (SkillGen) to a segment that starts where the approach to the object begins.
    #[serde(default, skip_serializing_if = "is_default")]
    pub transit: Transit,
    /// With planned transit, the segment starts where the end effector first comes within this
    /// distance (m) of the object: the approach is replayed, the way there is planned.
    #[serde(default = "default_approach", skip_serializing_if = "is_default_approach")]
    pub approach_m: f64,
}

impl SubtaskSpec {
    /// The action noise of the steps that bridge to the segment (interpolated or planned): the
    /// subtask's noise with `apply_noise_during_interpolation`, else none.
    #[must_use]
    pub fn bridge_noise(&self) -> f64 {
        if self.apply_noise_during_interpolation { self.action_noise } else { 0.0 }
    }
}

/// How the robot gets from where it is to the first pose of a subtask's segment.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Transit {
    /// A straight interpolation in pose (MimicGen).
    #[default]
    Interpolate,
    /// A collision-free path planned in joint space ([`crate::transit`]; SkillGen).
    Plan,
}

impl Transit {
    /// The word the CLI and files use.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Interpolate => "interpolate",
            Self::Plan => "plan",
        }
    }
}

impl std::fmt::Display for Transit {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for Transit {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "interpolate" => Ok(Self::Interpolate),
            "plan" => Ok(Self::Plan),
            other => Err(format!("transit is \"interpolate\" or \"plan\", not {other:?}")),
        }
    }
}

fn is_default<T: Default + PartialEq>(value: &T) -> bool {
    *value == T::default()
}
fn default_approach() -> f64 {
    0.1
}
#[allow(clippy::trivially_copy_pass_by_ref)] // serde's skip_serializing_if passes a reference
fn is_default_approach(value: &f64) -> bool {
    (*value - default_approach()).abs() < f64::EPSILON
}

fn default_selection() -> SelectionStrategy {
    SelectionStrategy::Random
}
fn default_noise() -> f64 {
    0.05
}
fn default_interp() -> usize {
    5
}

/// Settings of a generation run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct GenerationSettings {
    /// Attempts to make, or successes to reach when `guarantee` is set.
    pub num_trials: usize,
    /// Keep attempting until `num_trials` successes.
    pub guarantee: bool,
    /// Keep failed attempts (written to a sibling file).
    pub keep_failed: bool,
    /// Stop keeping failed attempts after this many.
    pub max_num_failures: usize,
    /// Hard cap on attempts when `guarantee` is set (0 = 100 x `num_trials`).
    pub max_attempts: usize,
    /// Choose a source demo at each subtask (true) or once per attempt (false).
    pub select_src_per_subtask: bool,
    /// Transform the first robot pose of every segment, not only the first subtask's.
    pub transform_first_robot_pose: bool,
    /// Interpolate from the previous segment's last target pose rather than the current pose.
    pub interpolate_from_last_target_pose: bool,
    /// Run seed: attempt k draws from a stream derived from (seed, k).
    pub seed: u64,
    /// End an attempt as soon as a subtask's segment has run without its end signal turning on,
    /// instead of executing the remaining subtasks first (the reference always runs them all).
    pub early_abort: bool,
    /// The planner of subtasks whose transit is planned.
    #[serde(skip_serializing_if = "is_default")]
    pub planner: crate::transit::PlannerSettings,
}

impl Default for GenerationSettings {
    fn default() -> Self {
        Self {
            num_trials: 10,
            guarantee: false,
            keep_failed: false,
            max_num_failures: 50,
            max_attempts: 0,
            select_src_per_subtask: false,
            transform_first_robot_pose: false,
            interpolate_from_last_target_pose: true,
            seed: 1,
            early_abort: false,
            planner: crate::transit::PlannerSettings::default(),
        }
    }
}

impl GenerationSettings {
    /// The attempt count at which a run stops whatever happened.
    #[must_use]
    pub fn attempt_cap(&self) -> usize {
        match (self.guarantee, self.max_attempts) {
            (false, 0) => self.num_trials,
            (false, cap) => cap.min(self.num_trials),
            (true, 0) => self.num_trials.saturating_mul(100),
            (true, cap) => cap,
        }
    }
}

/// Which source demos to use from a dataset (MimicGen's `experiment.source`).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SourceSelection {
    /// Dataset path as written in the config (may be a placeholder).
    pub dataset_path: Option<String>,
    /// Filter key under `mask/` naming the demos to use.
    pub filter_key: Option<String>,
    /// Use only the first `n` demos (after `start`).
    pub n: Option<usize>,
    /// Skip this many demos first.
    pub start: Option<usize>,
}

/// A task spec: ordered subtasks plus run settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TaskSpec {
    /// Task name (`stack`).
    #[serde(default)]
    pub name: String,
    /// The robosuite environment to generate in, when the spec names one (MimicGen's
    /// `experiment.task.name`, e.g. `Stack_D1`): it selects the task and variant of a run unless
    /// they are given explicitly.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub env_name: Option<String>,
    /// Run settings.
    #[serde(default)]
    pub generation: GenerationSettings,
    /// Source demo selection.
    #[serde(default)]
    pub source: SourceSelection,
    /// The subtasks in order.
    #[serde(rename = "subtask")]
    pub subtasks: Vec<SubtaskSpec>,
}

impl TaskSpec {
    /// Parses our TOML format. `origin` names the file in errors.
    ///
    /// ```
    /// let spec = mimicgen_engine::TaskSpec::from_toml_str(r#"
    /// name = "stack"
    /// [generation]
    /// num_trials = 100
    /// select_src_per_subtask = true
    ///
    /// [[subtask]]
    /// object_ref = "cubeA"
    /// term_signal = "grasp"
    /// term_offset_range = [10, 20]
    /// selection = { strategy = "nearest_neighbor_object", nn_k = 3 }
    ///
    /// [[subtask]]
    /// object_ref = "cubeB"
    /// selection = { strategy = "nearest_neighbor_object", nn_k = 3 }
    /// "#, "stack.toml").unwrap();
    /// assert_eq!(spec.subtasks.len(), 2);
    /// assert_eq!(spec.subtasks[0].action_noise, 0.05);
    /// ```
    ///
    /// # Errors
    /// [`EngineError::Config`] naming the file and the offending field.
    pub fn from_toml_str(text: &str, origin: &str) -> Result<Self, EngineError> {
        let spec: Self = toml::from_str(text).map_err(|e| toml_error(text, origin, &e))?;
        spec.check(origin)?;
        Ok(spec)
    }

    /// Parses the reference MimicGen experiment JSON. `origin` names the file in errors.
    ///
    /// # Errors
    /// [`EngineError::Config`] naming the file and the offending field.
    pub fn from_mimicgen_json_str(text: &str, origin: &str) -> Result<Self, EngineError> {
        let err = |field: &str, reason: String| EngineError::Config { file: origin.to_owned(), field: field.to_owned(), reason };
        let json: MgConfig = serde_json::from_str(text).map_err(|e| err("", e.to_string()))?;
        let mut subtasks: Vec<(usize, String, MgSubtask)> = Vec::new();
        for (key, value) in json.task.task_spec {
            let index = key
                .strip_prefix("subtask_")
                .and_then(|n| n.parse::<usize>().ok())
                .ok_or_else(|| err(&format!("task.task_spec.{key}"), "keys must be subtask_1, subtask_2, ...".to_owned()))?;
            let sub: MgSubtask = serde_json::from_value(value).map_err(|e| err(&format!("task.task_spec.{key}"), e.to_string()))?;
            subtasks.push((index, key, sub));
        }
        subtasks.sort_by_key(|(i, _, _)| *i);
        let mut out = Vec::with_capacity(subtasks.len());
        for (position, (index, key, sub)) in subtasks.into_iter().enumerate() {
            if index != position + 1 {
                return Err(err(
                    &format!("task.task_spec.{key}"),
                    format!("subtask numbering has a gap: expected subtask_{}", position + 1),
                ));
            }
            let nn = |kw: &serde_json::Map<String, serde_json::Value>, k: &str, default: f64| {
                kw.get(k).and_then(serde_json::Value::as_f64).unwrap_or(default)
            };
            let kw = sub.selection_strategy_kwargs.unwrap_or_default();
            let nn_k = kw.get("nn_k").and_then(serde_json::Value::as_u64).map_or(3, |k| usize::try_from(k).unwrap_or(usize::MAX));
            let selection = match sub.selection_strategy.as_str() {
                "random" => SelectionStrategy::Random,
                "nearest_neighbor_object" => SelectionStrategy::NearestNeighborObject {
                    nn_k,
                    pos_weight: nn(&kw, "pos_weight", 1.0),
                    rot_weight: nn(&kw, "rot_weight", 1.0),
                },
                "nearest_neighbor_robot_distance" => SelectionStrategy::NearestNeighborRobotDistance {
                    nn_k,
                    pos_weight: nn(&kw, "pos_weight", 1.0),
                    rot_weight: nn(&kw, "rot_weight", 1.0),
                },
                other => return Err(err(&format!("task.task_spec.{key}.selection_strategy"), format!("unknown strategy {other:?}"))),
            };
            out.push(SubtaskSpec {
                object_ref: sub.object_ref,
                term_signal: sub.subtask_term_signal,
                term_offset_range: sub.subtask_term_offset_range,
                selection,
                action_noise: sub.action_noise,
                num_interpolation_steps: sub.num_interpolation_steps,
                num_fixed_steps: sub.num_fixed_steps,
                apply_noise_during_interpolation: sub.apply_noise_during_interpolation,
                transit: Transit::Interpolate,
                approach_m: default_approach(),
            });
        }
        let g = json.experiment.generation;
        let spec = Self {
            name: json.name.unwrap_or_default(),
            env_name: json.experiment.task.and_then(|t| t.name),
            generation: GenerationSettings {
                num_trials: g.num_trials,
                guarantee: g.guarantee,
                keep_failed: g.keep_failed,
                max_num_failures: json.experiment.max_num_failures.unwrap_or(50),
                max_attempts: 0,
                select_src_per_subtask: g.select_src_per_subtask,
                transform_first_robot_pose: g.transform_first_robot_pose,
                interpolate_from_last_target_pose: g.interpolate_from_last_target_pose,
                seed: json.experiment.seed.unwrap_or(1),
                ..GenerationSettings::default()
            },
            source: json.experiment.source.unwrap_or_default(),
            subtasks: out,
        };
        spec.check(origin)?;
        Ok(spec)
    }

    /// Loads a spec from a `.toml` or `.json` (MimicGen) file.
    ///
    /// # Errors
    /// [`EngineError::Io`] if the file cannot be read, [`EngineError::Config`] if it is invalid.
    pub fn load(path: &Path) -> Result<Self, EngineError> {
        let origin = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|e| EngineError::Io { path: origin.clone(), reason: e.to_string() })?;
        match path.extension().and_then(|e| e.to_str()) {
            Some("json") => Self::from_mimicgen_json_str(&text, &origin),
            Some("toml") => Self::from_toml_str(&text, &origin),
            _ => Err(EngineError::Config {
                file: origin,
                field: String::new(),
                reason: "expected a .toml or a MimicGen .json file".to_owned(),
            }),
        }
    }

    /// Serialises to our TOML format.
    ///
    /// # Errors
    /// [`EngineError::Config`] if a value cannot be written as TOML.
    pub fn to_toml_string(&self) -> Result<String, EngineError> {
        toml::to_string_pretty(self).map_err(|e| EngineError::Config { file: String::new(), field: String::new(), reason: e.to_string() })
    }

    /// Checks the spec on its own: at least one subtask, signals on all but the last, sane numbers.
    ///
    /// # Errors
    /// [`EngineError::Config`] naming `origin` and the field.
    pub fn check(&self, origin: &str) -> Result<(), EngineError> {
        let err = |field: String, reason: String| Err(EngineError::Config { file: origin.to_owned(), field, reason });
        if self.subtasks.is_empty() {
            return err("subtask".to_owned(), "the task has no subtasks".to_owned());
        }
        let last = self.subtasks.len() - 1;
        for (i, s) in self.subtasks.iter().enumerate() {
            let field = |f: &str| format!("subtask[{i}].{f}");
            if i < last && s.term_signal.is_none() && s.term_offset_range.is_some() {
                return err(field("term_signal"), "an offset range needs a term signal".to_owned());
            }
            if i == last && s.term_offset_range.is_some_and(|r| r != (0, 0)) {
                return err(field("term_offset_range"), "the last subtask ends at the end of the demo and takes no offset".to_owned());
            }
            if let Some((lo, hi)) = s.term_offset_range
                && lo > hi
            {
                return err(field("term_offset_range"), format!("[{lo}, {hi}] is empty"));
            }
            if !(s.approach_m.is_finite() && s.approach_m > 0.0) {
                return err(field("approach_m"), format!("{} is not a positive distance", s.approach_m));
            }
            if s.transit == Transit::Plan && s.object_ref.is_none() {
                return err(field("transit"), "planned transit needs an object_ref (the approach is measured from it)".to_owned());
            }
            if !(s.action_noise.is_finite() && s.action_noise >= 0.0) {
                return err(field("action_noise"), format!("{} is not a non-negative number", s.action_noise));
            }
            match &s.selection {
                SelectionStrategy::Random => {}
                SelectionStrategy::NearestNeighborObject { nn_k, pos_weight, rot_weight }
                | SelectionStrategy::NearestNeighborRobotDistance { nn_k, pos_weight, rot_weight } => {
                    if *nn_k == 0 {
                        return err(field("selection.nn_k"), "must be at least 1".to_owned());
                    }
                    if !(pos_weight.is_finite() && rot_weight.is_finite() && *pos_weight >= 0.0 && *rot_weight >= 0.0) {
                        return err(field("selection"), "weights must be non-negative numbers".to_owned());
                    }
                    if matches!(s.selection, SelectionStrategy::NearestNeighborObject { .. }) && s.object_ref.is_none() {
                        return err(field("selection"), "nearest_neighbor_object needs an object_ref".to_owned());
                    }
                }
            }
        }
        Ok(())
    }

    /// Checks the spec against the objects and signals a dataset or environment provides.
    ///
    /// # Errors
    /// [`EngineError::UnknownName`] naming the subtask, the field and the names available.
    pub fn check_names(&self, objects: &[String], signals: &[String]) -> Result<(), EngineError> {
        let last = self.subtasks.len().saturating_sub(1);
        for (i, s) in self.subtasks.iter().enumerate() {
            if let Some(object) = &s.object_ref
                && !objects.contains(object)
            {
                return Err(EngineError::UnknownName {
                    field: format!("subtask[{i}].object_ref"),
                    name: object.clone(),
                    available: objects.to_vec(),
                });
            }
            match &s.term_signal {
                Some(signal) if i < last && !signals.contains(signal) => {
                    return Err(EngineError::UnknownName {
                        field: format!("subtask[{i}].term_signal"),
                        name: signal.clone(),
                        available: signals.to_vec(),
                    });
                }
                _ => {}
            }
        }
        Ok(())
    }
}

/// The 1-based line of field `field` (`subtask[1].object_ref`, as errors name fields) in a spec's
/// text: our TOML (`[[subtask]]` tables) or a MimicGen experiment JSON (`"subtask_2": {...}`).
/// `None` when the text does not spell it out on a line of its own.
#[must_use]
pub fn field_line(text: &str, field: &str) -> Option<usize> {
    let (index, key) = field.strip_prefix("subtask[")?.split_once("].")?;
    let index: usize = index.parse().ok()?;
    let lines = text.lines().enumerate();
    if text.trim_start().starts_with('{') {
        let table = format!("\"subtask_{}\"", index + 1);
        let quoted = format!("\"{key}\"");
        let mut inside = false;
        for (n, line) in lines {
            if line.contains("\"subtask_") {
                inside = line.contains(&table);
            }
            if inside && line.contains(&quoted) {
                return Some(n + 1);
            }
        }
        return None;
    }
    let mut table: Option<usize> = None;
    let mut subtasks = 0;
    for (n, line) in lines {
        let line = line.trim();
        if line.starts_with('[') {
            table = (line.trim_start_matches('[').trim_end_matches(']').trim() == "subtask" && line.starts_with("[[")).then_some(subtasks);
            subtasks += usize::from(table.is_some());
        } else if table == Some(index) && line.split_once('=').is_some_and(|(k, _)| k.trim().trim_matches('"') == key) {
            return Some(n + 1);
        }
    }
    None
}

/// A TOML error as `file:line`, the dotted field (`subtask[1].object_ref`) and the message.
fn toml_error(text: &str, origin: &str, e: &toml::de::Error) -> EngineError {
    let Some(span) = e.span() else {
        return EngineError::Config { file: origin.to_owned(), field: String::new(), reason: e.message().to_owned() };
    };
    let start = span.start.min(text.len());
    let line = text[..start].matches('\n').count() + 1;
    let lines: Vec<&str> = text.lines().take(line).collect();
    let key = lines.last().and_then(|l| l.split_once('=')).map(|(k, _)| k.trim().trim_matches('"').to_owned());
    // The table the line sits in, with its index when it is an array of tables.
    let mut table: Option<String> = None;
    let mut counts: std::collections::BTreeMap<String, usize> = std::collections::BTreeMap::new();
    for l in &lines {
        let l = l.trim();
        if let Some(name) = l.strip_prefix("[[").and_then(|r| r.strip_suffix("]]")) {
            let n = counts.entry(name.trim().to_owned()).or_insert(0);
            table = Some(format!("{}[{n}]", name.trim()));
            *n += 1;
        } else if let Some(name) = l.strip_prefix('[').and_then(|r| r.strip_suffix(']')) {
            table = Some(name.trim().to_owned());
        }
    }
    let field = match (table, key) {
        (Some(t), Some(k)) => format!("{t}.{k}"),
        (Some(t), None) => t,
        (None, Some(k)) => k,
        (None, None) => String::new(),
    };
    EngineError::Config { file: format!("{origin}:{line}"), field, reason: e.message().trim().to_owned() }
}

#[derive(Deserialize)]
struct MgConfig {
    name: Option<String>,
    experiment: MgExperiment,
    task: MgTask,
}

#[derive(Deserialize)]
struct MgExperiment {
    source: Option<SourceSelection>,
    task: Option<MgExperimentTask>,
    generation: MgGeneration,
    max_num_failures: Option<usize>,
    seed: Option<u64>,
}

#[derive(Deserialize)]
struct MgGeneration {
    #[serde(default)]
    guarantee: bool,
    #[serde(default)]
    keep_failed: bool,
    num_trials: usize,
    #[serde(default)]
    select_src_per_subtask: bool,
    #[serde(default)]
    transform_first_robot_pose: bool,
    #[serde(default)]
    interpolate_from_last_target_pose: bool,
}

#[derive(Deserialize)]
struct MgExperimentTask {
    name: Option<String>,
}

#[derive(Deserialize)]
struct MgTask {
    task_spec: serde_json::Map<String, serde_json::Value>,
}

#[derive(Deserialize)]
struct MgSubtask {
    object_ref: Option<String>,
    subtask_term_signal: Option<String>,
    subtask_term_offset_range: Option<(i64, i64)>,
    selection_strategy: String,
    selection_strategy_kwargs: Option<serde_json::Map<String, serde_json::Value>>,
    action_noise: f64,
    num_interpolation_steps: usize,
    num_fixed_steps: usize,
    apply_noise_during_interpolation: bool,
}

#[cfg(test)]
mod tests {
    use super::*;

    const CONFIG_D0: &str = include_str!("../tests/data/config_D0.json");

    #[test]
    fn parses_the_reference_stack_config() {
        let spec = TaskSpec::from_mimicgen_json_str(CONFIG_D0, "config_D0.json").unwrap();
        assert_eq!(spec.name, "stack");
        assert_eq!(spec.subtasks.len(), 2);
        let grasp = &spec.subtasks[0];
        assert_eq!(grasp.object_ref.as_deref(), Some("cubeA"));
        assert_eq!(grasp.term_signal.as_deref(), Some("grasp"));
        assert_eq!(grasp.term_offset_range, Some((10, 20)));
        assert_eq!(grasp.selection, SelectionStrategy::NearestNeighborObject { nn_k: 3, pos_weight: 1.0, rot_weight: 1.0 });
        assert!((grasp.action_noise - 0.05).abs() < 1e-12);
        assert_eq!(grasp.num_interpolation_steps, 5);
        assert_eq!(spec.subtasks[1].object_ref.as_deref(), Some("cubeB"));
        assert_eq!(spec.subtasks[1].term_signal, None);
        let g = &spec.generation;
        assert_eq!((g.num_trials, g.guarantee, g.keep_failed, g.max_num_failures, g.seed), (50, false, true, 25, 1));
        assert!(g.select_src_per_subtask && !g.transform_first_robot_pose && g.interpolate_from_last_target_pose);
        assert_eq!(spec.source.n, Some(10));
    }

    #[test]
    fn toml_round_trips() {
        let spec = TaskSpec::from_mimicgen_json_str(CONFIG_D0, "config_D0.json").unwrap();
        let text = spec.to_toml_string().unwrap();
        assert_eq!(TaskSpec::from_toml_str(&text, "x.toml").unwrap(), spec);
    }

    #[test]
    fn toml_type_errors_name_the_line_and_field() {
        let text = "name = \"stack\"\n\n[[subtask]]\nobject_ref = \"cubeA\"\nterm_signal = \"grasp\"\n\n[[subtask]]\nobject_ref = 3\n";
        let err = TaskSpec::from_toml_str(text, "my.toml").unwrap_err().to_string();
        assert!(err.contains("my.toml:8") && err.contains("subtask[1].object_ref") && err.contains("string"), "{err}");
        let err = TaskSpec::from_toml_str("[generation]\nseed = \"x\"\n[[subtask]]\n", "g.toml").unwrap_err().to_string();
        assert!(err.contains("g.toml:2") && err.contains("generation.seed"), "{err}");
    }

    #[test]
    fn bad_configs_name_file_and_field() {
        let bad = CONFIG_D0.replace("\"nearest_neighbor_object\"", "\"nearest_banana\"");
        let err = TaskSpec::from_mimicgen_json_str(&bad, "cfg.json").unwrap_err().to_string();
        assert!(err.contains("cfg.json") && err.contains("subtask_1.selection_strategy") && err.contains("nearest_banana"), "{err}");

        let err = TaskSpec::from_toml_str("[[subtask]]\nobject_ref = \"a\"\nactoin_noise = 0.1\n", "s.toml").unwrap_err().to_string();
        assert!(err.contains("s.toml") && err.contains("actoin_noise"), "{err}");

        let err = TaskSpec::from_toml_str(
            "[[subtask]]\nobject_ref = \"a\"\nterm_signal = \"g\"\nterm_offset_range = [5, 1]\n[[subtask]]\nobject_ref = \"b\"\n",
            "s.toml",
        )
        .unwrap_err()
        .to_string();
        assert!(err.contains("subtask[0].term_offset_range"), "{err}");

        let spec = TaskSpec::from_mimicgen_json_str(CONFIG_D0, "config_D0.json").unwrap();
        let err = spec.check_names(&["cubeA".into(), "cubeC".into()], &["grasp".into()]).unwrap_err().to_string();
        assert!(err.contains("subtask[1].object_ref") && err.contains("cubeB") && err.contains("cubeC"), "{err}");
        let err = spec.check_names(&["cubeA".into(), "cubeB".into()], &["touch".into()]).unwrap_err().to_string();
        assert!(err.contains("subtask[0].term_signal") && err.contains("grasp"), "{err}");
    }

    #[test]
    fn a_field_is_found_on_its_line_in_toml_and_json() {
        let toml = "name = \"stack\"\n[generation]\nseed = 1\n\n[[subtask]]\nobject_ref = \"cubeA\"\n\n[[subtask]]\nselection = { strategy = \"random\" }\nobject_ref = \"nope\"\n";
        assert_eq!(field_line(toml, "subtask[0].object_ref"), Some(6));
        assert_eq!(field_line(toml, "subtask[1].object_ref"), Some(10));
        assert_eq!(field_line(toml, "subtask[1].term_signal"), None);
        assert_eq!(field_line(toml, "subtask[2].object_ref"), None);
        assert_eq!(field_line(toml, "generation.seed"), None);
        let json = "{\n  \"task\": {\"task_spec\": {\n    \"subtask_1\": {\n      \"object_ref\": \"cubeA\"\n    },\n    \"subtask_2\": {\n      \"object_ref\": \"nope\"\n    }\n  }}\n}\n";
        assert_eq!(field_line(json, "subtask[0].object_ref"), Some(4));
        assert_eq!(field_line(json, "subtask[1].object_ref"), Some(7));
        assert_eq!(field_line(json, "subtask[2].object_ref"), None);
        assert_eq!(field_line(&json.replace("\"object_ref\": \"cubeA\"", "\"nn_k\": 3"), "subtask[0].object_ref"), None);
    }
}
