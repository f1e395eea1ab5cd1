//! Task specs and generation settings: what to generate and how.
//!
//! Two file formats load into the same types: our TOML (see `TaskSpec::from_toml_str` for an
//! example) and the reference MimicGen's experiment JSON (its `task.task_spec` and
//! `experiment.generation` sections), so existing configs keep working.
//!
//! About 500 lines with its tests (the reference's JSON is read in `spec/mimicgen_json.rs`, field
//! lines found in `spec/text.rs`).

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::EngineError;
use crate::pose::PoseDistanceWeights;

mod mimicgen_json;
mod text;

pub use text::field_line;
pub(crate) use text::toml_error;

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
    /// The object whose pose `nearest_neighbor_object` measures to pick the source demo, when not
    /// `object_ref`: with one source demo per attempt (`select_src_per_subtask = false`), the
    /// first subtask may pick it by an object a later subtask handles (Two Arm Transport picks
    /// arm 0's demo, lid first, by the hammer that lies in the bin either face up).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub selection_object: Option<String>,
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
    /// Source demos (indices in the source dataset, as the report counts them) that no selection
    /// picks: demos that never lead to a success (`mimicgen doctor` proposes them). The others
    /// keep their indices, so reports of runs with and without it read alike.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub exclude_sources: Vec<usize>,
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
            exclude_sources: Vec::new(),
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
                    if matches!(s.selection, SelectionStrategy::NearestNeighborObject { .. })
                        && s.object_ref.is_none()
                        && s.selection_object.is_none()
                    {
                        return err(field("selection"), "nearest_neighbor_object needs an object_ref or a selection_object".to_owned());
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
            for (name, object) in [("object_ref", &s.object_ref), ("selection_object", &s.selection_object)] {
                if let Some(object) = object
                    && !objects.contains(object)
                {
                    return Err(EngineError::UnknownName {
                        field: format!("subtask[{i}].{name}"),
                        name: object.clone(),
                        available: objects.to_vec(),
                    });
                }
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
