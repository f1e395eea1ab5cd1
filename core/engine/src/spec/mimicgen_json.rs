//! The reference's MimicGen experiment JSON (`config_D0.json`) read into a [`TaskSpec`].

use serde::Deserialize;

use super::{GenerationSettings, SelectionStrategy, SourceSelection, SubtaskSpec, TaskSpec, Transit, default_approach};
use crate::EngineError;

impl TaskSpec {
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
                selection_object: None,
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
