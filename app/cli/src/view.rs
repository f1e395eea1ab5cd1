//! `mimicgen view` and the `--rerun*` options of `mimicgen generate`: Rerun recordings.

use std::path::PathBuf;

use anyhow::Context as _;
use mimicgen_engine::spec::SourceSelection;
use mimicgen_io::RobomimicDataset;
use mimicgen_sim::{Scene, registry};
use mimicgen_viz::{LogConfig, RunLogger, SceneLevel, Sink};

/// Which attempts get the 3D scene (every geom's pose per step).
#[derive(clap::ValueEnum, Debug, Clone, Copy, PartialEq, Eq)]
pub enum SceneArg {
    /// Every attempt.
    All,
    /// Successful attempts only.
    Successes,
    /// None (paths, frames, plots and statistics only).
    None,
}

/// Where a Rerun recording goes.
#[derive(clap::Args, Debug, Clone)]
pub struct RerunArgs {
    /// Save a Rerun recording of the run (source demos, every attempt, statistics) to this .rrd file.
    #[arg(long, value_name = "FILE.rrd", conflicts_with_all = ["rerun_connect", "rerun_spawn"])]
    rerun: Option<PathBuf>,
    /// Stream the recording to a running Rerun viewer at this URL (e.g. rerun+http://127.0.0.1:9876/proxy).
    #[arg(long, value_name = "URL", conflicts_with = "rerun_spawn")]
    rerun_connect: Option<String>,
    /// Start the Rerun viewer (the venv's `rerun`, or $MIMICGEN_RERUN) and stream to it.
    #[arg(long)]
    rerun_spawn: bool,
    /// Which attempts get the 3D scene per step in the recording.
    #[arg(long, value_enum, default_value = "all")]
    rerun_scene: SceneArg,
    /// Log the 3D scene at every N-th control step only (2 = 10 Hz keeps streaming well inside 10 %
    /// of generation time; 1 logs every step).
    #[arg(long, value_name = "N", default_value_t = 2)]
    rerun_stride: usize,
}

impl RerunArgs {
    /// Whether a recording was asked for.
    pub fn is_set(&self) -> bool {
        self.sink().is_some()
    }

    fn sink(&self) -> Option<Sink> {
        match (&self.rerun, &self.rerun_connect, self.rerun_spawn) {
            (Some(path), _, _) => Some(Sink::Save(path.clone())),
            (None, Some(url), _) => Some(Sink::Connect(url.clone())),
            (None, None, true) => Some(Sink::Spawn),
            (None, None, false) => None,
        }
    }

    fn config(&self) -> LogConfig {
        let scene = match self.rerun_scene {
            SceneArg::All => SceneLevel::All,
            SceneArg::Successes => SceneLevel::Successes,
            SceneArg::None => SceneLevel::None,
        };
        LogConfig { scene, scene_stride: self.rerun_stride.max(1) }
    }

    /// A logger for `scene` when a Rerun option was given.
    ///
    /// # Errors
    /// The sink cannot be opened (no viewer installed, file not writable, viewer unreachable).
    pub fn logger(&self, app_id: &'static str, scene: &Scene) -> anyhow::Result<Option<RunLogger>> {
        let Some(sink) = self.sink() else { return Ok(None) };
        if let Sink::Save(path) = &sink
            && let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty())
        {
            std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        }
        let rec = sink.open(app_id)?;
        Ok(Some(RunLogger::new(rec, scene, self.config())?))
    }
}

/// Arguments of `mimicgen view`.
#[derive(clap::Args, Debug)]
#[command(after_help = "\
Examples:
  mimicgen view core/sim/data/stack_D0_source.hdf5 --spawn      # every source demo, viewer started
  mimicgen view out/generated.hdf5 --demo 3 --out demo3.rrd      # one demo, saved
  mimicgen view source_D0_prepared.hdf5 --connect rerun+http://127.0.0.1:9876/proxy

