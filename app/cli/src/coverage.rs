//! `mimicgen coverage`: the paper's support-coverage analysis of a dataset's initial scenes.

use std::path::PathBuf;

use mimicgen_engine::coverage::Coordinate;

use crate::exit::outln;

/// Arguments of `mimicgen coverage`.
#[derive(clap::Args, Debug)]
#[command(after_help = "\
Examples:
  mimicgen coverage out/stack_d1.hdf5 --variant D1
  mimicgen coverage out/stack_d1.hdf5 --variant D1 --bins 5 --json

Each object's x, y and yaw over the task variant's reset region is cut into --bins bins; support
coverage is the fraction of the bins^d joint bins that the demos' initial scenes hit (the paper's
appendix \"Bias and Artifacts in Generated Data\", with 3 bins). Histograms show where scenes fall
per dimension.")]
pub struct CoverageArgs {
    /// A dataset with `datagen_info/object_poses` (ours or the reference's).
    file: PathBuf,
    /// Task whose reset region defines the bins (default: from the file's env_args).
    #[arg(long)]
    task: Option<String>,
    /// Variant whose reset region defines the bins (default: from the file's env_args).
    #[arg(long)]
    variant: Option<String>,
    /// Bins per dimension.
    #[arg(long, default_value_t = 3)]
    bins: usize,
    /// Print JSON instead of text.
    #[arg(long)]
    json: bool,
}

/// Runs `mimicgen coverage`.
///
/// # Errors
/// Unreadable input, unknown task, or a dataset without object poses.
pub fn run(args: &CoverageArgs) -> anyhow::Result<()> {
    let file = args.file.display().to_string();
    let found = mimicgen_pipeline::coverage::dataset_coverage(&args.file, args.task.as_deref(), args.variant.as_deref(), args.bins)?;
    let (task, variant, c) = (found.task.as_str(), found.variant.as_str(), &found.coverage);
    if args.json {
        outln!("{}", serde_json::to_string_pretty(c)?);
        return Ok(());
    }
    outln!("{file}: {} initial scenes, bins over the reset region of {task} {variant}", c.scenes);
    outln!(
        "support coverage: {:.1} % ({} of {} joint bins, {} bins per dimension)",
        100.0 * c.support_coverage(),
        c.joint_bins_hit,
        c.joint_bins_total,
        c.bins
    );
    // A bar of `n` against the largest count `most`, 40 characters at the most.
    let bar = |n: usize, most: usize| "#".repeat(n * 40 / most.max(1));
    let widest = c.histograms.iter().flatten().copied().max().unwrap_or(1);
    for (d, hist) in c.dimensions.iter().zip(&c.histograms) {
        let unit = if d.coordinate == Coordinate::Yaw { "rad" } else { "m" };
        outln!("  {} {:?} [{:.3}, {:.3}] {unit}", d.object, d.coordinate, d.low, d.high);
        for (i, n) in hist.iter().enumerate() {
            outln!("    bin {i}: {n:>6} {}", bar(*n, widest));
        }
    }
    if !found.instances.is_empty() {
        outln!("  object instances (demos each):");
        let most = found.instances.values().copied().max().unwrap_or(1);
        for (label, n) in &found.instances {
            outln!("    {label:<20} {n:>6} {}", bar(*n, most));
        }
    }
    Ok(())
}
