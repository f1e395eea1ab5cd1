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
