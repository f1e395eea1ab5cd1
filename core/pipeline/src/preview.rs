//! Previewing attempts before a run: the scene attempt `index` of a run would draw, the source
//! segments it would pick (with the selection's ranking), transformed and bridged, and "try it":
//! that attempt executed in simulation. What the app's preview screen shows, from the same
//! generator `generate` runs, so a previewed attempt is the one a run with that seed makes.

use std::sync::Arc;

use mimicgen_engine::{Attempt, Generator, Overrides, Plan, SubtaskMarks};
use mimicgen_sim::SimEnv;

use crate::{Pipeline, PipelineError, RunConfig};

/// A prepared source file with one simulator, ready to plan and try attempts.
pub struct Previewer {
    pipeline: Pipeline,
    generator: Generator,
    env: SimEnv,
    /// The marks and seed `generator` was made with, so an unchanged request rebuilds nothing.
    configured: Option<(SubtaskMarks, u64)>,
}

impl std::fmt::Debug for Previewer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Previewer").field("pipeline", &self.pipeline).finish_non_exhaustive()
    }
}

impl Previewer {
    /// Prepares `config` as a run would (task, variant, spec, sources, scene), with hand-set
    /// subtask ends for the demos `marks` names, and builds one simulator.
    ///
    /// # Errors
    /// As [`Pipeline::prepare_with_ends`].
    pub fn new(config: &RunConfig, marks: &SubtaskMarks) -> Result<Self, PipelineError> {
        let pipeline = Pipeline::prepare_with_ends(config, &marks.ends)?;
        let env = SimEnv::new(Arc::clone(pipeline.scene()), Arc::clone(pipeline.task()));
        let generator = pipeline.generator().clone();
        Ok(Self { pipeline, generator, env, configured: None })
    }

    /// The pipeline behind it (task, variant, source path).
    #[must_use]
    pub fn pipeline(&self) -> &Pipeline {
        &self.pipeline
    }

    /// The generator plans and attempts come from (with the ends and seed last set).
    #[must_use]
    pub fn generator(&self) -> &Generator {
        &self.generator
    }

    /// Uses the hand-made `marks` (subtask ends instead of the file's signals, segment starts
    /// instead of the approach detector) and run seed `seed`.
    ///
    /// # Errors
    /// [`PipelineError::Engine`] naming the demo whose ends or starts do not fit.
    pub fn configure(&mut self, marks: &SubtaskMarks, seed: u64) -> Result<(), PipelineError> {
        if self.configured.as_ref().is_some_and(|(m, s)| m == marks && *s == seed) {
            return Ok(());
        }
        let label = self.pipeline.source_path().display().to_string();
        self.generator = self.pipeline.generator().with_marks(marks).map_err(|e| PipelineError::engine(label, e))?.with_seed(seed);
        self.configured = Some((marks.clone(), seed));
        Ok(())
    }

    /// Plans attempt `index` (see [`Generator::plan`]) with what `overrides` forces (source demos,
    /// moved objects).
    ///
    /// # Errors
    /// [`PipelineError::Engine`] for a forced demo or moved object that does not exist, or a scene
    /// the simulator rejects.
    pub fn plan(&mut self, index: u64, overrides: &Overrides) -> Result<Plan, PipelineError> {
        self.generator.plan(&mut self.env, index, overrides).map_err(|e| PipelineError::engine("preview", e))
    }

    /// Executes attempt `index` (see [`Generator::attempt_with`]): with no overrides, the attempt a
    /// run with this seed makes, step for step.
    ///
    /// # Errors
    /// As [`Previewer::plan`].
    pub fn try_attempt(&mut self, index: u64, overrides: &Overrides) -> Result<Attempt, PipelineError> {
        self.generator.attempt_with(&mut self.env, index, overrides).map_err(|e| PipelineError::engine("try it", e))
    }
}
