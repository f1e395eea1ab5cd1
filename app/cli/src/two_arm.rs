//! `mimicgen demos` and `mimicgen generate` for robosuite's two-arm tasks (`--task two_arm_lift`).

use std::path::Path;

use anyhow::Context as _;
use indicatif::{ProgressBar, ProgressStyle};
use mimicgen_engine::demonstrator::Style;
use mimicgen_pipeline::two_arm::{self, TwoArmEvent, TwoArmRun};

use crate::exit::outln;

/// Records scripted two-arm source demos, the operators moving in `style`.
///
/// # Errors
/// An unknown variant, a simulator failure, or a failure to write.
pub fn demos(task: &str, variant: &str, style: Style, num_demos: usize, seed: u64, out: &Path) -> anyhow::Result<()> {
    let task = two_arm::task(task, variant)?;
    if let Some(dir) = out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    let (path, tries) = two_arm::record_demos(task, variant, style, num_demos, seed, out, &mut |line| eprintln!("{line}"))?;
    eprintln!("wrote {num_demos} demos ({tries} tries) to {}", path.display());
    Ok(())
}

/// Runs a two-arm generation with a progress bar, prints its summary and writes it as
/// `<out>.json`.
///
/// # Errors
/// As [`two_arm::generate`], or a failure to write the report.
pub fn generate(run: &TwoArmRun, rerun: &crate::view::RerunArgs) -> anyhow::Result<()> {
    if let Some(dir) = run.out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    eprintln!(
        "generating with {} attempts of {} {} (two arms) on {} worker(s), seed {}",
        run.num_trials,
        run.task.name(),
        run.variant,
        run.workers,
        run.seed
    );
    let bar = ProgressBar::new(run.num_trials as u64);
    bar.set_style(
        ProgressStyle::with_template("{spinner} {elapsed_precise} [{bar:30}] {pos}/{len} {msg} ETA {eta}")
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    let scene = if rerun.is_set() { Some(run.task.scene()?) } else { None };
    let mut viz = match scene.as_ref() {
        Some(scene) => rerun.logger("mimicgen", scene)?,
        None => None,
    };
    let mut viz_error: Option<anyhow::Error> = None;
    let mut spec = None;
    let run_result = two_arm::run_and_report(run, &std::sync::atomic::AtomicBool::new(false), &mut |event| match event {
        TwoArmEvent::Started { spec: s, source_names } => {
            spec = Some(s.clone());
            if let Some(v) = viz.as_mut() {
                v.set_source_names(source_names.to_vec());
            }
        }
        TwoArmEvent::Attempt { attempt, attempts, successes, .. } => {
            bar.set_position(attempts as u64);
            bar.set_message(format!("{successes} successes"));
            if let (Some(v), Some(spec)) = (viz.as_mut(), spec.as_ref())
                && let Err(e) = v.log_two_arm_attempt(attempt, spec, (attempts, successes))
            {
                viz_error.get_or_insert_with(|| anyhow::anyhow!("logging attempt {} to Rerun: {e}", attempt.index));
                viz = None;
            }
        }
    });
    bar.finish_and_clear();
    if let Some(v) = viz {
        v.finish().context("flushing the Rerun recording")?;
    }
    if let Some(e) = viz_error {
        return Err(e);
    }
    let (summary, report) = run_result?;
    let seconds = report.wall_time_s;
    let rate = 100.0 * report.generation_rate;
    let report_path = mimicgen_pipeline::sibling(&run.out, "", "json");
    outln!(
        "{} {}: {} of {} attempts succeeded ({rate:.1} %) from {} source demos in {seconds:.0} s; wrote {} and {}",
        run.task.name(),
        run.variant,
        summary.successes,
        summary.attempts,
        summary.num_sources,
        summary.out.display(),
        report_path.display()
    );
    for (failure, count) in &summary.failures {
        outln!("  {count:>5}  {failure}");
    }
    Ok(())
}
