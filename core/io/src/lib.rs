//! robomimic / MimicGen HDF5 datasets and MCAP export for the MimicGen engine.
//!
//! What it does: reads a MimicGen source dataset into the engine's [`SourceDataset`]
//! ([`read_source_dataset`]), keeps every other group, dataset and attribute so a file can be
//! written back bit for bit ([`RobomimicDataset`]), writes generated demos demo by demo in the
//! layout robomimic's `SequenceDataset` loads ([`DatasetWriter`]), reads large files one demo at
//! a time ([`DemoReader`]), summarises a dataset ([`info::DatasetInfo`]), exports its streams to
//! MCAP for Foxglove ([`mcap_export`]) and the whole dataset to LeRobot's format ([`lerobot`]).
//! Camera observations (`obs/<camera>_image`, uint8) are written and read as images
//! ([`mimicgen_engine::image::ImageStream`]).
//!
//! Crash safety: [`DatasetWriter`] writes `<out>.partial` marked incomplete, flushes after every
//! demo and renames on [`DatasetWriter::finish`]; readers refuse an incomplete file unless
//! [`ReadOptions::recover`] is set, which keeps the completely written demos.
//!
//! Beware: libhdf5 opens files without close-on-exec and `flock`s them, so a child process
//! spawned while a file is open keeps it locked until the child exits.
//!
//! What it does not do: no simulation, no rendering (camera images come from `mimicgen-sim`).
//!
//! ```no_run
//! use mimicgen_engine::spec::SourceSelection;
//! let sources = mimicgen_io::read_source_dataset("source_D0.hdf5", &SourceSelection::default())?;
//! println!("{} demos, objects {:?}", sources.demos.len(), sources.object_names());
//! # Ok::<(), mimicgen_io::IoError>(())
//! ```
//!
//! [`SourceDataset`]: mimicgen_engine::SourceDataset

pub mod dataset;
mod error;
pub mod info;
pub mod lerobot;
pub mod mcap_export;
mod source_demo;
pub mod tree;
pub mod writer;

pub use dataset::{
    DatasetReport, DemoReader, DemoSource, ReadOptions, RobomimicDataset, read_source_dataset, root_string_attrs, source_demo_from_group,
    source_demo_of_arm, write_tree,
};
pub use error::{IoError, Result};
pub use writer::{
    ATTEMPT_ATTR, ArmInfo, CAUSE_ATTR, DatagenInfo, DatasetWriter, DemoData, FAILURE_ATTR, INSTANCE_ATTR, Observation, WriterOptions,
    image_dataset, observations_from_group,
};
