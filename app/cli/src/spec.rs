//! `mimicgen spec`: read, validate and convert task specs (our TOML or MimicGen's JSON).

use std::path::PathBuf;
use std::process::ExitCode;

use crate::exit::{out, outln};

/// `mimicgen spec`'s subcommands.
#[derive(Debug, clap::Subcommand)]
pub enum SpecCommand {
    /// Validate a task spec and print a summary of its subtasks.
    Check {
        /// A `.toml` spec or a MimicGen experiment `.json`.
        file: PathBuf,
    },
    /// Print a task spec as TOML (e.g. to convert a MimicGen JSON config).
    Convert {
        /// A `.toml` spec or a MimicGen experiment `.json`.
        file: PathBuf,
    },
}

/// Runs `mimicgen spec <command>`.
///
/// # Errors
/// The spec's errors, naming file, line and field.
pub fn run(command: SpecCommand) -> anyhow::Result<ExitCode> {
    match command {
        SpecCommand::Check { file } => {
            if let Some(code) = check_two_arm(&file)? {
                return Ok(code);
            }
            let spec = mimicgen_pipeline::check_spec_file(&file)?;
            outln!("{}: task {:?}, {} subtasks", file.display(), spec.name, spec.subtasks.len());
            for (i, s) in spec.subtasks.iter().enumerate() {
                let transit = match s.transit {
                    mimicgen_engine::spec::Transit::Interpolate => {
                        format!("interp {} + fixed {}", s.num_interpolation_steps, s.num_fixed_steps)
                    }
                    mimicgen_engine::spec::Transit::Plan => format!("planned transit to {} m from the object", s.approach_m),
                };
                outln!(
                    "  subtask {i}: relative to {:<8} ends on {:<10} offsets {:<10} selection {} , noise {}, {transit}",
                    s.object_ref.as_deref().unwrap_or("world"),
                    s.term_signal.as_deref().unwrap_or("demo end"),
                    s.term_offset_range.map_or_else(|| "-".to_owned(), |(a, b)| format!("[{a}, {b}]")),
                    s.selection.name(),
                    s.action_noise,
                );
            }
            let g = &spec.generation;
            outln!(
                "  generation: {} {}, per-subtask selection {}, interpolate from last target {}, seed {}",
                g.num_trials,
                if g.guarantee { "successes" } else { "attempts" },
                g.select_src_per_subtask,
                g.interpolate_from_last_target_pose,
                g.seed
            );
            Ok(ExitCode::SUCCESS)
        }
        SpecCommand::Convert { file } => {
            // The loader's errors name the file and line themselves.
            let spec = mimicgen_engine::TaskSpec::load(&file)?;
            out!("{}", spec.to_toml_string()?);
            Ok(ExitCode::SUCCESS)
        }
    }
}

/// `mimicgen spec check` of a two-arm spec (a TOML file with `[[arm]]` tables): its arms' subtasks
/// and its ties; `None` for any other file.
fn check_two_arm(file: &std::path::Path) -> anyhow::Result<Option<ExitCode>> {
    let is_toml = file.extension().is_some_and(|e| e == "toml");
    let Some(text) = is_toml.then(|| std::fs::read_to_string(file).ok()).flatten() else { return Ok(None) };
    if !text.lines().any(|l| l.trim() == "[[arm]]") {
        return Ok(None);
    }
    let spec = mimicgen_engine::two_arm::TwoArmSpec::from_toml_str(&text, &file.display().to_string())?;
    outln!("{}: two-arm task {:?}", file.display(), spec.name);
    for (a, arm) in spec.arms.iter().enumerate() {
        outln!("  arm {a} ({}): {} subtasks", arm.name, arm.subtasks.len());
        for (k, s) in arm.subtasks.iter().enumerate() {
            outln!(
                "    subtask {k}: relative to {:<8} ends on {:<14} selection {}, noise {}, interp {}",
                s.object_ref.as_deref().unwrap_or("world"),
                s.term_signal.as_deref().unwrap_or("demo end"),
                s.selection.name(),
                s.action_noise,
                s.num_interpolation_steps
            );
        }
    }
    for c in spec.constraints() {
        match c {
            mimicgen_engine::two_arm::Constraint::Coordination((a, k), (b, j)) => {
                outln!("  coordination: arm {a} subtask {k} with arm {b} subtask {j}");
            }
            mimicgen_engine::two_arm::Constraint::Sequential { first: (a, k), later: (b, j) } => {
                outln!("  sequential: arm {b} subtask {j} after arm {a} subtask {k}");
            }
        }
    }
    Ok(Some(ExitCode::SUCCESS))
}
