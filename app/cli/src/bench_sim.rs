//! `mimicgen bench-sim`: what generation costs on the MuJoCo backend, as ratios measured in one run.

use std::ops::ControlFlow;
use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::time::Instant;

use anyhow::Context as _;
use mimicgen_engine::{Attempt, Environment as _};
use mimicgen_io::RobomimicDataset;
use mimicgen_pipeline::memory::{peak_rss_mib, reset_peak_rss};
use mimicgen_pipeline::{Pipeline, Report, RunConfig};
use mimicgen_sim::SimEnv;
use serde_json::json;

use crate::exit::outln;

/// Arguments of `mimicgen bench-sim`.
#[derive(clap::Args, Debug)]
pub struct BenchSimArgs {
    /// Attempts per measurement.
    #[arg(long, default_value_t = 40)]
    attempts: usize,
    /// Task.
    #[arg(long, default_value = "stack")]
    task: String,
    /// Variant.
    #[arg(long, default_value = "D0")]
    variant: String,
    /// Also measure `generate --early-abort` against the default on the same attempts.
    #[arg(long)]
    early_abort: bool,
    /// Directory for the datasets the end-to-end runs write (default: a temporary one).
    #[arg(long)]
    dir: Option<std::path::PathBuf>,
    /// Also measure the end-to-end runs rendering these cameras (`--cameras` alone: agentview and
    /// the wrist camera), against the same runs without: demos per second and bytes per demo.
    #[command(flatten)]
    cameras: crate::generate::CameraArgs,
}

/// One end-to-end `generate` run (the pipeline: simulation, observations, compression, writing),
/// timed, with its peak resident memory.
fn end_to_end(args: &BenchSimArgs, out: &Path, workers: usize, early_abort: bool) -> anyhow::Result<(f64, Report)> {
    end_to_end_with(args, out, workers, early_abort, None)
}

fn end_to_end_with(
    args: &BenchSimArgs,
    out: &Path,
    workers: usize,
    early_abort: bool,
    cameras: Option<mimicgen_sim::camera::CameraConfig>,
) -> anyhow::Result<(f64, Report)> {
    let config = RunConfig {
        cameras,
        task: Some(args.task.clone()),
        variant: Some(args.variant.clone()),
        num_demos: Some(args.attempts),
        workers,
        out: out.to_path_buf(),
        early_abort,
        overwrite: true,
        ..RunConfig::default()
    };
    reset_peak_rss();
    let started = Instant::now();
    let report = Pipeline::prepare(&config)?.run(&AtomicBool::new(false), |_| {})?;
    Ok((started.elapsed().as_secs_f64(), report))
}

