//! `mimicgen bench-sim`: what generation costs on the MuJoCo backend, as ratios measured in one run.

use std::ops::ControlFlow;
use std::sync::Arc;
use std::time::Instant;

use anyhow::Context as _;
use mimicgen_engine::{Attempt, Generator, TaskSpec};
use mimicgen_sim::{Scene, SimEnv, registry};
use serde_json::json;

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
}

/// Peak resident memory of this process so far (Linux `VmHWM`), in MiB.
#[must_use]
pub fn peak_rss_mib() -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let kib: f64 = status.lines().find(|l| l.starts_with("VmHWM:"))?.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib / 1024.0)
}

/// Runs the benchmark and prints a JSON report.
///
/// # Errors
/// As `mimicgen generate`.
pub fn run(args: &BenchSimArgs) -> anyhow::Result<()> {
    let task = registry::task(&args.task, &args.variant).map_err(anyhow::Error::msg)?;
    let mut spec = TaskSpec::from_toml_str(registry::default_spec_toml(task.name()).unwrap_or_default(), "bundled spec")?;
    spec.generation.num_trials = args.attempts;
    let source = crate::generate::bundled_source(task.name(), "D0");
    let sources = mimicgen_io::read_source_dataset(&source, &spec.source).with_context(|| source.display().to_string())?;
    let scene = Arc::new(Scene::for_task(task.as_ref())?);
    let generator = Generator::new(spec, sources)?;
    let timed = |workers: usize| -> anyhow::Result<(f64, Vec<Attempt>)> {
        let mut envs: Vec<SimEnv> = (0..workers).map(|_| SimEnv::new(Arc::clone(&scene), Arc::clone(&task))).collect();
        let mut attempts = Vec::new();
        let started = Instant::now();
        mimicgen_engine::run(&generator, &mut envs, |a, _| {
            attempts.push(a);
            ControlFlow::Continue(())
        })?;
        Ok((started.elapsed().as_secs_f64(), attempts))
    };
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
        recorded.push((a.initial_state.clone(), env.take_controls()));
    }
    env.record_controls(false);
    let started = Instant::now();
    for (state, controls) in &recorded {
        env.replay_controls_bare(state, controls).map_err(|e| anyhow::anyhow!("{e}"))?;
    }
    let bare_s = started.elapsed().as_secs_f64();
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
        "peak_rss_mib": peak_rss_mib(),
    });
    println!("{}", serde_json::to_string_pretty(&report)?);
    Ok(())
}
