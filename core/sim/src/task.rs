//! Tasks: which objects a scene has, how scenes are sampled, subtask-end signals and success.
//! Every task we ship is described as data ([`crate::task_file`]).

use std::collections::BTreeMap;

use mimicgen_engine::EnvError;
use mimicgen_engine::coverage::Dimension;
use mimicgen_engine::demonstrator::PickPlaceScript;
use mimicgen_engine::pose::Pose;
use rand::RngCore;

use crate::compose::{BASE_TABLE_TOP_Z, ObjectModel};
use crate::state::SimState;

/// What a task adds to a robosuite scene.
pub trait Task: Send + Sync {
    /// Task name (`stack`).
    fn name(&self) -> &str;
    /// `(object name, body name)` of every object, in order.
    fn objects(&self) -> Vec<(String, String)>;
    /// The object models our composed scene adds to the base scene, in the same order (the first
    /// instance's where the variant has [`Task::instances`]).
    fn object_models(&self) -> Vec<ObjectModel>;
    /// The object instances the variant draws among, one per episode: `(label, every object's
    /// model)`; empty for a variant without (the same objects every episode).
    fn instances(&self) -> Vec<(String, Vec<ObjectModel>)> {
        Vec::new()
    }
    /// Initial `world_from_object` of every object, in order, for the object instance labelled
    /// `instance` (see [`Task::instances`]; `None` for the variant's own objects).
    ///
    /// # Errors
    /// [`EnvError::Fatal`] if no valid placement is found.
    fn sample_scene(&self, rng: &mut dyn RngCore, instance: Option<&str>) -> Result<Vec<Pose>, EnvError>;
    /// Subtask-end signals in the current state.
    fn signals(&self, env: &SimState) -> BTreeMap<String, i64>;
    /// Whether the task is achieved in the current state.
    fn is_success(&self, env: &SimState) -> bool;
    /// Notes what the task remembers of the episode so far (conditions that must have held at
    /// some earlier step); the environment calls it after every step.
    fn record_history(&self, _env: &mut SimState) {}
    /// The parts of the success condition that do not hold in the current state, in words;
    /// `None` when achieved or when the task cannot say.
    fn unmet_success(&self, _env: &SimState) -> Option<String> {
        None
    }
    /// robosuite's `object` observation for this task in the current state.
    fn object_obs(&self, env: &SimState) -> Vec<f64>;
    /// The scripted demonstrator's pick-and-places, in order (empty if the task has none).
    fn scripts(&self) -> Vec<PickPlaceScript>;
    /// The reset distribution as coverage dimensions: each object's x, y and yaw over its range.
    fn coverage_dimensions(&self) -> Vec<Dimension>;
    /// `(field, joint name)` of every scene joint the task reads; scenes check they have them.
    fn joints_read(&self) -> Vec<(String, String)> {
        Vec::new()
    }
    /// Height of the table top (m), robosuite's `table_offset` z.
    fn table_top_z(&self) -> f64 {
        BASE_TABLE_TOP_Z
    }
    /// How far the robot and the table stand from where the base scene has them (m, x and y):
    /// a task whose world frame is another robosuite arena's (Pick Place's bins arena).
    fn robot_offset_m(&self) -> [f64; 2] {
        [0.0; 2]
    }
    /// The mobile base the arm stands on, if it stands on one.
    fn mobile_base(&self) -> Option<crate::mobile_base::MobileBaseModel> {
        None
    }
    /// Indices of the objects that are obstacles (clutter the robot should not touch).
    fn obstacles(&self) -> Vec<usize> {
        Vec::new()
    }
}
