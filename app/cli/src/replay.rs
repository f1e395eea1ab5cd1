//! `mimicgen replay`: a dataset's demos replayed in our simulator, step by step (the half of
//! `scripts/compare_physics.py` that runs here).

use std::path::PathBuf;

use mimicgen_pipeline::replay::{self, ReplayMode};

use crate::exit::outln;

/// How `--mode` drives the arm.
#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub enum ModeArg {
    /// The stored controller targets, closed loop, with the attempt's own action noise.
    Targets,
    /// The stored actions, open loop (robomimic's playback).
    Actions,
    /// The stored absolute actions (`actions_abs`, from `generate --actions abs`), open loop.
    ActionsAbs,
    /// The stored joint-position actions (`actions_joint`, from `generate --actions joint`), open
    /// loop under a joint-position controller.
    ActionsJoint,
}

/// Arguments of `mimicgen replay`.
#[derive(clap::Args, Debug)]
#[command(after_help = "\
Examples:
  mimicgen replay out/stack_d0_failed.hdf5                      did each failed attempt fail again?
  mimicgen replay out/stack_d0.hdf5 --demos demo_3,demo_7 --trace trace.json
  mimicgen replay demos.hdf5 --mode actions                     robomimic's open-loop playback
  mimicgen replay demos.hdf5 --mode actions-abs                 the same from `actions_abs`
  mimicgen replay demos.hdf5 --mode actions-joint               the same from `actions_joint`

Every demo starts from its first stored state in its own scene (`model_file`). With --mode
targets (the default) each step's action is recomputed from where the arm is towards the stored
`datagen_info/target_pose`, plus the noise the attempt added: the attempt as generation drove
it. --trace writes, per demo and step, the end effector, finger joints, object poses, contact
count and the finger pads' contacts and normal forces per object, as JSON;
scripts/compare_physics.py runs the same demos in robosuite and says where the two part.")]
pub struct ReplayArgs {
    /// A robomimic / MimicGen dataset with `states`, `actions` and `model_file` per demo.
    file: PathBuf,
    /// Demos to replay, comma-separated (default: all).
    #[arg(long, value_delimiter = ',')]
    demos: Vec<String>,
    /// How to drive the arm.
    #[arg(long, value_enum, default_value = "targets")]
    mode: ModeArg,
    /// Write every step of every demo here (JSON).
    #[arg(long, value_name = "FILE.json")]
    trace: Option<PathBuf>,
    /// Replace an existing --trace file.
    #[arg(long)]
    overwrite: bool,
    /// Task, when `env_args` does not name one of ours (see `mimicgen tasks`).
    #[arg(long)]
    task: Option<String>,
}

/// Runs `mimicgen replay`.
///
/// # Errors
/// Unreadable input, unknown task or demo, a scene that does not compile, or a failure to write.
pub fn run(args: &ReplayArgs) -> anyhow::Result<()> {
    if let Some(trace) = &args.trace {
        crate::check_output(trace, Some(&args.file), args.overwrite)?;
    }
    let mode = match args.mode {
        ModeArg::Targets => ReplayMode::Targets,
        ModeArg::Actions => ReplayMode::Actions,
        ModeArg::ActionsAbs => ReplayMode::ActionsAbs,
        ModeArg::ActionsJoint => ReplayMode::ActionsJoint,
    };
    let bar = indicatif::ProgressBar::new(0).with_style(
        indicatif::ProgressStyle::with_template("replaying {bar:30} {pos}/{len} demos, {elapsed} ({eta} left) {msg}")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let traces = replay::replay(&args.file, &args.demos, mode, args.task.as_deref(), |done, total, name| {
        bar.set_length(total as u64);
        bar.set_position(done as u64);
        bar.set_message(name.to_owned());
    })?;
    bar.finish_and_clear();
    for t in &traces {
        let outcome = match (t.first_success, &t.stopped) {
            (Some(step), _) => format!("success (first at step {step})"),
            (None, Some(why)) => format!("stopped: {why}"),
            (None, None) => "no success".to_owned(),
        };
        let recorded = t.recorded_failure.as_ref().map(|f| format!(" [generated: failed, {f}]")).unwrap_or_default();
        outln!("{}: {} steps, {outcome}{recorded}", t.demo, t.steps.len() - 1);
    }
    let successes = traces.iter().filter(|t| t.success).count();
    outln!(
        "replay ({}): {successes} of {} succeeded",
        match mode {
            ReplayMode::Targets => "targets",
            ReplayMode::Actions => "actions",
            ReplayMode::ActionsAbs => "actions-abs",
            ReplayMode::ActionsJoint => "actions-joint",
        },
        traces.len()
    );
    if let Some(path) = &args.trace {
        let json = serde_json::to_vec(&traces)?;
        std::fs::write(path, json).map_err(|e| anyhow::anyhow!("{}: cannot write the trace: {e}", path.display()))?;
        eprintln!("trace of {} demos written to {}", traces.len(), path.display());
    }
    Ok(())
}
