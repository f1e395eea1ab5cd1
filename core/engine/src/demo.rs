//! Source demonstrations: what MimicGen's `datagen_info` holds per step, plus the opaque pieces a
//! simulator needs to write the demo back out.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use crate::EngineError;
use crate::pose::{Pose, check_finite};

/// A hand-made annotation of some demos, by demo name: what the app and `mimicgen annotate` mark,
/// used in place of what the file's signals and the approach detector give.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct SubtaskMarks {
    /// Subtask ends (exclusive, one per subtask but the last).
    pub ends: BTreeMap<String, Vec<usize>>,
    /// Segment starts (one per subtask, `None` where unmarked; see
    /// [`SourceDemo::manual_subtask_starts`]).
    #[serde(default)]
    pub starts: BTreeMap<String, Vec<Option<usize>>>,
}

/// A row-major 2-D array of `f64` with a fixed row width (actions, flattened states, gripper actions).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Rows {
    width: usize,
    data: Vec<f64>,
}

impl Rows {
    /// An empty array whose rows will have `width` values.
    #[must_use]
    pub fn new(width: usize) -> Self {
        Self { width, data: Vec::new() }
    }

    /// Wraps row-major `data`; `what` names the field in the error.
    ///
    /// # Errors
    /// [`EngineError::Shape`] when `data.len()` is not a multiple of `width`.
    pub fn from_vec(width: usize, data: Vec<f64>, what: &str) -> Result<Self, EngineError> {
        if width == 0 && !data.is_empty() || width != 0 && !data.len().is_multiple_of(width) {
            return Err(EngineError::Shape {
                what: what.to_owned(),
                reason: format!("{} values do not split into rows of {width}", data.len()),
            });
        }
        Ok(Self { width, data })
    }

    /// Values per row.
    #[must_use]
    pub fn width(&self) -> usize {
        self.width
    }

    /// Number of rows.
    #[must_use]
    pub fn len(&self) -> usize {
        self.data.len().checked_div(self.width).unwrap_or(0)
    }

    /// True when there are no rows.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Row `i`. Panics if `i >= len()`, like slice indexing ([`Self::get`] does not).
    #[must_use]
    #[allow(clippy::indexing_slicing, reason = "documented to panic past len(), as slice indexing does")]
    pub fn row(&self, i: usize) -> &[f64] {
        &self.data[i * self.width..(i + 1) * self.width]
    }

    /// Row `i`, `None` past `len()`.
    #[must_use]
    pub fn get(&self, i: usize) -> Option<&[f64]> {
        self.data.get(i * self.width..(i + 1) * self.width).filter(|_| i < self.len())
    }

    /// Appends a row; its length must equal `width()`.
    ///
    /// # Errors
    /// [`EngineError::Shape`] on a row of the wrong width.
    pub fn push(&mut self, row: &[f64]) -> Result<(), EngineError> {
        if row.len() != self.width {
            return Err(EngineError::Shape {
                what: "row".to_owned(),
                reason: format!("has {} values, expected {}", row.len(), self.width),
            });
        }
        self.data.extend_from_slice(row);
        Ok(())
    }

    /// All values, row-major.
    #[must_use]
    pub fn as_slice(&self) -> &[f64] {
        &self.data
    }

    /// Iterates over rows.
    pub fn iter(&self) -> impl ExactSizeIterator<Item = &[f64]> + '_ {
        (0..self.len()).map(move |i| self.get(i).unwrap_or_default())
    }

    /// Rows `start..end` as a new array. Panics past `len()`, like slice indexing.
    #[must_use]
    #[allow(clippy::indexing_slicing, reason = "documented to panic past len(), as slice indexing does")]
    pub fn slice(&self, start: usize, end: usize) -> Self {
        Self { width: self.width, data: self.data[start * self.width..end * self.width].to_vec() }
    }
}

/// Every object's pose at the first step of a recording (`object_poses` of a [`SourceDemo`] or a
/// generated trajectory): the scene an episode started in.
#[must_use]
pub fn initial_object_poses(object_poses: &BTreeMap<String, Vec<Pose>>) -> BTreeMap<String, Pose> {
    object_poses.iter().filter_map(|(name, poses)| poses.first().map(|p| (name.clone(), *p))).collect()
}

/// What a simulator needs to replay or rewrite a demo; the engine reads only the mobile base's
/// part of the actions ([`crate::base`]).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct SimPayload {
    /// The actions as recorded, `(T, action_dim)`.
    pub actions: Rows,
    /// Flattened simulator states recorded before each action, `(T, state_dim)`.
    pub states: Rows,
    /// The scene description the demo was recorded in (robosuite's `model_file` XML), if known.
    pub model_xml: Option<String>,
}

