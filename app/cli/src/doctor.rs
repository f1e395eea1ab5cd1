//! `mimicgen doctor`: why a run's attempts failed, what to change, and whether the change helps,
//! tested on the same attempts.

use std::path::PathBuf;
use std::sync::atomic::AtomicBool;

use anyhow::Context as _;
use indicatif::{ProgressBar, ProgressStyle};
use mimicgen_pipeline::doctor::{DoctorConfig, DoctorEvent, doctor};
use mimicgen_run::doctor::{Diagnosis, Verdict};

use crate::exit::outln;

/// Arguments of `mimicgen doctor`.
#[derive(clap::Args, Debug)]
#[command(after_help = "\
Examples:
  mimicgen generate --task nut_assembly --num-demos 200 --out out/nut.hdf5
  mimicgen doctor out/nut.hdf5                      # suggestions, the best 3 tested on 100 attempts each
  mimicgen doctor out/nut.json --budget 1200 --top 5   # more attempts: narrower intervals
  mimicgen doctor out/nut.json --json out/nut_doctor.json
  mimicgen doctor out/nut.json --check 1000          # then the best change on 1000 fresh attempts

Reads the run's report (RUN.json, written beside RUN.hdf5 by `mimicgen generate`): its failure
causes by subtask (grasp missed, grasp slipped, arm lagged, object moved, ran out of steps,
success unmet) and the source demos that never led to a success. From them it ranks changes to
the run's spec, most failures addressed first: exclude the never-succeeding source demos, less
action noise where grasps miss or slip, the nearest-neighbour source selection where grasps miss,
more interpolation steps or planned transit where the arm lags or knocks the object, a later
subtask end where a subtask runs out of steps.

It then runs the run's own spec and each of the --top best changes on the same attempts (the
run's seed; the attempt indices right after the run's last, which did not choose the
suggestions): every attempt has the same scene in every arm, so each change is compared pair by
pair. Each gets its rate, the difference to the run's spec with a 95 % interval, and a verdict:
helps (the interval is above zero), hurts (below) or not proven (it holds zero). A change that
does not help is reported as such. The best change that helps comes with the `mimicgen generate`
command that makes the run again with it. Nothing is written but --json; the same run and budget
give the same diagnosis on any number of workers.")]
pub struct DoctorArgs {
    /// The run: its report (`RUN.json`) or its dataset (`RUN.hdf5`, with the report beside it).
    run: PathBuf,
    /// Attempts to simulate in all, the run's own spec included (each of the --top + 1 arms
    /// gets an equal share). The doctor takes about as long as a run of this many attempts.
    #[arg(long, default_value_t = 400)]
    budget: usize,
    /// How many of the best-ranked changes to test.
    #[arg(long, default_value_t = 3)]
    top: usize,
    /// Worker threads, each with its own simulator.
    #[arg(long, default_value_t = std::thread::available_parallelism().map_or(1, std::num::NonZero::get))]
    workers: usize,
    /// Then check the best change (the winner, else the largest difference) on this many fresh
    /// attempts: the run's spec and the change on attempts 0..N of the run's seed plus one,
    /// paired. 0: no check.
    #[arg(long, default_value_t = 0, value_name = "N")]
    check: usize,
    /// Also write the diagnosis as JSON here.
    #[arg(long)]
    json: Option<PathBuf>,
    /// Replace the --json file if it exists.
    #[arg(long)]
    overwrite: bool,
}

