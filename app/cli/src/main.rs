//! `mimicgen`: turn a handful of robot demonstrations into large datasets (MimicGen, CoRL 2023).

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context as _;
use clap::{Parser, Subcommand};
use mimicgen_engine::TaskSpec;

/// Turn a handful of robot demonstrations into large, diverse training datasets.
///
/// MimicGen splits each source demo into object-centric subtask segments, re-targets them to new
/// scenes, executes them with noise and keeps only the attempts that succeed.
#[derive(Parser)]
#[command(name = "mimicgen", version, propagate_version = true, after_help = EXAMPLES)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

const EXAMPLES: &str = "\
Examples:
  mimicgen spec check config_D0.json          validate a MimicGen experiment JSON or our TOML
  mimicgen spec convert config_D0.json        print the same task spec as TOML
  mimicgen generate --task stack --variant D0 --num-demos 100 --out stack_d0.hdf5";

#[derive(Subcommand)]
enum Command {
    /// Read, validate and convert task specs (MimicGen JSON or TOML).
    Spec {
        #[command(subcommand)]
        command: SpecCommand,
    },
    /// Generate demonstrations in simulation.
    Generate {
        /// Task to generate (see `mimicgen tasks`).
        #[arg(long, default_value = "stack")]
        task: String,
        /// Task variant (reset distribution), e.g. D0 or D1.
        #[arg(long, default_value = "D0")]
        variant: String,
        /// Number of attempts (or successes with a guarantee config).
        #[arg(long, default_value_t = 10)]
        num_demos: usize,
        /// Run seed: the same seed gives the same dataset.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Output dataset.
        #[arg(long, default_value = "out/generated.hdf5")]
        out: PathBuf,
    },
}

#[derive(Subcommand)]
enum SpecCommand {
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

fn main() -> ExitCode {
    let cli = Cli::parse();
    match run(cli) {
        Ok(code) => code,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

fn run(cli: Cli) -> anyhow::Result<ExitCode> {
    match cli.command {
        Command::Spec { command: SpecCommand::Check { file } } => {
            let spec = TaskSpec::load(&file).with_context(|| format!("loading {}", file.display()))?;
            println!("{}: task {:?}, {} subtasks", file.display(), spec.name, spec.subtasks.len());
            for (i, s) in spec.subtasks.iter().enumerate() {
                println!(
                    "  subtask {i}: relative to {:<8} ends on {:<10} offsets {:<10} selection {} , noise {}, interp {} + fixed {}",
                    s.object_ref.as_deref().unwrap_or("world"),
                    s.term_signal.as_deref().unwrap_or("demo end"),
                    s.term_offset_range.map_or_else(|| "-".to_owned(), |(a, b)| format!("[{a}, {b}]")),
                    s.selection.name(),
                    s.action_noise,
                    s.num_interpolation_steps,
                    s.num_fixed_steps
                );
            }
            let g = &spec.generation;
            println!(
                "  generation: {} {}, per-subtask selection {}, interpolate from last target {}, seed {}",
                g.num_trials,
                if g.guarantee { "successes" } else { "attempts" },
                g.select_src_per_subtask,
                g.interpolate_from_last_target_pose,
                g.seed
            );
            Ok(ExitCode::SUCCESS)
        }
        Command::Spec { command: SpecCommand::Convert { file } } => {
            let spec = TaskSpec::load(&file).with_context(|| format!("loading {}", file.display()))?;
            print!("{}", spec.to_toml_string()?);
            Ok(ExitCode::SUCCESS)
        }
        Command::Generate { task, variant, .. } => {
            eprintln!(
                "mimicgen generate --task {task} --variant {variant}: the MuJoCo backend is not built yet.\n\
                 Built so far: the engine (segmentation, selection, transforms, the generation loop) and task specs;\n\
                 try `mimicgen spec check <config.json>`."
            );
            Ok(ExitCode::from(2))
        }
    }
}
