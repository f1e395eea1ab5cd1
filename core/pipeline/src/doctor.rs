//! The run doctor: reads a run's report, ranks the changes its failure causes point at
//! ([`mimicgen_run::doctor::suggest`]) and tests the best few in simulation on the same attempts
//! as the run's own spec: the same seed and the same attempt indices, so each attempt's scene is
//! the same in every arm and the comparison is paired. The attempts tested are the ones after the
//! run's last (the run's own attempts chose the suggestions; testing on them would flatter them).
//! Nothing is written.

use std::ops::ControlFlow;
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;

use mimicgen_engine::{Generator, RunControl};
use mimicgen_run::doctor::{Check, Diagnosis, Paired, Suggestion, Trial, rerun_config, suggest};

use crate::{Pipeline, PipelineError, Report, SpecOverrides, sibling};

/// What to test and how much.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DoctorConfig {
    /// The run: its report (`RUN.json`) or its dataset (`RUN.hdf5`, the report beside it).
    pub run: PathBuf,
    /// Attempts to simulate in all, the run's own spec included: each arm gets
    /// `budget / (tested + 1)`. It bounds the time: the doctor's cost is about `budget` attempts
    /// of the run.
    pub budget: usize,
    /// How many of the best-ranked suggestions to test.
    pub top: usize,
    /// Worker threads, each with its own simulator (the results do not depend on it).
    pub workers: usize,
    /// Then run the winner (else the trial with the largest difference) and the run's spec on
    /// this many fresh attempts (the run's seed plus one), paired: 0 for none.
    pub check: usize,
}

/// What the doctor is doing, for a progress bar.
#[derive(Debug, Clone, PartialEq)]
pub enum DoctorEvent {
    /// Suggestions ranked; `arms` arms (the run's spec first) of `attempts` each follow.
    Started {
        /// Every suggestion, ranked.
        suggestions: Vec<Suggestion>,
        /// Arms to run: the run's spec, then each tested suggestion.
        arms: usize,
        /// Attempts per arm.
        attempts: usize,
    },
    /// The trials are done; `trial` is checked on `attempts` fresh attempts of each side
    /// (the run's spec is arm 0 again, the change arm 1).
    Checking {
        /// The trial checked.
        trial: usize,
        /// Attempts per side.
        attempts: usize,
    },
    /// One more attempt of arm `arm` decided.
    Attempt {
        /// 0: the run's spec; k: the k-th suggestion (in the check, 1: the change checked).
        arm: usize,
        /// Attempts of the arm decided so far.
        done: usize,
        /// Of those, successes.
        successes: usize,
    },
}

/// Reads a run's report: `path` itself when it is JSON, else the `.json` beside the dataset.
///
/// # Errors
/// [`PipelineError::Input`] naming the file when it is missing or is not a run report.
pub fn read_report(path: &Path) -> Result<(Report, PathBuf), PipelineError> {
    let json =
        if path.extension().is_some_and(|e| e.eq_ignore_ascii_case("json")) { path.to_path_buf() } else { sibling(path, "", "json") };
    let label = json.display().to_string();
    let text = std::fs::read_to_string(&json).map_err(|e| {
        let hint = if json == path { String::new() } else { format!(" (the report `mimicgen generate` writes beside {})", path.display()) };
        PipelineError::input(label.clone(), "", format!("cannot read the run's report{hint}: {e}"))
    })?;
    let report: Report = serde_json::from_str(&text)
        .map_err(|e| PipelineError::input(label.clone(), "", format!("is not a `mimicgen generate` report: {e}")))?;
    // A two-arm run's report names its task; the doctor reads one-arm runs.
    if mimicgen_sim::two_arm::TwoArmTask::from_name(&report.task).is_some() {
        return Err(PipelineError::input(
            label,
            "task",
            format!("{} is a two-arm run: the doctor reads one-arm runs only so far", report.task),
        ));
    }
    Ok((report, json))
}