/// Runs the benchmark and prints a JSON report.
///
/// # Errors
/// As `mimicgen generate`.
pub fn run(args: &BenchSimArgs) -> anyhow::Result<()> {
    // The engine loop and bare physics run on the very generator and scene `generate` uses.
    let pipeline = Pipeline::prepare(&RunConfig {
        task: Some(args.task.clone()),
        variant: Some(args.variant.clone()),
        num_demos: Some(args.attempts),
        ..RunConfig::default()
    })?;
    let task = Arc::clone(pipeline.task());
    let scene = Arc::clone(pipeline.scene());
    let generator = pipeline.generator();
    let timed = |workers: usize| -> anyhow::Result<(f64, Vec<Attempt>)> {
        let mut envs: Vec<SimEnv> = (0..workers).map(|_| SimEnv::new(Arc::clone(&scene), Arc::clone(&task))).collect();
        let mut attempts = Vec::new();
        let started = Instant::now();
        mimicgen_engine::run(generator, &mut envs, |a, _| {
            attempts.push(a);
            ControlFlow::Continue(())
        })?;
        Ok((started.elapsed().as_secs_f64(), attempts))
    };
    let temp = tempfile::tempdir().context("creating a temporary directory")?;
    let dir_path = match &args.dir {
        Some(d) => {
            std::fs::create_dir_all(d).with_context(|| d.display().to_string())?;
            d.clone()
        }
        None => temp.path().to_path_buf(),
    };
    let (e2e_one_s, e2e_one) = end_to_end(args, &dir_path.join("one.hdf5"), 1, false)?;
    let e2e_one_peak = e2e_one.peak_rss_mib;
    let (e2e_two_s, e2e_two) = end_to_end(args, &dir_path.join("two.hdf5"), 2, false)?;
    let identical = RobomimicDataset::open(dir_path.join("one.hdf5"))?.data() == RobomimicDataset::open(dir_path.join("two.hdf5"))?.data();
    anyhow::ensure!(e2e_one.successes == e2e_two.successes, "1 and 2 workers disagree on the successes");
    let early = if args.early_abort {
        let (s, r) = end_to_end(args, &dir_path.join("early.hdf5"), 1, true)?;
        let same = RobomimicDataset::open(dir_path.join("one.hdf5"))?.data() == RobomimicDataset::open(dir_path.join("early.hdf5"))?.data();
        #[allow(clippy::cast_precision_loss)]
        Some(json!({
            "early_abort_1_worker_s": s,
            "successes": r.successes,
            "same_successful_demos": same,
            "s_per_success_default": e2e_one_s / e2e_one.successes.max(1) as f64,
            "s_per_success_early_abort": s / r.successes.max(1) as f64,
            "time_saved_fraction": 1.0 - s / e2e_one_s,
        }))
    } else {
        None
    };
    let cameras = match args.cameras.config() {
        Some(config) => {
            let label = format!("{} at {}x{}", config.names.join(", "), config.height, config.width);
            let (one_s, one) = end_to_end_with(args, &dir_path.join("cams_one.hdf5"), 1, false, Some(config.clone()))?;
            let (two_s, _) = end_to_end_with(args, &dir_path.join("cams_two.hdf5"), 2, false, Some(config))?;
            let bytes = |name: &str| std::fs::metadata(dir_path.join(name)).map(|m| m.len()).unwrap_or_default();
            let per_demo = |name: &str, n: usize| bytes(name) as f64 / n.max(1) as f64;
            let demos = |s: f64, n: usize| n as f64 / s;
            anyhow::ensure!(one.successes == e2e_one.successes, "rendering changed which attempts succeed");
            #[allow(clippy::cast_precision_loss)]
            Some(json!({
                "cameras": label,
                "end_to_end_1_worker_s": one_s,
                "end_to_end_2_workers_s": two_s,
                "demos_per_s_1_worker": demos(one_s, one.successes),
                "demos_per_s_2_workers": demos(two_s, one.successes),
                "demos_per_s_1_worker_without_cameras": demos(e2e_one_s, e2e_one.successes),
                "demos_per_s_2_workers_without_cameras": demos(e2e_two_s, e2e_one.successes),
                "slowdown_1_worker": one_s / e2e_one_s,
                "speedup_2_workers": one_s / two_s,
                "bytes_per_demo": per_demo("cams_one.hdf5", one.successes),
                "bytes_per_demo_without_cameras": per_demo("one.hdf5", e2e_one.successes),
                "peak_rss_mib_1_worker": one.peak_rss_mib,
            }))
        }
        None => None,
    };
    reset_peak_rss();
    let (one_s, attempts) = timed(1)?;
    let (two_s, _) = timed(2)?;
    let control_steps: usize = attempts.iter().map(|a| a.trajectory.len()).sum();
    let physics_steps = control_steps * scene.substeps;
    // Record the controls each attempt applied at every physics step (one more run, untimed), then
    // time bare mj_step replaying exactly those controls from the same initial states: the same
    // physics, contacts included, with no controller, recording or engine around it.
    let mut env = SimEnv::new(Arc::clone(&scene), Arc::clone(&task));
    let mut recorded = Vec::with_capacity(attempts.len());
    for a in &attempts {
        env.record_controls(true);
        let again = generator.attempt(&mut env, a.index)?;
        anyhow::ensure!(again.trajectory.states == a.trajectory.states, "attempt {} did not repeat exactly", a.index);
        recorded.push((a.initial_state.clone(), env.take_controls(), env.state()));
    }
    env.record_controls(false);
    let started = Instant::now();
    for (state, controls, _) in &recorded {
        env.replay_controls_bare(state, controls).map_err(|e| anyhow::anyhow!("{e}"))?;
    }
    let bare_s = started.elapsed().as_secs_f64();
    // The bare replay is the same physics only if it ends where the attempt ended.
    let mut worst_final_state_diff = 0.0_f64;
    for (state, controls, last) in &recorded {
        env.replay_controls_bare(state, controls).map_err(|e| anyhow::anyhow!("{e}"))?;
        let diff = env.state().iter().zip(last).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
        worst_final_state_diff = worst_final_state_diff.max(diff);
    }
    #[allow(clippy::cast_precision_loss)]
    let report = json!({
        "task": task.name(),
        "variant": args.variant,
        "attempts": attempts.len(),
        "successes": attempts.iter().filter(|a| a.success).count(),
        "control_steps": control_steps,
        "physics_steps": physics_steps,
        "generation_1_worker_s": one_s,
        "generation_2_workers_s": two_s,
        "bare_physics_s": bare_s,
        "bare_physics_steps_per_s": physics_steps as f64 / bare_s,
        "ratio_generation_to_bare_physics": one_s / bare_s,
        "attempts_per_s_1_worker": attempts.len() as f64 / one_s,
        "attempts_per_s_2_workers": attempts.len() as f64 / two_s,
        "speedup_2_workers": one_s / two_s,
        "bare_replay_final_state_max_abs_diff": worst_final_state_diff,
        "end_to_end_1_worker_s": e2e_one_s,
        "end_to_end_2_workers_s": e2e_two_s,
        "end_to_end_speedup_2_workers": e2e_one_s / e2e_two_s,
        "end_to_end_1_and_2_workers_identical_datasets": identical,
        "ratio_end_to_end_to_bare_physics": e2e_one_s / bare_s,
        "ratio_end_to_end_to_engine_loop": e2e_one_s / one_s,
        "end_to_end_successes": e2e_one.successes,
        "end_to_end_1_worker_peak_rss_mib": e2e_one_peak,
        "early_abort": early,
        "cameras": cameras,
        "peak_rss_mib": peak_rss_mib(),
    });
    outln!("{}", serde_json::to_string_pretty(&report)?);
    Ok(())
}
