//! `mimicgen demos`: record source demos with the scripted demonstrator, in the MimicGen source
//! layout, keeping the successful tries that the task's bundled spec can split into subtasks.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::Arc;

use anyhow::{Context as _, bail};
use mimicgen_engine::demo::initial_object_poses;
use mimicgen_engine::demonstrator::Style;
use mimicgen_engine::{Environment as _, TaskSpec};
use mimicgen_io::{DatagenInfo, DatasetWriter, DemoData, WriterOptions};
use mimicgen_sim::{Scene, SimEnv, registry};
use rand::SeedableRng as _;

/// The scripted operator's style (`mimicgen demos --style`).
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum DemoStyle {
    /// Even, straight moves; waits for the arm before grasping or placing.
    Careful,
    /// As careful, never waiting for the arm.
    Hasty,
    /// A person's timing, aim and hand (reaction, hesitation, corrections, drift).
    Human,
}

impl From<DemoStyle> for Style {
    fn from(style: DemoStyle) -> Self {
        match style {
            DemoStyle::Careful => Self::Careful,
            DemoStyle::Hasty => Self::Hasty,
            DemoStyle::Human => Self::Human,
        }
    }
}

/// Arguments of `mimicgen demos`.
#[derive(clap::Args, Debug)]
#[command(after_help = "\
Examples:
  mimicgen demos --task stack --variant D0 --num-demos 10 --out my_sources.hdf5
  mimicgen demos --task square --style human --num-demos 10 --seed 1 --out square_human.hdf5
  mimicgen demos --task two_arm_handover --num-demos 10 --out handover_sources.hdf5   # two arms

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
    /// How the scripted operator moves. careful: even, straight moves, hovering until the arm has
    /// caught up before grasping or placing (the bundled `<task>_D0_source.hdf5`). hasty: the same
    /// without waiting for the arm (sources that transfer worse to wide variants). human: like a
    /// person at a teleoperation device: reaction pauses, moves that speed up and slow down, a
    /// drifting hand, twice the grasp offset and yaw error, hesitation partway down, descents
    /// aimed a few mm off and corrected (the bundled `<task>_D0_human.hdf5`).
    #[arg(long, value_enum, default_value_t = DemoStyle::Careful)]
    style: DemoStyle,
    /// The same as `--style hasty` (kept for older scripts).
    #[arg(long, hide = true, conflicts_with = "style")]
    hasty: bool,
    /// Seed of the scenes and of the demonstrator's variation.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Output file.
    #[arg(long)]
    out: PathBuf,
    /// Replace an existing output.
    #[arg(long)]
    overwrite: bool,
}

/// Runs `mimicgen demos`.
///
/// # Errors
/// Unknown task, simulator failure, or a failure to write.
pub fn demos(args: &DemosArgs) -> anyhow::Result<()> {
    crate::check_output(&args.out, None, args.overwrite)?;
    let style = if args.hasty { Style::Hasty } else { args.style.into() };
    if mimicgen_sim::two_arm::TwoArmTask::from_name(&args.task).is_some() {
        return crate::two_arm::demos(&args.task, &args.variant, style, args.num_demos, args.seed, &args.out);
    }
    let task = match registry::task(&args.task, &args.variant) {
        Ok(task) => task,
        Err(e) => crate::exit::usage!("{e}"),
    };
    let mut scripts = task.scripts();
    for script in &mut scripts {
        script.style = style;
    }
    if scripts.is_empty() {
        crate::exit::usage!(
            "no scripted demonstrator for {} (its bundled source demos are recorded ones: `mimicgen generate --task {}` uses them; `mimicgen prepare` turns your own recordings into source demos)",
            task.name(),
            task.name()
        );
    }
    let (scene, xml) = Scene::for_task_with_xml(task.as_ref())?;
    let scene = Arc::new(scene);
    let xml = mimicgen_sim::assets::portable_asset_paths(&xml);
    // Demos are kept only if the task's bundled spec can split them into its subtasks.
    let spec = registry::default_spec_toml(task.name())
        .map(|toml| TaskSpec::from_toml_str(toml, &format!("bundled {} spec", task.name())))
        .transpose()?;
    // Object transfer: each try draws one of the variant's instances (Mobile Kitchen's pans and
    // carrots), and the demo records which.
    let instances: Vec<(String, Arc<Scene>)> =
        Scene::instances_for_task(task.as_ref(), &mimicgen_sim::robot::PANDA)?.into_iter().map(|(label, s)| (label, Arc::new(s))).collect();
    let mut env = SimEnv::new(Arc::clone(&scene), Arc::clone(&task)).with_instances(instances);
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
            let unmet = env.unmet_success().unwrap_or_else(|| "task not achieved".to_owned());
            eprintln!("try {tries}: failed ({unmet}; {}); discarded", signal_steps(&demo.subtask_term_signals));
            continue;
        }
        if let Some(Err(e)) = spec.as_ref().map(|spec| mimicgen_engine::segment::Segmentation::new(std::slice::from_ref(&demo), spec)) {
            eprintln!("try {tries}: succeeded but is no usable source demo ({e}); discarded");
            continue;
        }
        let n = demo.len();
        let initial = initial_object_poses(&demo.object_poses);
        let instance = env.instance().map(str::to_owned);
        let instance_xml = instance.as_ref().map(|_| mimicgen_sim::assets::portable_asset_paths(&env.physics().scene().xml));
        let done: Vec<i64> = (0..n).map(|t| i64::from(t + 1 == n)).collect();
        #[allow(clippy::cast_precision_loss)]
        let data = DemoData {
            actions: demo.sim.actions.clone(),
            other_actions: std::collections::BTreeMap::new(),
            states: demo.sim.states.clone(),
            rewards: Some(done.iter().map(|&d| d as f64).collect()),
            dones: Some(done),
            obs: BTreeMap::new(),
            images: BTreeMap::new(),
            datagen_info: Some(DatagenInfo {
                eef_poses: demo.eef_poses,
                target_poses: demo.target_poses,
                gripper_actions: demo.gripper_actions,
                object_poses: demo.object_poses,
                subtask_term_signals: demo.subtask_term_signals,
                arms: Vec::new(),
            }),
            src_demo_inds: Vec::new(),
            src_demo_labels: Vec::new(),
            model_xml: Some(scene.xml_with_fixed_objects(instance_xml.as_deref().unwrap_or(&xml), &initial)?),
            attempt_index: None,
            failure: None,
            cause: None,
            object_instance: instance,
        };
        let name = writer.append(&data)?;
        eprintln!("{name}: {n} steps");
    }
    let path = writer.finish()?;
    eprintln!("wrote {} demos ({} tries) to {}", args.num_demos, tries, path.display());
    Ok(())
}

/// Where each subtask signal first held in a recorded try, in that order, and those that never
/// did: what a failed try got through.
fn signal_steps(signals: &BTreeMap<String, Vec<i64>>) -> String {
    let mut fired: Vec<(Option<usize>, &str)> =
        signals.iter().map(|(name, flags)| (flags.iter().position(|&f| f != 0), name.as_str())).collect();
    fired.sort_by_key(|&(step, _)| step.unwrap_or(usize::MAX));
    let words: Vec<String> =
        fired.iter().map(|(step, name)| step.map_or_else(|| format!("{name} never"), |t| format!("{name} at step {t}"))).collect();
    words.join(", ")
}
