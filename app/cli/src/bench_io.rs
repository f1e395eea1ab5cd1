//! `mimicgen bench-io`: time and peak memory of writing and reading a synthetic dataset.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context as _;
use mimicgen_engine::Rows;
use mimicgen_engine::pose::{Pose, Rot, Vec3, pose_from_parts};
use mimicgen_engine::spec::SourceSelection;
use mimicgen_io::{DatagenInfo, DatasetWriter, DemoData, DemoReader, DemoSource as _, ReadOptions, RobomimicDataset, WriterOptions};

use mimicgen_pipeline::memory::{peak_rss_mib, reset_peak_rss};

use crate::exit::outln;

#[allow(clippy::cast_precision_loss)]
fn synthetic_demo(d: usize, steps: usize) -> anyhow::Result<DemoData> {
    let pose = |t: usize, k: f64| -> Pose {
        let s = t as f64 * 0.01 + d as f64 * 1e-3 + k;
        pose_from_parts(Vec3::new(s, 0.5 * s, 0.8), Rot::from_euler_angles(0.0, 0.0, s))
    };
    let row = |w: usize, k: f64| (0..steps * w).map(|i| ((i as f64) * 1e-3 + k).sin()).collect::<Vec<f64>>();
    let obs = BTreeMap::from([
        ("object".to_owned(), (vec![23], row(23, 1.0))),
        ("robot0_eef_pos".to_owned(), (vec![3], row(3, 2.0))),
        ("robot0_eef_quat".to_owned(), (vec![4], row(4, 3.0))),
        ("robot0_gripper_qpos".to_owned(), (vec![2], row(2, 4.0))),
        ("robot0_joint_pos".to_owned(), (vec![7], row(7, 5.0))),
    ]);
    Ok(DemoData {
        actions: Rows::from_vec(7, row(7, 0.0), "actions")?,
        other_actions: std::collections::BTreeMap::new(),
        states: Rows::from_vec(45, row(45, 0.5), "states")?,
        rewards: Some(vec![0.0; steps]),
        dones: Some(vec![0; steps]),
        obs,
        images: BTreeMap::new(),
        datagen_info: Some(DatagenInfo {
            eef_poses: (0..steps).map(|t| pose(t, 0.0)).collect(),
            target_poses: (0..steps).map(|t| pose(t, 0.01)).collect(),
            gripper_actions: Rows::from_vec(1, row(1, 0.2), "gripper")?,
            object_poses: BTreeMap::from([
                ("cubeA".to_owned(), (0..steps).map(|t| pose(t, 0.3)).collect()),
                ("cubeB".to_owned(), (0..steps).map(|t| pose(t, 0.6)).collect()),
            ]),
            subtask_term_signals: BTreeMap::from([("grasp".to_owned(), (0..steps).map(|t| i64::from(t >= steps / 2)).collect())]),
            arms: Vec::new(),
        }),
        src_demo_inds: vec![0, 1],
        src_demo_labels: vec![0; steps],
        model_xml: Some("<mujoco model=\"bench\"/>".to_owned()),
        attempt_index: None,
        failure: None,
        cause: None,
        object_instance: None,
    })
}

/// `mimicgen bench-io`'s arguments.
#[derive(Debug, clap::Args)]
pub struct BenchIoArgs {
    /// Number of demos.
    #[arg(long, default_value_t = 1000)]
    pub demos: usize,
    /// Steps per demo.
    #[arg(long, default_value_t = 150)]
    pub steps: usize,
    /// Directory for the temporary dataset (default: the system temp dir).
    #[arg(long)]
    pub dir: Option<PathBuf>,
}

/// Runs the benchmark and prints one line per phase.
pub fn run(args: BenchIoArgs) -> anyhow::Result<()> {
    let BenchIoArgs { demos, steps, dir } = args;
    let dir = match dir {
        Some(d) => d,
        None => std::env::temp_dir(),
    };
    let path = dir.join(format!("mimicgen-bench-io-{}.hdf5", std::process::id()));
    let resettable = reset_peak_rss();
    let before = peak_rss_mib().unwrap_or(f64::NAN);
    let start = Instant::now();
    let mut writer = DatasetWriter::create(
        &path,
        WriterOptions { env_args: Some("{}".into()), compress_obs: true, valid_fraction: Some(0.1), split_seed: 0 },
    )?;
    for d in 0..demos {
        writer.append(&synthetic_demo(d, steps)?)?;
    }
    writer.finish()?;
    let write_secs = start.elapsed().as_secs_f64();
    let write_peak = peak_rss_mib().unwrap_or(f64::NAN);
    let bytes = std::fs::metadata(&path).with_context(|| path.display().to_string())?.len();
    reset_peak_rss();
    let start = Instant::now();
    let reader = DemoReader::open_with(&path, ReadOptions::default())?;
    let mut streamed = 0;
    for name in reader.demo_names() {
        streamed += mimicgen_io::dataset::demo_steps(&*reader.load_demo(name)?);
    }
    let stream_secs = start.elapsed().as_secs_f64();
    let stream_peak = peak_rss_mib().unwrap_or(f64::NAN);
    reset_peak_rss();
    let start = Instant::now();
    let file = RobomimicDataset::open(&path)?;
    let open_secs = start.elapsed().as_secs_f64();
    let sources = file.to_source_dataset(&SourceSelection::default())?;
    let read_secs = start.elapsed().as_secs_f64();
    let read_peak = peak_rss_mib().unwrap_or(f64::NAN);
    let sources_len = sources.demos.len();
    outln!("bench-io: {demos} demos x {steps} steps, file {:.1} MB ({})", bytes as f64 / 1e6, path.display());
    outln!("  write (stream, gzip obs):       {write_secs:.2} s, peak RSS {write_peak:.0} MiB (process start {before:.0} MiB)");
    outln!("  read (streaming, demo by demo):   {stream_secs:.2} s, peak RSS {stream_peak:.0} MiB");
    outln!(
        "  read (whole file) + to engine:  {open_secs:.2} s + {:.2} s, peak RSS {read_peak:.0} MiB{}",
        read_secs - open_secs,
        if resettable { "" } else { " (peak not resettable: includes the write phase)" }
    );
    anyhow::ensure!(streamed == demos * steps, "streamed {streamed} steps, wrote {}", demos * steps);
    anyhow::ensure!(sources_len == demos, "read back {sources_len} demos, wrote {demos}");
    std::fs::remove_file(&path).with_context(|| path.display().to_string())?;
    Ok(())
}
