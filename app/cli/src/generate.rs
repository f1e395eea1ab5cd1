//! `mimicgen generate` and `mimicgen demos`: run the engine on the MuJoCo backend and write
//! robomimic datasets.

use std::collections::BTreeMap;
use std::ops::ControlFlow;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use anyhow::{Context as _, bail};
use indicatif::{ProgressBar, ProgressStyle};
use mimicgen_engine::demo::initial_object_poses;
use mimicgen_engine::{EngineError, Environment as _, Generator, TaskSpec};
use mimicgen_io::{DatagenInfo, DatasetWriter, DemoData, WriterOptions};
use mimicgen_sim::{Scene, SimEnv, Task, registry};
use rand::SeedableRng as _;
use serde_json::json;

/// Where the bundled scripted source demos of a task live.
#[must_use]
pub fn bundled_source(task: &str, variant: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("../../core/sim/data/{task}_{variant}_source.hdf5"))
}

/// Arguments of `mimicgen generate`.
#[derive(clap::Args, Debug)]
#[command(after_help = "\
Examples:
  mimicgen generate                                   # 100 attempts of Stack D0 from the bundled demos
  mimicgen generate --variant D1 --num-demos 1000 --workers 2 --out out/stack_d1.hdf5
  mimicgen generate --task square --variant D2 --num-demos 1000 --out out/square_d2.hdf5
  mimicgen generate --task stack_three --guarantee --num-demos 200 --out out/stack_three.hdf5
  mimicgen generate --source source_D0_prepared.hdf5 --config config_D0.json   # your MimicGen files

Successful attempts go to --out (robomimic layout, low-dim observations); with --keep-failed,
failed ones go to <out>_failed.hdf5. A JSON report (rate, per source demo, failures by subtask and
reason) is printed and written next to the dataset as <out>.json.")]
pub struct GenerateArgs {
    /// Task to generate (see `mimicgen tasks`).
    #[arg(long, default_value = "stack")]
    task: String,
    /// Task variant: the reset distribution new scenes are drawn from.
    #[arg(long, default_value = "D0")]
    variant: String,
    /// Attempts to make (successes to reach with --guarantee). Default: the spec's num_trials.
    #[arg(long)]
    num_demos: Option<usize>,
    /// Run seed: the same seed gives the same dataset, whatever --workers. Default: the spec's.
    #[arg(long)]
    seed: Option<u64>,
    /// Worker threads, each with its own simulator.
    #[arg(long, default_value_t = default_workers())]
    workers: usize,
    /// Output dataset.
    #[arg(long, default_value = "out/generated.hdf5")]
    out: PathBuf,
    /// Source demos (MimicGen source layout). Default: the task's bundled scripted demos.
    #[arg(long)]
    source: Option<PathBuf>,
    /// Task spec: our TOML or a MimicGen experiment JSON. Default: the task's bundled spec.
    #[arg(long)]
    config: Option<PathBuf>,
    /// Also write failed attempts (to `OUT_failed.hdf5` beside `--out`), up to the spec's max_num_failures.
    #[arg(long)]
    keep_failed: bool,
    /// Keep attempting until --num-demos successes.
    #[arg(long)]
    guarantee: bool,
    /// Hard cap on attempts with --guarantee.
    #[arg(long)]
    max_attempts: Option<usize>,
    /// Put this fraction of demos, drawn at random with the run seed, in a `mask/valid` filter key
    /// (the rest in `mask/train`).
    #[arg(long)]
    valid_fraction: Option<f64>,
    /// Rerun: where the recording goes and how much 3D scene it holds.
    #[command(flatten)]
    rerun: crate::view::RerunArgs,
}

fn default_workers() -> usize {
    std::thread::available_parallelism().map_or(1, std::num::NonZero::get)
}

/// The scene a run uses: the source file's own `model_file` when it has one (so generation happens
/// in the scene the demos were recorded in), else the task's composed scene.
fn scene_for(task: &dyn Task, model_xml: Option<&str>, origin: &Path) -> anyhow::Result<(Arc<Scene>, String)> {
    match model_xml {
        Some(xml) => {
            let assets = mimicgen_sim::assets::robosuite_assets_dir()?;
            let local = mimicgen_sim::assets::remap_asset_paths(xml, &assets);
            let scene = Scene::compile(&local, &format!("{} (model_file)", origin.display()), &task.objects(), 20.0)?;
            Ok((Arc::new(scene), xml.to_owned()))
        }
        None => {
            let assets = mimicgen_sim::assets::robosuite_assets_dir()?;
            let xml = mimicgen_sim::compose::compose_scene(&assets, &task.object_models(), task.table_top_z());
            let scene = Scene::compile(&xml, &format!("composed {} scene", task.name()), &task.objects(), 20.0)?;
            Ok((Arc::new(scene), xml))
        }
    }
}

