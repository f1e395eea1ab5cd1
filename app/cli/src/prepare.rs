//! `mimicgen prepare`: turn a plain robomimic dataset into a MimicGen source dataset by replaying
//! its recorded states in the simulator, as the reference's `prepare_src_dataset.py` does.

use std::path::PathBuf;

/// Arguments of `mimicgen prepare`.
#[derive(clap::Args, Debug)]
#[command(after_help = "\
Examples:
  mimicgen prepare my_robomimic_demos.hdf5 --out my_sources.hdf5

Every demo's states are restored in its own scene (`model_file`) to record what MimicGen needs per
step: end-effector pose, controller target pose implied by the action, gripper action, object poses
and subtask-end signals (datagen_info). Actions, states, rewards, dones and observations are copied.")]
pub struct PrepareArgs {
    /// A robomimic dataset with `states`, `actions` and `model_file` per demo.
    file: PathBuf,
    /// Output MimicGen source dataset.
    #[arg(long)]
    out: PathBuf,
    /// Task, when `env_args` does not name one of ours (see `mimicgen tasks`).
    #[arg(long)]
    task: Option<String>,
    /// Replace an existing output (never the input itself).
    #[arg(long)]
    overwrite: bool,
}

/// Runs `mimicgen prepare`.
///
/// # Errors
/// Unreadable input, unknown task, a scene that does not compile, or a failure to write.
pub fn prepare(args: &PrepareArgs) -> anyhow::Result<()> {
    crate::check_output(&args.out, Some(&args.file), args.overwrite)?;
    let bar = indicatif::ProgressBar::new(0).with_style(
        indicatif::ProgressStyle::with_template("replaying {bar:30} {pos}/{len} demos, {elapsed} ({eta} left) {msg}")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let written = mimicgen_pipeline::prepare::prepare(&args.file, &args.out, args.task.as_deref(), |done, total, name| {
        bar.set_length(total as u64);
        bar.set_position(done as u64);
        bar.set_message(name.to_owned());
    })?;
    bar.finish_and_clear();
    eprintln!("wrote {written} demos to {}", args.out.display());
    Ok(())
}

/// Arguments of `mimicgen render`.
#[derive(clap::Args, Debug)]
#[command(after_help = "\
Examples:
  mimicgen render out/stack_d0.hdf5 --out out/stack_d0_img.hdf5 --cameras
  mimicgen render source_D0.hdf5 --out source_D0_img.hdf5 --cameras agentview --camera-size 120x160

Every demo's stored states are restored in its own scene (`model_file`) and rendered with
robosuite's cameras, as `generate --cameras` renders them (robomimic's dataset_states_to_obs for
images). Everything else is copied as it is, filter keys included.")]
pub struct RenderArgs {
    /// A robomimic dataset with `states` and `model_file` per demo.
    file: PathBuf,
    /// Output dataset: the same with camera observations.
    #[arg(long)]
    out: PathBuf,
    /// Task, when `env_args` does not name one of ours (see `mimicgen tasks`).
    #[arg(long)]
    task: Option<String>,
    /// Replace an existing output.
    #[arg(long)]
    overwrite: bool,
    /// The cameras (default agentview and robot0_eye_in_hand, 84 x 84).
    #[command(flatten)]
    cameras: crate::generate::CameraArgs,
}

/// Runs `mimicgen render`.
///
/// # Errors
/// Unreadable input, unknown task or camera, a scene that does not compile, or a failure to write.
pub fn render(args: &RenderArgs) -> anyhow::Result<()> {
    let cameras = args.cameras.config().unwrap_or_default();
    let bar = indicatif::ProgressBar::new(0).with_style(
        indicatif::ProgressStyle::with_template("rendering {bar:30} {pos}/{len} demos, {elapsed} ({eta} left)")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let written =
        mimicgen_pipeline::render::render(&args.file, &args.out, &cameras, args.task.as_deref(), args.overwrite, |done, total| {
            bar.set_length(total as u64);
            bar.set_position(done as u64);
        })?;
    bar.finish_and_clear();
    eprintln!("wrote {written} demos with {} ({}x{}) to {}", cameras.names.join(", "), cameras.height, cameras.width, args.out.display());
    Ok(())
}