/// One source demonstration, step-aligned: index `t` of every field describes the same step.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct SourceDemo {
    /// Name in the dataset (`demo_3`).
    pub name: String,
    /// End-effector pose `world_from_eef` before each action.
    pub eef_poses: Vec<Pose>,
    /// Controller target pose `world_from_target` implied by each action.
    pub target_poses: Vec<Pose>,
    /// Gripper part of each action, `(T, gripper_dim)`.
    pub gripper_actions: Rows,
    /// `world_from_object` per object name, per step.
    pub object_poses: BTreeMap<String, Vec<Pose>>,
    /// Subtask-end signals per name, per step (nonzero = on).
    pub subtask_term_signals: BTreeMap<String, Vec<i64>>,
    /// Hand-annotated end step of every subtask but the last; overrides the signals when set.
    pub manual_subtask_ends: Option<Vec<usize>>,
    /// Hand-marked start of each subtask's segment (`None` for a subtask without one): where
    /// the approach to its object begins, replacing the detected one for a subtask whose transit
    /// is planned (see [`crate::segment::Segmentation::approach_starts`]).
    pub manual_subtask_starts: Option<Vec<Option<usize>>>,
    /// Opaque simulator data.
    pub sim: SimPayload,
}

impl SourceDemo {
    /// Number of steps.
    #[must_use]
    pub fn len(&self) -> usize {
        self.eef_poses.len()
    }

    /// True when the demo has no steps.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.eef_poses.is_empty()
    }

    /// Checks that every per-step field has the same length and every pose is finite.
    ///
    /// # Errors
    /// [`EngineError::Shape`] or [`EngineError::InvalidPose`] naming the demo and field.
    pub fn validate(&self) -> Result<(), EngineError> {
        let n = self.len();
        if n == 0 {
            return Err(EngineError::Shape { what: format!("{}/eef_pose", self.name), reason: "demo has no steps".to_owned() });
        }
        let mut lengths: Vec<(String, usize)> =
            vec![("target_pose".to_owned(), self.target_poses.len()), ("gripper_action".to_owned(), self.gripper_actions.len())];
        lengths.extend(self.object_poses.iter().map(|(k, v)| (format!("object_poses/{k}"), v.len())));
        lengths.extend(self.subtask_term_signals.iter().map(|(k, v)| (format!("subtask_term_signals/{k}"), v.len())));
        if !self.sim.actions.is_empty() {
            lengths.push(("actions".to_owned(), self.sim.actions.len()));
        }
        if !self.sim.states.is_empty() {
            lengths.push(("states".to_owned(), self.sim.states.len()));
        }
        for (field, len) in lengths {
            if len != n {
                return Err(EngineError::Shape {
                    what: format!("{}/{field}", self.name),
                    reason: format!("has {len} steps but eef_pose has {n}"),
                });
            }
        }
        let poses = self.eef_poses.iter().map(|p| ("eef_pose", p)).chain(self.target_poses.iter().map(|p| ("target_pose", p)));
        for (i, (field, pose)) in poses.enumerate() {
            check_finite(pose, &format!("{}/{field}[{}]", self.name, i % n))?;
        }
        for (name, poses) in &self.object_poses {
            for (t, pose) in poses.iter().enumerate() {
                check_finite(pose, &format!("{}/object_poses/{name}[{t}]", self.name))?;
            }
        }
        let rows = [("gripper_action", &self.gripper_actions), ("actions", &self.sim.actions), ("states", &self.sim.states)];
        for (field, rows) in rows {
            if let Some((t, _)) = rows.iter().enumerate().find(|(_, row)| row.iter().any(|v| !v.is_finite())) {
                return Err(EngineError::NonFinite { what: format!("{}/{field}[{t}]", self.name) });
            }
        }
        Ok(())
    }
}

/// A set of source demonstrations of one task, with what the simulator needs to run it again.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct SourceDataset {
    /// The demos, in dataset order (source-demo indices refer to this order).
    pub demos: Vec<SourceDemo>,
    /// Environment metadata as the dataset stores it (robomimic's `env_args` JSON), if any.
    pub env_args: Option<String>,
}

impl SourceDataset {
    /// Object names present in every demo, sorted.
    #[must_use]
    pub fn object_names(&self) -> Vec<String> {
        common_keys(self.demos.iter().map(|d| d.object_poses.keys()))
    }

    /// Signal names present in every demo, sorted.
    #[must_use]
    pub fn signal_names(&self) -> Vec<String> {
        common_keys(self.demos.iter().map(|d| d.subtask_term_signals.keys()))
    }

    /// Validates every demo.
    ///
    /// # Errors
    /// The first demo's validation error, or [`EngineError::Shape`] for an empty dataset.
    pub fn validate(&self) -> Result<(), EngineError> {
        if self.demos.is_empty() {
            return Err(EngineError::Shape { what: "source dataset".to_owned(), reason: "holds no demos".to_owned() });
        }
        self.demos.iter().try_for_each(SourceDemo::validate)
    }
}

fn common_keys<'a, I, K>(mut sets: I) -> Vec<String>
where
    I: Iterator<Item = K>,
    K: Iterator<Item = &'a String>,
{
    let Some(first) = sets.next() else { return Vec::new() };
    let mut common: Vec<String> = first.cloned().collect();
    for keys in sets {
        let keys: Vec<&String> = keys.collect();
        common.retain(|k| keys.contains(&k));
    }
    common
}
