//! MuJoCo environments that behave like robosuite 1.4.1, for the MimicGen engine.
//!
//! What it does: loads robosuite scenes (a dataset's `model_file`, with asset paths re-pointed at
//! the local robosuite assets), drives the Panda with robosuite's OSC_POSE controller at 20 Hz over
//! 2 ms physics steps, and implements [`mimicgen_engine::Environment`] for tasks ([`task`]).
//! Two-arm tasks ([`two_arm`]) drive both arms of robosuite's own two-arm scenes.
//! Camera observations are rendered offscreen with MuJoCo's renderer ([`camera`]).
//! What it does not do: file formats (see `mimicgen-io`).
//!
//! This is the only crate that links libmujoco (set up by `scripts/setup.sh`).

pub mod assets;
pub mod camera;
pub mod compose;
pub mod data_task;
pub mod env;
pub mod geometry;
pub mod joint_control;
pub mod legacy_contacts;
pub mod mjcf_edit;
pub mod mobile_base;
pub mod model_cache;
mod offscreen;
pub mod osc;
pub mod registry;
pub mod robot;
pub mod scene;
pub mod state;
pub mod task;
pub mod task_file;
pub mod transit;
pub mod two_arm;

pub use data_task::DataTask;
pub use env::SimEnv;
pub use geometry::{GeomPoser, Part, Shape, VisibleGeom};
pub use scene::{ConvexCollider, Scene};
pub use state::SimState;
pub use task::Task;
pub use task_file::TaskFile;

/// Everything that can go wrong building or running a simulation.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum SimError {
    /// robosuite's assets are not where they should be.
    #[error("{path}: {reason}")]
    Assets {
        /// The directory looked at.
        path: String,
        /// What to do about it.
        reason: String,
    },
    /// MuJoCo could not compile the scene.
    #[error("MuJoCo cannot compile the scene from {file}: {reason}")]
    Compile {
        /// Where the XML came from.
        file: String,
        /// MuJoCo's message.
        reason: String,
    },
    /// A recorded state does not fit the scene.
    #[error("a state for the scene from {file}: {reason}")]
    State {
        /// Where the scene's XML came from.
        file: String,
        /// What does not fit.
        reason: String,
    },
    /// Offscreen rendering failed (no EGL, a bad camera size).
    #[error("rendering the scene from {file}: {reason}")]
    Render {
        /// Where the scene came from.
        file: String,
        /// What failed and what to do about it.
        reason: String,
    },
    /// A name the task or robot needs is not in the model.
    #[error("the scene from {file} has no {kind} named {name:?}")]
    MissingName {
        /// Where the XML came from.
        file: String,
        /// joint, actuator, site, body or geom.
        kind: String,
        /// The missing name.
        name: String,
    },
    /// A task reads a joint (a `joint` predicate or observation term) that its scene lacks.
    #[error("task {task:?} ({task}.task.toml): `{field}` reads joint {joint:?}, which the scene from {file} does not have")]
    TaskJoint {
        /// The task's name.
        task: String,
        /// The task file's field that names it (`success`, `signals.<name>`, `observation`).
        field: String,
        /// The joint's name.
        joint: String,
        /// Where the scene's XML came from.
        file: String,
    },
}

impl SimError {
    /// True when the user's input (a scene file) is at fault rather than the installation.
    #[must_use]
    pub fn is_user_error(&self) -> bool {
        !matches!(self, Self::Assets { .. } | Self::Render { .. })
    }
}
