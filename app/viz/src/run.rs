//! A generation run (or a dataset) streamed to one recording.

use mimicgen_engine::demo::initial_object_poses;
use mimicgen_engine::{Attempt, RunStats, SourceDemo};
use mimicgen_sim::Scene;
use rerun::RecordingStream;

use crate::record::{self, timelines};
use crate::{SceneLogger, VizError};

/// Which attempts get the full scene (every geom's pose per step).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SceneLevel {
    /// Every attempt and source demo.
    #[default]
    All,
    /// Successful attempts and source demos only.
    Successes,
    /// No per-step scene poses (paths, frames, plots and statistics only).
    None,
}

/// How much to log.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LogConfig {
    /// Which attempts get per-step scene poses.
    pub scene: SceneLevel,
    /// Log the scene at every `scene_stride`-th step.
    pub scene_stride: usize,
}

impl Default for LogConfig {
    fn default() -> Self {
        Self { scene: SceneLevel::All, scene_stride: 1 }
    }
}

/// Logs source demos, attempts and statistics of one run (or the demos of one dataset).
#[derive(Debug)]
pub struct RunLogger {
    rec: RecordingStream,
    scene: SceneLogger,
    config: LogConfig,
    source_names: Vec<String>,
    frame: usize,
    demos_cleared: bool,
    /// The `frame` at which each logged demo starts.
    demo_frames: std::collections::BTreeMap<usize, usize>,
}

impl RunLogger {
    /// Logs the scene's geoms (static) and returns a logger for `rec`.
    ///
    /// # Errors
    /// [`VizError::Rerun`] from the stream.
    pub fn new(rec: RecordingStream, scene: &Scene, config: LogConfig) -> Result<Self, VizError> {
        let scene = SceneLogger::new(scene, "world/scene");
        rec.log_static("world", &rerun::ViewCoordinates::RIGHT_HAND_Z_UP()).map_err(|e| VizError::rerun("world", &e))?;
        scene.log_static(&rec)?;
        Ok(Self {
            rec,
            scene,
            config,
            source_names: Vec::new(),
            frame: 0,
            demos_cleared: false,
            demo_frames: std::collections::BTreeMap::new(),
        })
    }

    /// The recording.
    #[must_use]
    pub fn stream(&self) -> &RecordingStream {
        &self.rec
    }