fn io_err(e: &mimicgen_io::IoError) -> EngineError {
    EngineError::Io { path: String::new(), reason: e.to_string() }
}

fn sibling(out: &Path, suffix: &str, ext: &str) -> PathBuf {
    let stem = out.file_stem().map_or_else(|| "generated".into(), |s| s.to_string_lossy().into_owned());
    out.with_file_name(format!("{stem}{suffix}.{ext}"))
}

/// Runs `mimicgen generate`.
///
/// # Errors
/// Bad arguments, unreadable inputs, or a failure to write the outputs.
pub fn generate(args: &GenerateArgs) -> anyhow::Result<()> {
    let task = registry::task(&args.task, &args.variant).map_err(anyhow::Error::msg)?;
    let mut spec = match &args.config {
        Some(path) => TaskSpec::load(path)?,
        None => {
            TaskSpec::from_toml_str(registry::default_spec_toml(task.name()).unwrap_or_default(), &format!("bundled {} spec", task.name()))?
        }
    };
    let g = &mut spec.generation;
    if let Some(n) = args.num_demos {
        g.num_trials = n;
    }
    if let Some(seed) = args.seed {
        g.seed = seed;
    }
    g.keep_failed |= args.keep_failed;
    g.guarantee |= args.guarantee;
    if let Some(cap) = args.max_attempts {
        g.max_attempts = cap;
    }
    if args.workers == 0 {
        bail!("--workers must be at least 1");
    }
    let source_path = args.source.clone().unwrap_or_else(|| bundled_source(task.name(), "D0"));
    if !source_path.is_file() {
        bail!(
            "source demos {} not found (record them with `mimicgen demos --task {}`, or pass --source)",
            source_path.display(),
            task.name()
        );
    }
    let sources = mimicgen_io::read_source_dataset(&source_path, &spec.source)
        .with_context(|| format!("reading source demos {}", source_path.display()))?;
    let (scene, scene_xml) = scene_for(task.as_ref(), sources.demos.first().and_then(|d| d.sim.model_xml.as_deref()), &source_path)?;
    let env_args = registry::env_args_for_variant(sources.env_args.as_deref(), task.name(), &args.variant);
    let num_sources = sources.demos.len();
    let generator = Generator::new(spec.clone(), sources).with_context(|| format!("source demos {}", source_path.display()))?;
    let mut envs: Vec<SimEnv> = (0..args.workers).map(|_| SimEnv::new(Arc::clone(&scene), Arc::clone(&task))).collect();
    let mut obs_env = SimEnv::new(Arc::clone(&scene), Arc::clone(&task));
    let mut viz = args.rerun.logger("mimicgen", &scene)?;
    if let Some(v) = viz.as_mut() {
        v.log_demos(generator.dataset().demos.iter().enumerate()).context("logging the source demos to Rerun")?;
    }

    if let Some(dir) = args.out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    let options = WriterOptions {
        env_args: Some(env_args.clone()),
        compress_obs: true,
        valid_fraction: args.valid_fraction,
        split_seed: spec.generation.seed,
    };
    let mut writer = DatasetWriter::create(&args.out, options.clone())?;
    let failed_path = sibling(&args.out, "_failed", "hdf5");
    let mut failed_writer = if spec.generation.keep_failed {
        Some(DatasetWriter::create(&failed_path, WriterOptions { valid_fraction: None, ..options })?)
    } else {
        None
    };

    let settings = &spec.generation;
    let total = if settings.guarantee { settings.num_trials } else { settings.attempt_cap() };
    let bar = ProgressBar::new(total as u64);
    bar.set_style(
        ProgressStyle::with_template("{spinner} {elapsed_precise} [{bar:30}] {pos}/{len} {msg} ETA {eta}")
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    eprintln!(
        "generating {} {} {} from {} source demos in {} on {} worker(s), seed {}",
        if settings.guarantee { "until" } else { "with" },
        settings.num_trials,
        if settings.guarantee { "successes" } else { "attempts" },
        num_sources,
        source_path.display(),
        args.workers,
        settings.seed
    );
    let started = Instant::now();
    let mut failures_kept = 0usize;
    let stats = mimicgen_engine::run(&generator, &mut envs, |attempt, stats| {
        let target = if attempt.success {
            Some(&mut writer)
        } else if failures_kept < settings.max_num_failures {
            failures_kept += 1;
            failed_writer.as_mut()
        } else {
            None
        };
        let outcome = target.map_or(Ok(()), |w| {
            let initial = initial_object_poses(&attempt.trajectory.object_poses);
            obs_env.place_fixed_objects(&initial);
            let xml = scene
                .xml_with_fixed_objects(&scene_xml, &initial)
                .map_err(|e| EngineError::Io { path: String::new(), reason: e.to_string() })?;
            obs_env
                .observations_for_states(&attempt.trajectory.states)
                .map_err(|e| EngineError::Env { attempt: attempt.index, source: e })
                .and_then(|obs| w.append_attempt(&attempt, obs, Some(xml)).map(drop).map_err(|e| io_err(&e)))
        });
        if let Err(e) = outcome {
            return ControlFlow::Break(Err(e));
        }
        if let Some(Err(e)) = viz.as_mut().map(|v| v.log_attempt(&attempt, stats)) {
            return ControlFlow::Break(Err(EngineError::Io { path: "rerun recording".to_owned(), reason: e.to_string() }));
        }
        let secs = started.elapsed().as_secs_f64().max(1e-9);
        bar.set_position(if settings.guarantee { stats.successes } else { stats.attempts } as u64);
        #[allow(clippy::cast_precision_loss)]
        bar.set_message(format!(
            "{} ok / {} tried, rate {:.1}%, {:.2} demos/s",
            stats.successes,
            stats.attempts,
            100.0 * stats.rate(),
            stats.successes as f64 / secs
        ));
        ControlFlow::Continue(())
    })?;
    bar.finish_and_clear();
    if let Some(v) = viz {
        v.finish().context("flushing the Rerun recording")?;
    }
    let written = writer.finish()?;
    let failed_written = failed_writer.map(DatasetWriter::finish).transpose()?;
    let wall = started.elapsed().as_secs_f64();
    let report = json!({
        "task": task.name(),
        "variant": args.variant,
        "seed": settings.seed,
        "workers": args.workers,
        "source": source_path.display().to_string(),
        "output": written.display().to_string(),
        "failed_output": failed_written.map(|p| p.display().to_string()),
        "attempts": stats.attempts,
        "successes": stats.successes,
        "generation_rate": stats.rate(),
        "wall_time_s": wall,
        "attempts_per_s": if wall > 0.0 { f64::from(u32::try_from(stats.attempts).unwrap_or(u32::MAX)) / wall } else { 0.0 },
        "per_source_demo": stats.per_source_demo.iter().enumerate().map(|(i, d)| json!({"demo": i, "attempts": d.attempts, "successes": d.successes})).collect::<Vec<_>>(),
        "peak_rss_mib": crate::bench_sim::peak_rss_mib(),
        "failures": stats.failures.iter().map(|f| json!({"subtask": f.subtask, "reason": f.reason.to_string(), "count": f.count})).collect::<Vec<_>>(),
    });
    let text = serde_json::to_string_pretty(&report)?;
    let report_path = sibling(&args.out, "", "json");
    std::fs::write(&report_path, &text).with_context(|| format!("writing {}", report_path.display()))?;
    println!("{text}");
    eprintln!(
        "{} of {} attempts succeeded ({:.1}%) in {wall:.1} s; dataset {}, report {}",
        stats.successes,
        stats.attempts,
        100.0 * stats.rate(),
        written.display(),
        report_path.display()
    );
    Ok(())
}

/// Arguments of `mimicgen demos`.
#[derive(clap::Args, Debug)]
#[command(after_help = "\
Examples:
  mimicgen demos --task stack --variant D0 --num-demos 10 --out my_sources.hdf5

Records source demos with the scripted demonstrator (teleoperator-like variation in grasps, speeds
and pauses; it hovers until the arm has caught up before grasping or placing, and aims the place
from where the object sits in the hand), keeps the successful ones that the task's bundled spec can
split into subtasks, and writes them in the MimicGen source layout
(datagen_info with eef/target/object poses and subtask signals), ready for `mimicgen generate --source`.")]
pub struct DemosArgs {
    /// Task (see `mimicgen tasks`).
    #[arg(long, default_value = "stack")]
    task: String,
    /// Variant whose reset distribution the demos are recorded in.
    #[arg(long, default_value = "D0")]
    variant: String,
    /// Successful demos to record.
    #[arg(long, default_value_t = 10)]
    num_demos: usize,
    /// Record like a hasty operator: descend to grasp or place as soon as the motion is commanded,
    /// without waiting for the arm to catch up (source demos that transfer worse to wide variants).
    #[arg(long)]
    hasty: bool,
    /// Seed of the scenes and of the demonstrator's variation.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Output file.
    #[arg(long)]
    out: PathBuf,
}

/// Runs `mimicgen demos`.
///
/// # Errors
/// Unknown task, simulator failure, or a failure to write.
pub fn demos(args: &DemosArgs) -> anyhow::Result<()> {
    let task = registry::task(&args.task, &args.variant).map_err(anyhow::Error::msg)?;
    let mut scripts = task.scripts();
    for script in &mut scripts {
        script.wait_for_arm = !args.hasty;
    }
    if scripts.is_empty() {
        bail!("no scripted demonstrator for {}", task.name());
    }
    let (scene, xml) = scene_for(task.as_ref(), None, Path::new(""))?;
    // Demos are kept only if the task's bundled spec can split them into its subtasks.
    let spec = registry::default_spec_toml(task.name())
        .map(|toml| TaskSpec::from_toml_str(toml, &format!("bundled {} spec", task.name())))
        .transpose()?;
    let mut env = SimEnv::new(Arc::clone(&scene), Arc::clone(&task));
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(args.seed);
    let options = WriterOptions {
        env_args: Some(registry::env_args(task.name(), &args.variant)),
        compress_obs: false,
        valid_fraction: None,
        split_seed: 0,
    };
    if let Some(dir) = args.out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    let mut writer = DatasetWriter::create(&args.out, options)?;
    let mut tries = 0;
    while writer.len() < args.num_demos {
        tries += 1;
        if tries > 10 * args.num_demos.max(1) {
            bail!("the scripted demonstrator made only {} usable demos in {} tries", writer.len(), tries - 1);
        }
        env.reset(&mut rng).map_err(|e| anyhow::anyhow!("{e}"))?;
        let demo =
            mimicgen_engine::demonstrator::record_sequence(&scripts, &mut env, "demo", &mut rng).map_err(|e| anyhow::anyhow!("{e}"))?;
        if !env.is_success() {
            continue;
        }
        if let Some(Err(e)) = spec.as_ref().map(|spec| mimicgen_engine::segment::Segmentation::new(std::slice::from_ref(&demo), spec)) {
            eprintln!("try {tries}: succeeded but is no usable source demo ({e}); discarded");
            continue;
        }
        let n = demo.len();
        let initial = initial_object_poses(&demo.object_poses);
        let done: Vec<i64> = (0..n).map(|t| i64::from(t + 1 == n)).collect();
        #[allow(clippy::cast_precision_loss)]
        let data = DemoData {
            actions: demo.sim.actions.clone(),
            states: demo.sim.states.clone(),
            rewards: Some(done.iter().map(|&d| d as f64).collect()),
            dones: Some(done),
            obs: BTreeMap::new(),
            datagen_info: Some(DatagenInfo {
                eef_poses: demo.eef_poses,
                target_poses: demo.target_poses,
                gripper_actions: demo.gripper_actions,
                object_poses: demo.object_poses,
                subtask_term_signals: demo.subtask_term_signals,
            }),
            src_demo_inds: Vec::new(),
            src_demo_labels: Vec::new(),
            model_xml: Some(scene.xml_with_fixed_objects(&xml, &initial)?),
        };
        let name = writer.append(&data)?;
        eprintln!("{name}: {n} steps");
    }
    let path = writer.finish()?;
    eprintln!("wrote {} demos ({} tries) to {}", args.num_demos, tries, path.display());
    Ok(())
}
