//! `mimicgen`: turn a handful of robot demonstrations into large datasets (MimicGen, CoRL 2023).

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context as _;
use clap::{Parser, Subcommand};
use exit::{out, outln};
use mimicgen_io::info::DatasetInfo;
use mimicgen_io::{DemoReader, DemoSource as _, ReadOptions};

mod annotate;
mod app;
mod bench_app;
mod bench_io;
mod bench_render;
mod bench_sim;
mod bench_transit;
mod coverage;
mod exit;
mod generate;
mod prepare;
mod replay;
mod serve;
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
        command: SpecCommand,
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
  mimicgen app --screen preview --variant C0 --transit plan   # planned transit around the clutter")]
    App(Box<app::AppArgs>),
    /// The inspection app in a browser, for machines without a display: serves the app and runs
    /// its backend here; open the printed URL (through `ssh -L 8080:localhost:8080 host`).
    Serve(serve::ServeArgs),
    /// Record scripted source demos of a task (the bundled defaults are made this way).
    Demos(generate::DemosArgs),
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
    /// Measure the app's frame time with a file loaded, and the time until it is browsable.
    BenchApp(bench_app::BenchAppArgs),
    /// Summarise a robomimic / MimicGen HDF5 dataset.
    Info {
        /// The dataset.
        file: PathBuf,
        /// Print JSON instead of text.
        #[arg(long)]
        json: bool,
        /// Open a file an interrupted writer left behind (keeps its complete demos).
        #[arg(long)]
        recover: bool,
    },
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
    Merge {
        /// The shards' datasets, all K of them, in any order.
        #[arg(required = true, value_name = "SHARD")]
        shards: Vec<PathBuf>,
        /// Output dataset (the failed attempts go to OUT_failed.hdf5, the report to OUT.json).
        #[arg(long)]
        out: PathBuf,
        /// Replace existing outputs.
        #[arg(long)]
        overwrite: bool,
    },
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
    Export {
        /// The dataset.
        file: PathBuf,
        /// Output MCAP file.
        #[arg(long, required_unless_present = "lerobot")]
        mcap: Option<PathBuf>,
        /// Output LeRobot dataset directory (format v3.0).
        #[arg(long)]
        lerobot: Option<PathBuf>,
        /// LeRobot: observation keys concatenated into `observation.state`, in order.
        #[arg(long, value_delimiter = ',', default_value = "robot0_eef_pos,robot0_eef_quat,robot0_gripper_qpos,object")]
        state_keys: Vec<String>,
        /// LeRobot: the task instruction of every frame. Default: the task's, from env_args.
        #[arg(long)]
        instruction: Option<String>,
        /// LeRobot: the ffmpeg that encodes camera streams. Default: $MIMICGEN_FFMPEG, else the
        /// one scripts/setup.sh unpacked into the cache, else `ffmpeg` on the PATH.
        #[arg(long)]
        ffmpeg: Option<PathBuf>,
        /// Replace an existing output (the MCAP file, the LeRobot directory).
        #[arg(long)]
        overwrite: bool,
    },
    /// Measure HDF5 write and read of a synthetic dataset (seconds and peak memory).
    BenchIo {
        /// Number of demos.
        #[arg(long, default_value_t = 1000)]
        demos: usize,
        /// Steps per demo.
        #[arg(long, default_value_t = 150)]
        steps: usize,
        /// Directory for the temporary dataset (default: the system temp dir).
        #[arg(long)]
        dir: Option<PathBuf>,
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
        Command::Spec { command: SpecCommand::Check { file } } => {
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
        Command::Spec { command: SpecCommand::Convert { file } } => {
            // The loader's errors name the file and line themselves.
            let spec = mimicgen_engine::TaskSpec::load(&file)?;
            out!("{}", spec.to_toml_string()?);
            Ok(ExitCode::SUCCESS)
        }
        Command::Info { file, json, recover } => {
            let ds = DemoReader::open_with(&file, ReadOptions { recover })?;
            let info = DatasetInfo::of(&ds)?;
            if json {
                outln!("{}", serde_json::to_string_pretty(&info)?);
            } else {
                print_info(&info)?;
            }
            Ok(ExitCode::SUCCESS)
        }
        Command::Export { file, mcap, lerobot, state_keys, instruction, ffmpeg, overwrite } => {
            let ds = DemoReader::open_with(&file, ReadOptions::default())?;
            if let Some(mcap) = mcap {
                check_output(&mcap, Some(&file), overwrite)?;
                let summary = mimicgen_io::mcap_export::export(&ds, &mcap)?;
                outln!("{}: {} demos, {} steps at 20 Hz", mcap.display(), summary.demos, summary.steps);
                for (topic, n) in &summary.messages {
                    outln!("  {topic:<24} {n} messages");
                }
            }
            if let Some(out) = lerobot {
                let request = mimicgen_pipeline::lerobot::ExportRequest { state_keys: Some(state_keys), instruction, ffmpeg, overwrite };
                let bar = indicatif::ProgressBar::new(ds.demo_names().len() as u64).with_style(
                    indicatif::ProgressStyle::with_template("exporting {bar:30} {pos}/{len} episodes, {elapsed} ({eta} left)")
                        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
                );
                drop(ds);
                let summary = mimicgen_pipeline::lerobot::export(&file, &out, &request, |done, _| bar.set_position(done as u64))?;
                bar.finish_and_clear();
                outln!(
                    "{}: LeRobot {} dataset, {} episodes, {} frames at 20 fps",
                    summary.out,
                    mimicgen_io::lerobot::CODEBASE_VERSION,
                    summary.episodes,
                    summary.frames
                );
                let state: Vec<String> = summary.state.iter().map(|(k, n)| format!("{k} ({n})")).collect();
                outln!("  observation.state: {}", state.join(" + "));
                outln!("  task: {:?}", summary.task);
                for video in &summary.videos {
                    outln!("  {video}: H.264 video");
                }
            }
            Ok(ExitCode::SUCCESS)
        }
        Command::Merge { shards, out, overwrite } => {
            let bar = indicatif::ProgressBar::new(0).with_style(
                indicatif::ProgressStyle::with_template("merging {bar:30} {pos}/{len} attempts, {elapsed} ({eta} left)")
                    .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
            );
            let report = mimicgen_pipeline::merge::merge(&shards, &out, overwrite, |done, total| {
                bar.set_length(total as u64);
                bar.set_position(done as u64);
            })?;
            bar.finish_and_clear();
            outln!("{}", serde_json::to_string_pretty(&report)?);
            eprintln!(
                "merged {} shards: {} of {} attempts succeeded ({:.1} %) -> {}",
                shards.len(),
                report.successes,
                report.attempts,
                100.0 * report.generation_rate,
                report.output
            );
            Ok(ExitCode::SUCCESS)
        }
        Command::BenchIo { demos, steps, dir } => {
            bench_io::run(demos, steps, dir)?;
            Ok(ExitCode::SUCCESS)
        }
        Command::Generate(args) => {
            generate::generate(&args)?;
            Ok(ExitCode::SUCCESS)
        }
        Command::Demos(args) => {
            generate::demos(&args)?;
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
        Command::View(args) => {
            view::view(&args)?;
            Ok(ExitCode::SUCCESS)
        }
        Command::Tasks => {
            for t in mimicgen_sim::registry::tasks() {
                outln!("{:<21} variants {:<10} {}", t.name, t.variants.join(", "), t.description);
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

fn fmt_list(v: &[f64]) -> String {
    let parts: Vec<String> = v.iter().map(|x| format!("{x:.3}")).collect();
    format!("[{}]", parts.join(", "))
}

fn print_info(info: &DatasetInfo) -> anyhow::Result<()> {
    let l = &info.lengths;
    outln!("{}", info.file);
    let total = info.total_attr.map_or_else(String::new, |t| format!(" (data/total says {t})"));
    outln!("  demos {}, samples {}{total}", info.num_demos, info.num_samples);
    outln!("  lengths: mean {:.1}, std {:.1}, min {}, max {}", l.mean, l.std, l.min, l.max);
    outln!(
        "  env: {}, controller {}",
        info.env_name.as_deref().unwrap_or("(no env_args)"),
        info.controller_type.as_deref().unwrap_or("(unknown)")
    );
    outln!("  actions: {} dims, min {}, max {}", info.action_dim, fmt_list(&info.action_min), fmt_list(&info.action_max));
    if info.obs.is_empty() {
        outln!("  obs: (none)");
    }
    for (key, shape) in &info.obs {
        let dtype = info.obs_dtypes.get(key).map(String::as_str).unwrap_or_default();
        outln!("  obs/{key}: {shape:?}{}", if dtype == "float64" || dtype.is_empty() { String::new() } else { format!(" {dtype}") });
    }
    outln!("  objects: {}", if info.objects.is_empty() { "(none)".to_owned() } else { info.objects.join(", ") });
    for (name, s) in &info.signals {
        let f = &s.first_on_step;
        outln!(
            "  signal {name}: first 0->1 at step min {}, mean {:.1}, max {} ({} of {} demos){}",
            f.min,
            f.mean,
            f.max,
            f.count,
            s.demos,
            if s.never_on.is_empty() { String::new() } else { format!("; never on in {}", s.never_on.join(", ")) }
        );
    }
    if info.filter_keys.is_empty() {
        outln!("  filter keys: (none)");
    }
    for (key, n) in &info.filter_keys {
        outln!("  filter key {key}: {n} demos");
    }
    if info.report.is_mimicgen_source() {
        outln!("  MimicGen source: yes (datagen_info complete)");
    } else {
        outln!("  MimicGen source: no: {}", info.report);
    }
    Ok(())
}