    /// Logs demos (source demos of a run, or a dataset's demos) on the `demo` timeline under
    /// `world/demo`, with the scene per step where states fit. Their names label attempts' sources.
    ///
    /// # Errors
    /// [`VizError::Rerun`] from the stream, [`VizError::Sim`] for states that do not fit the scene.
    pub fn log_demos<'a>(&mut self, demos: impl IntoIterator<Item = (usize, &'a SourceDemo)>) -> Result<(), VizError> {
        for (index, demo) in demos {
            if self.source_names.len() <= index {
                self.source_names.resize(index + 1, String::new());
            }
            if let Some(name) = self.source_names.get_mut(index) {
                name.clone_from(&demo.name);
            }
            self.demo_frames.insert(index, self.frame);
            record::log_demo(&self.rec, "world/demo", demo, index, self.frame)?;
            let n = demo.sim.states.len();
            if self.config.scene != SceneLevel::None && n > 0 {
                let index_i64 = i64::try_from(index).unwrap_or(i64::MAX);
                let steps: Vec<i64> = (0..n).map(|t| i64::try_from(t).unwrap_or(i64::MAX)).collect();
                let frames: Vec<i64> = steps.iter().map(|t| t + i64::try_from(self.frame).unwrap_or(i64::MAX)).collect();
                self.scene.place_fixed_objects(&initial_object_poses(&demo.object_poses));
                self.scene.log_states(
                    &self.rec,
                    &demo.sim.states,
                    self.config.scene_stride,
                    &[(timelines::STEP, steps), (timelines::DEMO, vec![index_i64; n]), (timelines::FRAME, frames)],
                )?;
            }
            self.frame += demo.len().max(n);
        }
        self.rec.disable_timeline(timelines::DEMO);
        Ok(())
    }

    /// Logs the camera images of demo `index` (already logged by [`RunLogger::log_demos`]) on its
    /// steps; returns the cameras.
    ///
    /// # Errors
    /// [`VizError::Rerun`] from the stream.
    pub fn log_demo_images(
        &mut self,
        index: usize,
        images: &std::collections::BTreeMap<String, mimicgen_engine::image::ImageStream>,
    ) -> Result<Vec<String>, VizError> {
        let frame = self.demo_frames.get(&index).copied().unwrap_or(self.frame);
        let cameras = record::log_images(&self.rec, images, index, frame)?;
        self.rec.disable_timeline(timelines::DEMO);
        Ok(cameras)
    }

    /// Logs one attempt and the statistics after it.
    ///
    /// # Errors
    /// [`VizError::Rerun`] from the stream, [`VizError::Sim`] for states that do not fit the scene.
    pub fn log_attempt(&mut self, attempt: &Attempt, stats: &RunStats) -> Result<(), VizError> {
        record::log_attempt(&self.rec, attempt, &self.source_names, self.frame)?;
        if !self.demos_cleared {
            // Source demos stay on the `demo` timeline; on `frame` they give way to the attempts.
            self.rec.log("world/demo", &rerun::Clear::recursive()).map_err(|e| VizError::rerun("world/demo", &e))?;
            self.demos_cleared = true;
        }
        record::log_stats(&self.rec, stats, &self.source_names)?;
        self.scene.place_fixed_objects(&initial_object_poses(&attempt.trajectory.object_poses));
        self.log_attempt_scene(&attempt.trajectory.states, attempt.index, attempt.success)
    }

    /// The scene at every step of attempt `index` (as configured: every attempt, successes only,
    /// none), on the `step`, `attempt` and `frame` timelines; moves the run's frame past it.
    fn log_attempt_scene(&mut self, states: &mimicgen_engine::Rows, index: u64, success: bool) -> Result<(), VizError> {
        let n = states.len();
        let wanted = match self.config.scene {
            SceneLevel::All => true,
            SceneLevel::Successes => success,
            SceneLevel::None => false,
        };
        if wanted && n > 0 {
            let k = i64::try_from(index).unwrap_or(i64::MAX);
            let steps: Vec<i64> = (0..n).map(|t| i64::try_from(t).unwrap_or(i64::MAX)).collect();
            let frames: Vec<i64> = steps.iter().map(|t| t + i64::try_from(self.frame).unwrap_or(i64::MAX)).collect();
            self.scene.log_states(
                &self.rec,
                states,
                self.config.scene_stride,
                &[(timelines::STEP, steps), (timelines::ATTEMPT, vec![k; n]), (timelines::FRAME, frames)],
            )?;
        }
        self.frame += n;
        Ok(())
    }

    /// Names the source demos attempts are labelled with (what [`RunLogger::log_demos`] does for a
    /// one-arm run's).
    pub fn set_source_names(&mut self, names: Vec<String>) {
        self.source_names = names;
    }

    /// Logs one two-arm attempt (see [`record::log_two_arm_attempt`]), with the scene per step as
    /// configured, and the run's counts after it (`stats/attempts`, `stats/successes`).
    ///
    /// # Errors
    /// [`VizError::Rerun`] from the stream, [`VizError::Sim`] for states that do not fit the scene.
    pub fn log_two_arm_attempt(
        &mut self,
        attempt: &mimicgen_engine::two_arm::TwoArmAttempt,
        spec: &mimicgen_engine::two_arm::TwoArmSpec,
        counts: (usize, usize),
    ) -> Result<(), VizError> {
        record::log_two_arm_attempt(&self.rec, attempt, spec, &self.source_names, self.frame)?;
        #[allow(clippy::cast_precision_loss)] // counts far below 2^52
        for (what, value) in [("stats/attempts", counts.0 as f64), ("stats/successes", counts.1 as f64)] {
            self.rec.log(what, &rerun::Scalars::single(value)).map_err(|e| VizError::rerun(what, &e))?;
        }
        self.log_attempt_scene(&attempt.states, attempt.index, attempt.success)
    }

    /// Logs a planned, not executed, attempt: its segments, and the scene at `plan.initial_state`
    /// (when it fits the scene) at step 0.
    ///
    /// # Errors
    /// [`VizError::Rerun`] from the stream, [`VizError::Sim`] for a state that does not fit.
    pub fn log_plan(&mut self, plan: &mimicgen_engine::Plan) -> Result<(), VizError> {
        record::log_plan(&self.rec, plan, &self.source_names, self.frame)?;
        if self.config.scene != SceneLevel::None && !plan.initial_state.is_empty() {
            let mut states = mimicgen_engine::Rows::new(plan.initial_state.len());
            states.push(&plan.initial_state).map_err(|e| VizError::rerun("plan state", &e))?;
            let k = i64::try_from(plan.index).unwrap_or(i64::MAX);
            let frame = i64::try_from(self.frame).unwrap_or(i64::MAX);
            self.scene.place_fixed_objects(&plan.initial_object_poses);
            self.scene.log_states(
                &self.rec,
                &states,
                1,
                &[(timelines::STEP, vec![0]), (timelines::ATTEMPT, vec![k]), (timelines::FRAME, vec![frame])],
            )?;
        }
        self.frame += 1;
        Ok(())
    }

    /// Flushes everything to the sink.
    ///
    /// # Errors
    /// [`VizError::Rerun`] if the sink cannot be flushed.
    pub fn finish(self) -> Result<(), VizError> {
        self.rec.flush_blocking().map_err(|e| VizError::rerun("flush", &e))
    }
}
