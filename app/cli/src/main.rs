//! `mimicgen`: turn a handful of robot demonstrations into large datasets (MimicGen, CoRL 2023).

use std::process::ExitCode;

use anyhow::Context as _;
use clap::{Parser, Subcommand};
use exit::outln;

mod annotate;
mod app;
mod bench_app;
mod bench_io;
mod bench_render;
mod bench_serve;
mod bench_sim;
mod bench_transit;
mod coverage;
mod demos;
mod doctor;
mod exit;
mod export;
mod generate;
mod info;
mod merge;
mod prepare;
mod replay;
mod serve;
mod spec;
mod two_arm;
mod view;

/// Turn a handful of robot demonstrations into large, diverse training datasets.
///
/// MimicGen splits each source demo into object-centric subtask segments, re-targets them to new
/// scenes, executes them with noise and keeps only the attempts that succeed.
#[derive(Parser)]
#[command(name = "mimicgen", version, propagate_version = true, after_help = format!("{EXAMPLES}\n\n{}", exit::TABLE))]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

const EXAMPLES: &str = "\
Examples:
  mimicgen spec check config_D0.json          validate a MimicGen experiment JSON or our TOML
  mimicgen spec convert config_D0.json        print the same task spec as TOML
  mimicgen tasks                              the tasks (stack, stack_three, square) and variants
  mimicgen generate --task stack --variant D0 --num-demos 100 --out stack_d0.hdf5
  mimicgen generate --task square --variant D1 --num-demos 1000 --out square_d1.hdf5
  mimicgen generate --action-noise 0.02 --nn-k 1:5   spec fields for one run (K:VALUE: subtask K)
  mimicgen doctor out/stack_d0.hdf5            why attempts failed, changes tested on the same attempts
  mimicgen info source_D0.hdf5                 demos, lengths, obs/action shapes, objects, signals
  mimicgen export generated.hdf5 --mcap out.mcap   poses, actions, labels for Foxglove
  mimicgen view generated.hdf5 --demo 3 --spawn     one demo in the Rerun viewer
  mimicgen replay out_failed.hdf5 --trace t.json    each attempt again, step by step (compare_physics.py)
  mimicgen app                                the inspection app in a window
  mimicgen serve                              the same app in a browser (headless servers, over SSH)";

#[derive(Subcommand)]
enum Command {
    /// Read, validate and convert task specs (MimicGen JSON or TOML).
    Spec {
        #[command(subcommand)]
        command: spec::SpecCommand,
    },
    /// Generate demonstrations in simulation (MuJoCo, robosuite-like Panda + OSC_POSE).
    Generate(Box<generate::GenerateArgs>),
    /// Subtask ends for source demos: proposed from the recording (--auto) or typed (--ends),
    /// written where MimicGen reads them.
    Annotate(annotate::AnnotateArgs),
    /// The inspection app: source demos, their timelines, subtask ends by hand or proposed,
    /// previews of attempts over new scenes, "try it" in simulation, a Rerun 3D view.
    #[command(after_help = "\
Examples:
  mimicgen app                                   # the bundled Stack D0 source demos
  mimicgen app my_sources.hdf5                   # MimicGen source demos, or a plain robomimic file
  mimicgen app --screen preview --try-it         # open on the preview screen and try attempt 0
  mimicgen app --run 100                         # start a 100-attempt run on the generate screen
  mimicgen app --run 20 --attempt 1              # then attempt 1, beside the nearest success if it failed
  mimicgen app core/sim/data/square_D0_source.hdf5 --run 3 --robot ur5e --cameras   # another arm, images
  mimicgen app --demo 3 --screenshot annotate.png  # the docs' screenshots (under Xvfb too)
  mimicgen app --screen preview --variant C0 --transit plan   # planned transit around the clutter
  mimicgen app --run 40 --action-noise 0.3 --doctor 120   # a noisy run, then the Doctor on it")]
    App(Box<app::AppArgs>),
    /// The inspection app in a browser, for machines without a display: serves the app and runs
    /// its backend here; open the printed URL (through `ssh -L 8080:localhost:8080 host`).
    Serve(serve::ServeArgs),
    /// Why a run's attempts failed and what to change: ranks the changes its failure causes
    /// point at and tests the best few against the run's own spec on the same attempts.
    Doctor(doctor::DoctorArgs),
    /// Record scripted source demos of a task (the bundled defaults are made this way).
    Demos(demos::DemosArgs),
    /// List the tasks, their variants and the arms.
    ///
    /// Every task is a task file (`core/sim/tasks/<task>.task.toml`: objects, placement per
    /// variant, signals and success from predicates, observation, demonstrator). Add your own
    /// without code: put `<name>.task.toml` (and its generation spec `<name>.toml`) in a
    /// directory and point MIMICGEN_TASK_DIR at it; `docs/tasks.md` has the format.
    #[command(
        after_help = "Examples:\n  mimicgen tasks\n  MIMICGEN_TASK_DIR=my_tasks mimicgen demos --task tower --out tower_sources.hdf5"
    )]
    Tasks,
    /// Show a dataset's demos in the Rerun viewer (3D scene, paths by subtask, signals).
    View(view::ViewArgs),
    /// Support coverage and histograms of a dataset's initial scenes (the paper's bias analysis).
    Coverage(coverage::CoverageArgs),
    /// Turn a plain robomimic dataset into MimicGen source demos by replaying its states.
    Prepare(prepare::PrepareArgs),
    /// Add camera observations to a dataset from its stored states (robomimic's states-to-obs).
    Render(prepare::RenderArgs),
    /// Replay a dataset's demos in our simulator (stored targets closed loop, or actions open
    /// loop): did they succeed again, and per step what the physics did (--trace).
    Replay(replay::ReplayArgs),
    /// Measure generation against bare physics stepping and across worker counts.
    BenchSim(bench_sim::BenchSimArgs),
    /// Milliseconds per camera frame, drawn several ways, and whether they give the same pixels.
    BenchRender(bench_render::BenchRenderArgs),
    /// Interpolated against planned transit on the same attempts: rates, obstacle contacts,
    /// planning time (the cluttered C0 variants by default).
    BenchTransit(bench_transit::BenchTransitArgs),
    /// Compile the MJCF on stdin into the model cache (`$MIMICGEN_CACHE/models`); run by this
    /// program itself so that MuJoCo's compiler memory is a child's, not the run's.
    #[command(hide = true)]
    CompileModel,
    /// Read FILE's HDF5 structure and attributes (no dataset values); exit 0 when read, 1 when
    /// refused. The app and `mimicgen serve` run it as a child before reading a file a user chose:
    /// a damaged header that crashes libhdf5 then ends this child, not them.
    #[command(hide = true)]
    Vet {
        /// The file.
        file: std::path::PathBuf,
    },
    /// Measure the app's frame time with a file loaded, and the time until it is browsable.
    BenchApp(bench_app::BenchAppArgs),
    /// Measure `mimicgen serve` under load: N tabs opening, scrubbing, previewing and trying
    /// while a run goes on; request latency, errors, memory.
    BenchServe(bench_serve::BenchServeArgs),
    /// Summarise a robomimic / MimicGen HDF5 dataset.
    Info(info::InfoArgs),
    /// Join the shards of a run (`generate --shard i/K`) into the dataset of the whole run.
    #[command(after_help = "\