/// Diagnoses a run: ranks its suggestions and tests the best `config.top` against its own spec.
/// Deterministic: the same run and budget give the same diagnosis, whatever `workers`.
///
/// # Errors
/// An unreadable report, inputs the run named that are gone or changed, a budget too small for
/// one attempt per arm, a fatal simulator error. Cancelled, it stops with
/// [`PipelineError::Input`] on the field `cancel`.
pub fn doctor(config: &DoctorConfig, cancel: &AtomicBool, mut on_event: impl FnMut(&DoctorEvent)) -> Result<Diagnosis, PipelineError> {
    let (report, report_path) = read_report(&config.run)?;
    let label = report_path.display().to_string();
    if report.attempts == 0 {
        return Err(PipelineError::input(label, "attempts", "the run made no attempts: nothing to diagnose"));
    }
    let workers = config.workers.max(1);
    let pipeline = Pipeline::prepare(&crate::RunConfig { workers, ..rerun_config(&report, &SpecOverrides::default(), PathBuf::new()) })?;
    let suggestions = suggest(&report, pipeline.generator().spec());
    let tested = config.top.min(suggestions.len());
    let attempts = config.budget / (tested + 1);
    if attempts == 0 {
        return Err(PipelineError::input(
            "",
            "--budget",
            format!("{} is less than one attempt for each of the {} arms", config.budget, tested + 1),
        ));
    }
    on_event(&DoctorEvent::Started { suggestions: suggestions.clone(), arms: tested + 1, attempts });
    let first = report.attempts;
    // Attempts `first..first + attempts` of `seed` with `change`, reported as arm `index`.
    let arm = |index: usize,
               change: &SpecOverrides,
               (seed, first, attempts): (u64, usize, usize),
               on_event: &mut dyn FnMut(&DoctorEvent)|
     -> Result<Vec<bool>, PipelineError> {
        let mut spec = pipeline.generator().spec().clone();
        change.apply(&mut spec)?;
        spec.generation.seed = seed;
        spec.generation.num_trials = first + attempts;
        spec.generation.guarantee = false;
        spec.generation.max_attempts = 0;
        let generator =
            Generator::new(spec, pipeline.generator().dataset().clone()).map_err(|e| PipelineError::engine(label.clone(), e))?;
        let mut envs: Vec<_> = (0..workers).map(|_| pipeline.env()).collect();
        let mut outcomes = Vec::with_capacity(attempts);
        let control = RunControl { start: first, cancel: Some(cancel), ..RunControl::default() };
        mimicgen_engine::run_with(
            &generator,
            &mut envs,
            control,
            |_, _| Ok(()),
            |attempt, (), _| {
                outcomes.push(attempt.success);
                let successes = outcomes.iter().filter(|&&s| s).count();
                on_event(&DoctorEvent::Attempt { arm: index, done: outcomes.len(), successes });
                ControlFlow::Continue(())
            },
        )
        .map_err(|e| PipelineError::engine(label.clone(), e))?;
        if outcomes.len() < attempts {
            return Err(PipelineError::input("", "cancel", "the doctor was cancelled before its trials were done"));
        }
        Ok(outcomes)
    };
    let seed = report.seed;
    let base = arm(0, &SpecOverrides::default(), (seed, first, attempts), &mut on_event)?;
    let mut trials = Vec::with_capacity(tested);
    for (k, suggestion) in suggestions.iter().take(tested).enumerate() {
        let changed = arm(k + 1, &suggestion.change, (seed, first, attempts), &mut on_event)?;
        let paired = Paired::new(&base, &changed);
        let out = sibling(Path::new(&report.output), "_doctor", "hdf5");
        let args = rerun_config(&report, &suggestion.change, out).to_args();
        trials.push(Trial { suggestion: suggestion.clone(), paired, verdict: paired.verdict(), command: command_line(&args) });
    }
    let checked = Diagnosis::to_check(&trials).filter(|_| config.check > 0).and_then(|i| trials.get(i).map(|t| (i, &t.suggestion.change)));
    let check = match checked {
        Some((trial, change)) => {
            on_event(&DoctorEvent::Checking { trial, attempts: config.check });
            let fresh = (seed.wrapping_add(1), 0, config.check);
            let before = arm(0, &SpecOverrides::default(), fresh, &mut on_event)?;
            let after = arm(1, change, fresh, &mut on_event)?;
            let paired = Paired::new(&before, &after);
            Some(Check { trial, seed: fresh.0, paired, verdict: paired.verdict() })
        }
        None => None,
    };
    Ok(Diagnosis {
        check,
        report: label,
        task: report.task.clone(),
        variant: report.variant.clone(),
        run_rate: report.generation_rate,
        seed: report.seed,
        first_attempt: first,
        attempts,
        base_successes: base.iter().filter(|&&s| s).count(),
        suggestions,
        winner: Diagnosis::pick_winner(&trials),
        trials,
    })
}

/// `mimicgen generate ARGS`, each argument quoted for a POSIX shell where it needs it.
fn command_line(args: &[String]) -> String {
    let quoted: Vec<String> = args
        .iter()
        .map(|a| {
            if !a.is_empty() && a.chars().all(|c| c.is_ascii_alphanumeric() || "-_./:,=+@%".contains(c)) {
                a.clone()
            } else {
                format!("'{}'", a.replace('\'', r"'\''"))
            }
        })
        .collect();
    format!("mimicgen generate {}", quoted.join(" "))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_command_line_quotes_what_a_shell_would_split() {
        let args = ["--source".to_owned(), "my demos/s.hdf5".to_owned(), "--exclude-source".to_owned(), "2,6".to_owned()];
        assert_eq!(command_line(&args), "mimicgen generate --source 'my demos/s.hdf5' --exclude-source 2,6");
        assert_eq!(command_line(&["it's".to_owned()]), r"mimicgen generate 'it'\''s'");
    }
}