/// Runs `mimicgen doctor`.
///
/// # Errors
/// An unreadable report, inputs of the run that are gone, a simulator failure, an unwritable --json.
pub fn run(args: &DoctorArgs) -> anyhow::Result<()> {
    // Refused before the trials, not after them.
    if let Some(json) = &args.json {
        crate::check_output(json, Some(&args.run), args.overwrite)?;
    }
    let config = DoctorConfig { run: args.run.clone(), budget: args.budget, top: args.top, workers: args.workers, check: args.check };
    let bar = ProgressBar::hidden();
    bar.set_style(
        ProgressStyle::with_template("{spinner} {elapsed_precise} [{bar:30}] {pos}/{len} {msg} ETA {eta}")
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    let (mut per_arm, mut checking) = (0, false);
    // In a log (a batch job) a bar draws nothing: a line per tenth of each arm instead.
    let terminal = std::io::IsTerminal::is_terminal(&std::io::stderr());
    let cancel = AtomicBool::new(false);
    let diagnosis = doctor(&config, &cancel, |event| match event {
        DoctorEvent::Started { suggestions, arms, attempts } => {
            per_arm = *attempts;
            eprintln!("{} suggestion(s); testing {} on {attempts} attempts each, beside the run's own spec", suggestions.len(), arms - 1);
            bar.set_draw_target(indicatif::ProgressDrawTarget::stderr());
            bar.set_length((arms * attempts) as u64);
        }
        DoctorEvent::Checking { trial, attempts } => {
            bar.finish_and_clear();
            eprintln!("checking change {} on {attempts} fresh attempts", trial + 1);
            checking = true;
            per_arm = *attempts;
            bar.reset();
            bar.set_length((2 * attempts) as u64);
        }
        DoctorEvent::Attempt { arm, done, successes } => {
            bar.set_position((arm * per_arm + done) as u64);
            let name = match (*arm, checking) {
                (0, _) => "the run's spec".to_owned(),
                (_, true) => "the change".to_owned(),
                (k, false) => format!("change {k}"),
            };
            if !terminal && (done * 10 % per_arm.max(1) < 10 || *done == per_arm) {
                eprintln!("progress {name}: {successes} of {done} of {per_arm}");
            }
            bar.set_message(format!("{name}: {successes} of {done}"));
        }
    })?;
    bar.finish_and_clear();
    print(&diagnosis)?;
    if let Some(path) = &args.json {
        std::fs::write(path, serde_json::to_string_pretty(&diagnosis)?).with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(())
}

#[allow(clippy::cast_precision_loss)] // attempt counts are far below 2^52
fn print(d: &Diagnosis) -> anyhow::Result<()> {
    let pct = |successes: usize| 100.0 * successes as f64 / d.attempts.max(1) as f64;
    outln!("{} {}: {:.1} % in the run ({})", d.task, d.variant, 100.0 * d.run_rate, d.report);
    if d.suggestions.is_empty() {
        outln!("no failure cause points at a change: nothing to suggest");
        return Ok(());
    }
    outln!("\nsuggestions, most failures addressed first:");
    for (i, s) in d.suggestions.iter().enumerate() {
        outln!("  {}. {:<44} {} ({} failures: {})", i + 1, s.flags(), s.what, s.addresses, s.why);
    }
    outln!(
        "\ntested on attempts {}..{} (seed {}): the run's spec {:.1} %",
        d.first_attempt,
        d.first_attempt + d.attempts,
        d.seed,
        pct(d.base_successes)
    );
    for (i, t) in d.trials.iter().enumerate() {
        let p = &t.paired;
        outln!(
            "  {}. {:<44} {:>5.1} %  {:<28} gained {}, lost {}: {}",
            i + 1,
            t.suggestion.flags(),
            pct(p.changed_successes),
            p.interval(),
            p.gained,
            p.lost,
            t.verdict.words()
        );
    }
    if let Some(check) = &d.check
        && let Some(t) = d.trials.get(check.trial)
    {
        let p = &check.paired;
        let rate = |n: usize| 100.0 * n as f64 / p.attempts.max(1) as f64;
        outln!(
            "\nchecked on {} fresh attempts (seed {}): {} {:.1} % -> {:.1} %, {}, gained {}, lost {}: {}",
            p.attempts,
            check.seed,
            t.suggestion.flags(),
            rate(p.base_successes),
            rate(p.changed_successes),
            p.interval(),
            p.gained,
            p.lost,
            check.verdict.words()
        );
    }
    match d.best() {
        Some(best) => {
            outln!("\nbest: {} ({:+.1} points); the run again with it:", best.suggestion.what, 100.0 * best.paired.difference);
            outln!("  {}", best.command);
        }
        None => {
            let hurt = d.trials.iter().filter(|t| t.verdict == Verdict::Hurts).count();
            outln!("\nno change was shown to help on {} attempts ({hurt} hurt); a larger --budget narrows the intervals", d.attempts);
        }
    }
    Ok(())
}