Examples:
  mimicgen generate --num-demos 1000 --seed 7 --shard 0/2 --out shards/s0.hdf5   # on machine A
  mimicgen generate --num-demos 1000 --seed 7 --shard 1/2 --out shards/s1.hdf5   # on machine B
  mimicgen merge shards/s0.hdf5 shards/s1.hdf5 --out stack.hdf5

Shard i makes the attempts whose index is i modulo K; each attempt depends only on the run seed
and its index, so the merged dataset equals `mimicgen generate --num-demos 1000 --seed 7` (same
demos, arrays, masks, failed attempts and report counts), also with --guarantee (every shard
runs to its own --num-demos successes; the merge keeps the whole run's first ones). Each shard's
folder must hold its dataset, its .json report, its .attempts.jsonl log and, with --keep-failed,
its _failed.hdf5.")]
    Merge(merge::MergeArgs),
    /// Export a dataset: to MCAP for Foxglove (poses, actions, labels), or to a LeRobot dataset
    /// (parquet frames, camera streams as MP4, meta/) that LeRobot's loaders read.
    #[command(after_help = "\
Examples:
  mimicgen export out/stack_d0.hdf5 --mcap out/stack_d0.mcap
  mimicgen export out/stack_cams.hdf5 --lerobot out/stack_lerobot     # LeRobot v3.0 dataset directory
  mimicgen export out/stack_cams.hdf5 --lerobot out/lr --state-keys robot0_eef_pos,robot0_gripper_qpos

Load the LeRobot export in Python:
  from lerobot.datasets.lerobot_dataset import LeRobotDataset   # or ledataset.datasets.lerobot_dataset
  ds = LeRobotDataset(\"local/stack\", root=\"out/stack_lerobot\")
  ds[0][\"observation.images.agentview\"]   # (3, 84, 84) float in [0, 1]

Every obs/<camera>_image of the dataset (generate --cameras) becomes the video feature
observation.images.<camera> (H.264, encoded by the ffmpeg scripts/setup.sh installs).")]
    Export(export::ExportArgs),
    /// Measure HDF5 write and read of a synthetic dataset (seconds and peak memory).
    BenchIo(bench_io::BenchIoArgs),
}

/// Refuses to write `out` onto the command's own `input` (ever) or over an existing file (unless
/// `overwrite`): an existing output is never replaced without asking.
///
/// # Errors
/// Naming the output and what to do.
pub(crate) fn check_output(out: &std::path::Path, input: Option<&std::path::Path>, overwrite: bool) -> anyhow::Result<()> {
    let same = |a: &std::path::Path, b: &std::path::Path| a.canonicalize().is_ok_and(|a| b.canonicalize().is_ok_and(|b| a == b));
    if let Some(input) = input
        && same(out, input)
    {
        exit::usage!("{}: is the input; choose another output", out.display());
    }
    if out.exists() && !overwrite {
        exit::usage!("{}: exists; {}", out.display(), mimicgen_pipeline::FrontEnd::Cli.output_exists_advice(false));
    }
    Ok(())
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    if let Command::Generate(args) = &cli.command
        && args.renders_on_every_core()
        && std::env::var_os("LP_NUM_THREADS").is_none()
    {
        #[allow(unsafe_code)]
        // SAFETY: no other thread has started yet, so none reads the environment meanwhile.
        unsafe {
            std::env::set_var("LP_NUM_THREADS", "0");
        }
    }
    if let Ok(me) = std::env::current_exe() {
        mimicgen_sim::model_cache::compile_in_child(me);
    }
    match run(cli) {
        Ok(code) => code,
        Err(e) if exit::closed_pipe(&e) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {}", exit::message(&e));
            ExitCode::from(exit::code(&e))
        }
    }
}

fn run(cli: Cli) -> anyhow::Result<ExitCode> {
    match cli.command {
        Command::Spec { command } => spec::run(command),
        Command::Info(args) => info::run(args),
        Command::Export(args) => export::run(args),
        Command::Merge(args) => merge::run(args),
        Command::BenchIo(args) => {
            bench_io::run(args)?;
            Ok(ExitCode::SUCCESS)
        }
        Command::Generate(args) => {
            generate::generate(&args)?;
            Ok(ExitCode::SUCCESS)
        }
        Command::Demos(args) => {
            demos::demos(&args)?;
            Ok(ExitCode::SUCCESS)
        }
        Command::App(args) => {
            app::run(*args)?;
            Ok(ExitCode::SUCCESS)
        }
        Command::Serve(args) => {
            serve::run(args)?;
            Ok(ExitCode::SUCCESS)
        }
        Command::Doctor(args) => {
            doctor::run(&args)?;
            Ok(ExitCode::SUCCESS)
        }
        Command::Annotate(args) => {
            annotate::run(&args)?;
            Ok(ExitCode::SUCCESS)
        }
        Command::Coverage(args) => {
            coverage::run(&args)?;
            Ok(ExitCode::SUCCESS)
        }
        Command::Prepare(args) => {
            prepare::prepare(&args)?;
            Ok(ExitCode::SUCCESS)
        }
        Command::Render(args) => {
            prepare::render(&args)?;
            Ok(ExitCode::SUCCESS)
        }
        Command::Replay(args) => {
            replay::run(&args)?;
            Ok(ExitCode::SUCCESS)
        }
        Command::CompileModel => {
            let mut xml = String::new();
            std::io::Read::read_to_string(&mut std::io::stdin(), &mut xml).context("reading the MJCF from stdin")?;
            mimicgen_sim::scene::store_compiled(&xml).map_err(|e| anyhow::anyhow!("compiling the scene: {e}"))?;
            Ok(ExitCode::SUCCESS)
        }
        Command::Vet { file } => Ok(match mimicgen_io::tree::vet(&file) {
            Ok(_) => ExitCode::SUCCESS,
            Err(e) => {
                eprintln!("mimicgen vet: {e}");
                ExitCode::from(1)
            }
        }),
        Command::BenchRender(args) => {
            bench_render::run(&args)?;
            Ok(ExitCode::SUCCESS)
        }
        Command::BenchSim(args) => {
            bench_sim::run(&args)?;
            Ok(ExitCode::SUCCESS)
        }
        Command::BenchTransit(args) => {
            bench_transit::run(&args)?;
            Ok(ExitCode::SUCCESS)
        }
        Command::BenchApp(args) => {
            bench_app::run(&args)?;
            Ok(ExitCode::SUCCESS)
        }
        Command::BenchServe(args) => {
            bench_serve::run(&args)?;
            Ok(ExitCode::SUCCESS)
        }
        Command::View(args) => {
            view::view(&args)?;
            Ok(ExitCode::SUCCESS)
        }
        Command::Tasks => {
            for t in mimicgen_sim::registry::tasks() {
                outln!("{:<21} variants {:<10} {}", t.name, t.variants.join(", "), t.description);
            }
            for t in mimicgen_sim::two_arm::TwoArmTask::ALL {
                outln!("{:<21} variants {:<10} two arms: {}", t.name(), t.variants().join(", "), t.description());
            }
            for b in mimicgen_sim::registry::broken() {
                outln!("{:<21} BROKEN: {}", b.name, b.error);
            }
            outln!();
            for r in mimicgen_sim::robot::ROBOTS {
                outln!(
                    "robot {:<7} robosuite's {} with its default gripper (generate --robot {}): {}",
                    r.name,
                    r.robosuite_name,
                    r.name,
                    r.status
                );
            }
            Ok(ExitCode::SUCCESS)
        }
    }
}
