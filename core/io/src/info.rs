//! A summary of a dataset: sizes, lengths, observation and action shapes, environment, objects,
//! subtask signals and filter keys (what `mimicgen info` prints).

use std::collections::BTreeMap;

use serde::Serialize;

use crate::dataset::{DatasetReport, DemoSource, demo_steps};
use crate::error::Result;
use crate::tree::{Array, Node};

/// Minimum, mean, standard deviation (population) and maximum of a set of numbers.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct Summary {
    /// How many numbers.
    pub count: usize,
    /// Smallest.
    pub min: f64,
    /// Mean.
    pub mean: f64,
    /// Population standard deviation.
    pub std: f64,
    /// Largest.
    pub max: f64,
}

impl Summary {
    /// Summarises `values` (all zeros when empty).
    #[must_use]
    #[allow(clippy::cast_precision_loss)] // counts far below 2^53
    pub fn of(values: &[f64]) -> Self {
        if values.is_empty() {
            return Self::default();
        }
        let n = values.len() as f64;
        let mean = values.iter().sum::<f64>() / n;
        let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n;
        Self {
            count: values.len(),
            min: values.iter().copied().fold(f64::INFINITY, f64::min),
            mean,
            std: var.sqrt(),
            max: values.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        }
    }
}

/// Where a subtask signal first switches on (its first 0 -> 1 transition) across demos.
#[derive(Debug, Clone, PartialEq, Default, Serialize)]
pub struct SignalInfo {
    /// Demos that have the signal.
    pub demos: usize,
    /// Demos where it never switches on (MimicGen cannot segment those).
    pub never_on: Vec<String>,
    /// Step of the first 0 -> 1 transition over the demos where there is one.
    pub first_on_step: Summary,
}

/// Everything `mimicgen info` reports.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DatasetInfo {
    /// The file.
    pub file: String,
    /// Number of demos.
    pub num_demos: usize,
    /// Total steps over all demos.
    pub num_samples: usize,
    /// The `data` attribute `total`, when present.
    pub total_attr: Option<i64>,
    /// Demo lengths.
    pub lengths: Summary,
    /// Observation keys with their per-step shapes (from the first demo that has them).
    pub obs: BTreeMap<String, Vec<usize>>,
    /// Observation keys with their element type (`float64`, `uint8` for camera images).
    pub obs_dtypes: BTreeMap<String, String>,
    /// Values per action.
    pub action_dim: usize,
    /// Per-dimension minimum of the actions.
    pub action_min: Vec<f64>,
    /// Per-dimension maximum of the actions.
    pub action_max: Vec<f64>,
    /// `env_args.env_name`.
    pub env_name: Option<String>,
    /// The controller type from `env_args.env_kwargs.controller_configs` (robosuite 1.4 or 1.5 layout).
    pub controller_type: Option<String>,
    /// Object names under `datagen_info/object_poses` (in any demo).
    pub objects: Vec<String>,
    /// Subtask signals under `datagen_info/subtask_term_signals`.
    pub signals: BTreeMap<String, SignalInfo>,
    /// Filter keys under `mask/` with their demo counts.
    pub filter_keys: BTreeMap<String, usize>,
    /// What MimicGen needs and does not find.
    pub report: DatasetReport,
}

impl DatasetInfo {
    /// Summarises a dataset.
    ///
    /// # Errors
    /// [`crate::IoError::Invalid`] when a mask is malformed; read errors of [`DemoSource::load_demo`].
    #[allow(clippy::cast_precision_loss)] // step counts far below 2^53
    pub fn of(ds: &impl DemoSource) -> Result<Self> {
        let mut lengths = Vec::new();
        let mut obs = BTreeMap::new();
        let mut obs_dtypes = BTreeMap::new();
        let (mut action_min, mut action_max): (Vec<f64>, Vec<f64>) = (Vec::new(), Vec::new());
        let mut objects = std::collections::BTreeSet::new();
        let mut first_on: BTreeMap<String, (usize, Vec<String>, Vec<f64>)> = BTreeMap::new();
        let mut report = DatasetReport { file: ds.file().to_owned(), ..DatasetReport::default() };
        for name in ds.demo_names() {
            let demo = ds.load_demo(name)?;
            let demo: &crate::tree::Group = &demo;
            report.add_demo(name, demo);
            lengths.push(demo_steps(demo) as f64);
            if let Some(o) = demo.group("obs") {
                for (key, node) in &o.members {
                    if let Node::Dataset(d) = node {
                        obs.entry(key.clone()).or_insert_with(|| d.array.shape.get(1..).unwrap_or_default().to_vec());
                        obs_dtypes.entry(key.clone()).or_insert_with(|| d.array.values.dtype_name());
                    }
                }
            }
            if let Some(a) = demo.dataset("actions")
                && let (Some(values), Some(&width)) = (a.array.values.to_f64(), a.array.shape.get(1))
                && width > 0
            {
                if action_min.is_empty() {
                    action_min = vec![f64::INFINITY; width];
                    action_max = vec![f64::NEG_INFINITY; width];
                }
                for row in values.chunks_exact(width) {
                    for ((lo, hi), v) in action_min.iter_mut().zip(action_max.iter_mut()).zip(row) {
                        *lo = lo.min(*v);
                        *hi = hi.max(*v);
                    }
                }
            }
            let Some(info) = demo.group("datagen_info") else { continue };
            if let Some(o) = info.group("object_poses") {
                objects.extend(o.members.keys().cloned());
            }
            if let Some(s) = info.group("subtask_term_signals") {
                for (sig, node) in &s.members {
                    let Node::Dataset(d) = node else { continue };
                    let entry = first_on.entry(sig.clone()).or_default();
                    entry.0 += 1;
                    match d.array.values.to_i64().as_deref().and_then(first_transition) {
                        Some(t) => entry.2.push(t as f64),
                        None => entry.1.push(name.clone()),
                    }
                }
            }
        }
        let env: Option<serde_json::Value> = ds.env_args_json().and_then(|s| serde_json::from_str(s).ok());
        let env_name = env.as_ref().and_then(|e| e.get("env_name")).and_then(|v| v.as_str()).map(str::to_owned);
        let controller_type = env
            .as_ref()
            .and_then(|e| e.pointer("/env_kwargs/controller_configs"))
            .and_then(|c| c.get("type").or_else(|| c.pointer("/body_parts/right/type")).and_then(|v| v.as_str()).map(str::to_owned));
        Ok(Self {
            file: ds.file().to_owned(),
            num_demos: ds.demo_names().len(),
            #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
            num_samples: lengths.iter().sum::<f64>() as usize,
            total_attr: ds.data_attrs().get("total").and_then(Array::as_i64),
            lengths: Summary::of(&lengths),
            obs,
            obs_dtypes,
            action_dim: action_min.len(),
            action_min,
            action_max,
            env_name,
            controller_type,
            objects: objects.into_iter().collect(),
            signals: first_on
                .into_iter()
                .map(|(k, (demos, never_on, steps))| (k, SignalInfo { demos, never_on, first_on_step: Summary::of(&steps) }))
                .collect(),
            filter_keys: ds.filter_keys()?.into_iter().map(|(k, v)| (k, v.len())).collect(),
            report,
        })
    }
}

/// First step `t >= 1` where the signal goes from 0 to nonzero, as MimicGen's segmentation reads it.
#[must_use]
pub fn first_transition(signal: &[i64]) -> Option<usize> {
    mimicgen_engine::segment::first_rising_edge(signal, 0)
}
