//! `mimicgen coverage`: the paper's support-coverage analysis of a dataset's initial scenes.

use std::collections::BTreeMap;
use std::path::PathBuf;

use anyhow::{Context as _, anyhow};
use mimicgen_engine::coverage::{Coordinate, coverage};
use mimicgen_engine::pose::{Mat4, Pose, pose_from_matrix};
use mimicgen_io::RobomimicDataset;
use mimicgen_sim::registry;

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
    let dataset = RobomimicDataset::open(&args.file).with_context(|| format!("opening {file}"))?;
    let (name, variant) = match &args.task {
        Some(name) => (name.clone(), args.variant.clone().unwrap_or_else(|| "D0".to_owned())),
        None => {
            let (task, variant) =
                registry::task_from_env_args(dataset.env_args()).map_err(|e| anyhow!("{file}: {e}; pass --task and --variant"))?;
            (task.name().to_owned(), args.variant.clone().unwrap_or(variant))
        }
    };
    let task = registry::task(&name, &variant).map_err(anyhow::Error::msg)?;
    let dims = task.coverage_dimensions();
    let mut scenes = Vec::with_capacity(dataset.demo_names().len());
    for name in dataset.demo_names() {
        let demo = dataset.demo(name).ok_or_else(|| anyhow!("{file}: data/{name} vanished"))?;
        let mut scene: BTreeMap<String, Pose> = BTreeMap::new();
        for d in &dims {
            if scene.contains_key(&d.object) {
                continue;
            }
            let path = format!("datagen_info/object_poses/{}", d.object);
            let values =
                demo.dataset_at(&path).and_then(|x| x.array.values.to_f64()).ok_or_else(|| anyhow!("{file}: data/{name} has no {path}"))?;
            let first: [f64; 16] =
                values.get(..16).and_then(|v| v.try_into().ok()).ok_or_else(|| anyhow!("{file}: data/{name}/{path} is empty"))?;
            scene.insert(d.object.clone(), pose_from_matrix(&Mat4::from_row_slice(&first), &format!("{file}: data/{name}/{path}[0]"))?);
        }
        scenes.push(scene);
    }
    let c = coverage(&scenes, &dims, args.bins)?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&c)?);
        return Ok(());
    }
    println!("{file}: {} initial scenes, bins over the reset region of {} {variant}", c.scenes, task.name());
    println!(
        "support coverage: {:.1} % ({} of {} joint bins, {} bins per dimension)",
        100.0 * c.support_coverage(),
        c.joint_bins_hit,
        c.joint_bins_total,
        c.bins
    );
    let widest = c.histograms.iter().flatten().copied().max().unwrap_or(1).max(1);
    for (d, hist) in c.dimensions.iter().zip(&c.histograms) {
        let unit = if d.coordinate == Coordinate::Yaw { "rad" } else { "m" };
        println!("  {} {:?} [{:.3}, {:.3}] {unit}", d.object, d.coordinate, d.low, d.high);
        for (i, n) in hist.iter().enumerate() {
            let bar = "#".repeat(n * 40 / widest);
            println!("    bin {i}: {n:>6} {bar}");
        }
    }
    Ok(())
}
