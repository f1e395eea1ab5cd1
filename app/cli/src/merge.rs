//! `mimicgen merge`: the shards of a run joined into the whole run's dataset.

use std::path::PathBuf;
use std::process::ExitCode;

use crate::exit::outln;

/// `mimicgen merge`'s arguments.
#[derive(Debug, clap::Args)]
pub struct MergeArgs {
    /// The shards' datasets, all K of them, in any order.
    #[arg(required = true, value_name = "SHARD")]
    pub shards: Vec<PathBuf>,
    /// Output dataset (the failed attempts go to OUT_failed.hdf5, the report to OUT.json).
    #[arg(long)]
    pub out: PathBuf,
    /// Replace existing outputs.
    #[arg(long)]
    pub overwrite: bool,
}

/// Runs `mimicgen merge`.
///
/// # Errors
/// What the command reports (each names the file and field).
pub fn run(args: MergeArgs) -> anyhow::Result<ExitCode> {
    let MergeArgs { shards, out, overwrite } = args;

    let bar = indicatif::ProgressBar::new(0).with_style(
        indicatif::ProgressStyle::with_template("merging {bar:30} {pos}/{len} attempts, {elapsed} ({eta} left)")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let report = mimicgen_pipeline::merge::merge(&shards, &out, overwrite, |done, total| {
        bar.set_length(total as u64);
        bar.set_position(done as u64);
    })?;
    bar.finish_and_clear();
    outln!("{}", serde_json::to_string_pretty(&report)?);
    eprintln!(
        "merged {} shards: {} of {} attempts succeeded ({:.1} %) -> {}",
        shards.len(),
        report.successes,
        report.attempts,
        100.0 * report.generation_rate,
        report.output
    );
    Ok(ExitCode::SUCCESS)
}
