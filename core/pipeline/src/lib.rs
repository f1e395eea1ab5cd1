//! A whole generation run as a library: the one pipeline behind the `mimicgen` CLI, the app and
//! the Python package.
//!
//! What it does: works out the task and variant from the inputs ([`RunConfig`]), reads and checks
//! the spec and the source demos (refusing controllers the backend does not implement), compiles
//! the scene, runs attempts on worker threads that also compute the observations of the attempts
//! that will be kept, writes the robomimic dataset (and failed attempts) in attempt order,
//! commits its progress after every attempt so an interrupted run resumes exactly, and reports
//! typed [`Event`]s and a [`Report`]. A cancel flag stops it cleanly with valid outputs.
//! What it does not do: print, parse arguments, or draw (front ends consume the events).
//!
//! ```no_run
//! use std::sync::atomic::AtomicBool;
//! use mimicgen_pipeline::{Event, Pipeline, RunConfig};
//!
//! # fn main() -> Result<(), mimicgen_pipeline::PipelineError> {
//! let config = RunConfig { num_demos: Some(20), workers: 2, out: "out/stack.hdf5".into(), ..RunConfig::default() };
//! let pipeline = Pipeline::prepare(&config)?;
//! let cancel = AtomicBool::new(false);
//! let report = pipeline.run(&cancel, |event| {
//!     if let Event::Attempt(a) = event {
//!         println!("attempt {}: {:?}", a.attempt.index, a.outcome);
//!     }
//! })?;
//! println!("{} of {} succeeded", report.successes, report.attempts);
//! # Ok(()) }
//! ```

pub mod annotate;
pub mod bundled;
mod config;
pub use config::check_spec_file;
pub mod coverage;
pub mod doctor;
mod error;
mod events;
pub mod lerobot;
pub mod memory;
pub mod merge;
mod outputs;
mod policy_env;
pub mod prepare;
pub mod preview;
pub mod render;
pub mod replay;
mod run;
pub mod two_arm;

pub use error::PipelineError;
pub use events::{AttemptEvent, Event};
pub use mimicgen_run::{
    ActionForm, CameraConfig, CauseReport, Choice, CoverageFigure, DatasetQuality, DemoReport, FailureReport, FrontEnd, InstanceReport,
    NEVER_SUCCEEDS_MIN_USES, OffsetRange, Outcome, ReplayCheck, Report, RunConfig, RunInfo, Scoped, SpecOverrides,
};
pub use outputs::{
    AttemptRecord, PROGRESS_ATTR, RUN_ATTR, attempt_log_path, clear_outputs, failed_path, quality_path, read_attempt_log, sibling,
};
pub use policy_env::PolicyEnv;
pub use run::{Observed, Pipeline};