Reads a MimicGen dataset (ours or the reference's: data/demo_*/datagen_info and states), rebuilds
its scene from the file's model_file (task from env_args), and logs per demo the 3D scene per step,
the end-effector path by subtask, subtask ends with object frames, and the subtask-end signals.
Without --out or --connect the viewer is started.")]
pub struct ViewArgs {
    /// The dataset (HDF5).
    file: PathBuf,
    /// Only this demo (index in the file's demo order).
    #[arg(long)]
    demo: Option<usize>,
    /// Save the recording to this .rrd file.
    #[arg(long, value_name = "FILE.rrd", conflicts_with = "connect")]
    out: Option<PathBuf>,
    /// Stream to a running viewer at this URL.
    #[arg(long, value_name = "URL")]
    connect: Option<String>,
    /// Start the viewer (the default without --out or --connect).
    #[arg(long, conflicts_with_all = ["out", "connect"])]
    spawn: bool,
    /// Log the 3D scene at every N-th step only.
    #[arg(long, value_name = "N", default_value_t = 1)]
    stride: usize,
}

/// Runs `mimicgen view`.
///
/// # Errors
/// Unreadable dataset, unknown task, no viewer, or a failure to log.
pub fn view(args: &ViewArgs) -> anyhow::Result<()> {
    let dataset = RobomimicDataset::open(&args.file)?;
    let sources = dataset.to_source_dataset(&SourceSelection::default())?;
    let (task, _) = match registry::task_from_env_args(sources.env_args.as_deref()) {
        Ok(found) => found,
        Err(e) => crate::exit::usage!("{}: {e}", args.file.display()),
    };
    if let Some(i) = args.demo.filter(|&i| i >= sources.demos.len()) {
        crate::exit::usage!("--demo {i}: {} has {} demos", args.file.display(), sources.demos.len());
    }
    // The scene of the demo shown (object-transfer datasets hold one scene per object instance).
    let shown = sources.demos.get(args.demo.unwrap_or(0));
    let origin = format!("{} (model_file of {})", args.file.display(), shown.map_or("its first demo", |d| d.name.as_str()));
    let scene = match shown.and_then(|d| d.sim.model_xml.as_deref()) {
        Some(xml) => Scene::from_model_file(xml, &origin, task.as_ref())?,
        None => Scene::for_task(task.as_ref())?,
    };
    let scenes: std::collections::BTreeSet<&str> = sources.demos.iter().filter_map(|d| d.sim.model_xml.as_deref()).collect();
    if args.demo.is_none() && scenes.len() > 1 {
        eprintln!(
            "note: the demos have {} different scenes (object instances); the 3D view draws every demo in demo_0's: pass --demo N for one demo in its own",
            scenes.len()
        );
    }
    let sink = match (&args.out, &args.connect) {
        (Some(path), _) => Sink::Save(path.clone()),
        (None, Some(url)) => Sink::Connect(url.clone()),
        (None, None) => Sink::Spawn,
    };
    let rec = sink.open("mimicgen")?;
    let mut logger = RunLogger::new(rec, &scene, LogConfig { scene: SceneLevel::All, scene_stride: args.stride.max(1) })?;
    let selected = sources.demos.iter().enumerate().filter(|(i, _)| args.demo.is_none_or(|d| d == *i));
    logger.log_demos(selected)?;
    // Camera observations (generate --cameras) as images on the same timelines.
    let mut cameras: Vec<String> = Vec::new();
    for (i, demo) in sources.demos.iter().enumerate().filter(|(i, _)| args.demo.is_none_or(|d| d == *i)) {
        let Some(obs) = dataset.demo(&demo.name).and_then(|g| g.group("obs")) else { continue };
        let (_, images) = mimicgen_io::observations_from_group(obs);
        for camera in logger.log_demo_images(i, &images)? {
            if !cameras.contains(&camera) {
                cameras.push(camera);
            }
        }
    }
    if !cameras.is_empty() {
        mimicgen_viz::send_blueprint(logger.stream(), mimicgen_viz::blueprint_with_cameras(&cameras))?;
    }
    logger.finish()?;
    eprintln!(
        "logged {} demo(s) of {} to {}",
        args.demo.map_or(sources.demos.len(), |_| 1),
        args.file.display(),
        match &sink {
            Sink::Save(p) => p.display().to_string(),
            Sink::Connect(u) => u.clone(),
            Sink::Spawn => "the viewer".to_owned(),
        }
    );
    Ok(())
}
