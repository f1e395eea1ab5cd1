//! `mimicgen export`: a dataset to MCAP (Foxglove) or to a LeRobot dataset.

use std::path::PathBuf;
use std::process::ExitCode;

use mimicgen_io::{DemoReader, DemoSource as _, ReadOptions};

use crate::check_output;
use crate::exit::outln;

/// `mimicgen export`'s arguments.
#[derive(Debug, clap::Args)]
pub struct ExportArgs {
    /// The dataset.
    pub file: PathBuf,
    /// Output MCAP file.
    #[arg(long, required_unless_present = "lerobot")]
    pub mcap: Option<PathBuf>,
    /// Output LeRobot dataset directory (format v3.0).
    #[arg(long)]
    pub lerobot: Option<PathBuf>,
    /// LeRobot: observation keys concatenated into `observation.state`, in order.
    #[arg(long, value_delimiter = ',', default_value = "robot0_eef_pos,robot0_eef_quat,robot0_gripper_qpos,object")]
    pub state_keys: Vec<String>,
    /// LeRobot: the task instruction of every frame. Default: the task's, from env_args.
    #[arg(long)]
    pub instruction: Option<String>,
    /// LeRobot: the ffmpeg that encodes camera streams. Default: $MIMICGEN_FFMPEG, else the
    /// one scripts/setup.sh unpacked into the cache, else `ffmpeg` on the PATH.
    #[arg(long)]
    pub ffmpeg: Option<PathBuf>,
    /// Replace an existing output (the MCAP file, the LeRobot directory).
    #[arg(long)]
    pub overwrite: bool,
}

/// Runs `mimicgen export`.
///
/// # Errors
/// What the command reports (each names the file and field).
pub fn run(args: ExportArgs) -> anyhow::Result<ExitCode> {
    let ExportArgs { file, mcap, lerobot, state_keys, instruction, ffmpeg, overwrite } = args;

    let ds = DemoReader::open_with(&file, ReadOptions::default())?;
    if let Some(mcap) = mcap {
        check_output(&mcap, Some(&file), overwrite)?;
        let summary = mimicgen_io::mcap_export::export(&ds, &mcap)?;
        outln!("{}: {} demos, {} steps at 20 Hz", mcap.display(), summary.demos, summary.steps);
        for (topic, n) in &summary.messages {
            outln!("  {topic:<24} {n} messages");
        }
    }
    if let Some(out) = lerobot {
        let request = mimicgen_pipeline::lerobot::ExportRequest { state_keys: Some(state_keys), instruction, ffmpeg, overwrite };
        let bar = indicatif::ProgressBar::new(ds.demo_names().len() as u64).with_style(
            indicatif::ProgressStyle::with_template("exporting {bar:30} {pos}/{len} episodes, {elapsed} ({eta} left)")
                .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        drop(ds);
        let summary = mimicgen_pipeline::lerobot::export(&file, &out, &request, |done, _| bar.set_position(done as u64))?;
        bar.finish_and_clear();
        outln!(
            "{}: LeRobot {} dataset, {} episodes, {} frames at 20 fps",
            summary.out,
            mimicgen_io::lerobot::CODEBASE_VERSION,
            summary.episodes,
            summary.frames
        );
        let state: Vec<String> = summary.state.iter().map(|(k, n)| format!("{k} ({n})")).collect();
        outln!("  observation.state: {}", state.join(" + "));
        outln!("  task: {:?}", summary.task);
        for video in &summary.videos {
            outln!("  {video}: H.264 video");
        }
    }
    Ok(ExitCode::SUCCESS)
}
