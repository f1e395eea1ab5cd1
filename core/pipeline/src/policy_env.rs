//! Our simulator as an environment a learner drives: the scenes a run generates in, reset from a
//! seeded random stream, stepped with a policy's actions, observed with the keys and shapes the
//! run's datasets hold. The Python package's `mimicgen_rs.Env` (and through it robomimic's
//! rollouts and the gymnasium wrapper) is this type.

use std::collections::BTreeMap;

use mimicgen_engine::Environment as _;
use mimicgen_engine::image::ImageStream;
use mimicgen_sim::SimEnv;
use mimicgen_sim::camera::Cameras;
use rand::SeedableRng as _;
use rand_chacha::ChaCha8Rng;

use crate::{Pipeline, PipelineError, RunConfig};

/// An environment of one task and variant (and arm, and cameras) for policy rollouts.
pub struct PolicyEnv {
    env: SimEnv,
    rng: ChaCha8Rng,
    cameras: Option<Cameras>,
    env_args: String,
    label: String,
}

impl std::fmt::Debug for PolicyEnv {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PolicyEnv").field("env", &self.label).finish_non_exhaustive()
    }
}

impl PolicyEnv {
    /// The environment `config` would generate in (its task, variant, arm and cameras; the rest
    /// of the run's settings do not matter), its resets drawn from `seed`: the same seed gives
    /// the same scenes, episode after episode.
    ///
    /// # Errors
    /// As [`Pipeline::prepare`]: an unknown task, variant or arm, unreadable source demos, a
    /// scene that does not compile; a two-arm task (not served yet).
    pub fn new(config: &RunConfig, seed: u64) -> Result<Self, PipelineError> {
        if let Some(task) = config.task.as_deref()
            && mimicgen_sim::two_arm::TwoArmTask::from_name(task).is_some()
        {
            return Err(PipelineError::input(
                "",
                "task",
                format!("{task} is a two-arm task; environments for policies serve the single-arm tasks"),
            ));
        }
        let pipeline = Pipeline::prepare(config)?;
        let label = format!("{} {}", pipeline.task().name(), pipeline.variant());
        Ok(Self {
            env: pipeline.env(),
            rng: ChaCha8Rng::seed_from_u64(seed),
            cameras: config.cameras.clone().map(|c| Cameras::new(pipeline.scene(), c)).transpose()?,
            env_args: pipeline.env_args().to_owned(),
            label,
        })
    }

    /// The `env_args` (robomimic's environment metadata, JSON) of the datasets generated in this
    /// environment.
    #[must_use]
    pub fn env_args(&self) -> &str {
        &self.env_args
    }

    /// Width of an action: pose (6), gripper, and the base's three where the arm has one.
    #[must_use]
    pub fn action_dim(&self) -> usize {
        self.env.action_dim()
    }

    /// Restarts the environment's random stream from `seed` (gymnasium's `reset(seed=...)`).
    pub fn reseed(&mut self, seed: u64) {
        self.rng = ChaCha8Rng::seed_from_u64(seed);
    }

    /// A new episode: objects (and, under object transfer, which objects) and the arm's noise
    /// drawn from the environment's random stream.
    ///
    /// # Errors
    /// [`PipelineError::Engine`] when no scene could be drawn (a task's placement gave up).
    pub fn reset(&mut self) -> Result<(), PipelineError> {
        let label = &self.label;
        self.env.reset(&mut self.rng).map_err(|e| sim_error(label, &e))
    }

    /// Restores a flattened robosuite state (a dataset's `states` row), as robomimic's
    /// `reset_to` does.
    ///
    /// # Errors
    /// [`PipelineError::Input`] naming `state` when its length is not this scene's.
    pub fn reset_to(&mut self, state: &[f64]) -> Result<(), PipelineError> {
        self.env.reset_to_state(state).map_err(|e| PipelineError::input("", "state", e.to_string()))?;
        self.env.hold_posture_here();
        self.env.record_history();
        Ok(())
    }

    /// One control step (robosuite's 20 Hz) with `action`.
    ///
    /// # Errors
    /// [`PipelineError::Input`] naming `action` for a wrong width or a value that is not a
    /// number; [`PipelineError::Engine`] when the physics became unstable.
    pub fn step(&mut self, action: &[f64]) -> Result<(), PipelineError> {
        let want = self.action_dim();
        if action.len() != want {
            return Err(PipelineError::input("", "action", format!("has {} values; {} takes {want}", action.len(), self.label)));
        }
        if let Some((i, a)) = action.iter().enumerate().find(|(_, a)| !a.is_finite()) {
            return Err(PipelineError::input("", format!("action[{i}]"), format!("is {a}, not a number")));
        }
        self.env.step(action).map_err(|e| sim_error(&self.label, &e))
    }

    /// The low-dim observations, keyed and shaped as the run's datasets hold them
    /// (`robot0_eef_pos`, `robot0_eef_quat` in `xyzw`, `robot0_gripper_qpos`, `object`, ...).
    #[must_use]
    pub fn observation(&self) -> BTreeMap<String, Vec<f64>> {
        self.env.observation()
    }

    /// The cameras' images of the present state (`<camera>_image`, `[height, width, 3]`, as
    /// datasets store them); empty without cameras.
    ///
    /// # Errors
    /// [`PipelineError::Sim`] when rendering fails.
    pub fn images(&self) -> Result<BTreeMap<String, ImageStream>, PipelineError> {
        let Some(cameras) = &self.cameras else { return Ok(BTreeMap::new()) };
        let mut streams = cameras.streams(1);
        cameras.capture(self.env.physics().data(), &mut streams)?;
        Ok(streams)
    }

    /// Whether the task is achieved now.
    #[must_use]
    pub fn is_success(&self) -> bool {
        self.env.is_success()
    }

    /// The subtask-end signals now (`grasp`, ...).
    #[must_use]
    pub fn subtask_signals(&self) -> BTreeMap<String, i64> {
        self.env.subtask_term_signals()
    }

    /// The flattened robosuite state (what a dataset's `states` row holds).
    #[must_use]
    pub fn state(&self) -> Vec<f64> {
        self.env.state()
    }

    /// The scene's MJCF (a dataset's `model_file`), with portable asset paths.
    #[must_use]
    pub fn model_xml(&self) -> String {
        mimicgen_sim::assets::portable_asset_paths(&self.env.physics().scene().xml)
    }

    /// The object instance in use (`steel_pan+baby_carrot`) under object transfer.
    #[must_use]
    pub fn object_instance(&self) -> Option<String> {
        self.env.instance().map(str::to_owned)
    }
}

/// A simulator's failure, naming the environment.
fn sim_error(label: &str, e: &mimicgen_engine::EnvError) -> PipelineError {
    PipelineError::input("", label, e.to_string())
}
