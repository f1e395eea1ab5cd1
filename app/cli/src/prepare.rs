//! `mimicgen prepare`: turn a plain robomimic dataset into a MimicGen source dataset by replaying
//! its recorded states in the simulator, as the reference's `prepare_src_dataset.py` does.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::Arc;

use anyhow::{Context as _, anyhow};
use mimicgen_engine::Environment as _;
use mimicgen_engine::demo::Rows;
use mimicgen_io::{DatagenInfo, DatasetWriter, DemoData, RobomimicDataset, WriterOptions};
use mimicgen_sim::{Scene, SimEnv, registry};

/// Arguments of `mimicgen prepare`.
#[derive(clap::Args, Debug)]
#[command(after_help = "\
Examples:
  mimicgen prepare my_robomimic_demos.hdf5 --out my_sources.hdf5

Every demo's states are restored in its own scene (`model_file`) to record what MimicGen needs per
step: end-effector pose, controller target pose implied by the action, gripper action, object poses
and subtask-end signals (datagen_info). Actions, states, rewards, dones and observations are copied.")]
pub struct PrepareArgs {
    /// A robomimic dataset with `states`, `actions` and `model_file` per demo.
    file: PathBuf,
    /// Output MimicGen source dataset.
    #[arg(long)]
    out: PathBuf,
    /// Task, when `env_args` does not name one of ours (see `mimicgen tasks`).
    #[arg(long)]
    task: Option<String>,
}

fn rows(demo: &mimicgen_io::tree::Group, field: &str, file: &str, name: &str) -> anyhow::Result<Rows> {
    let d = demo.dataset(field).ok_or_else(|| anyhow!("{file}: data/{name} has no `{field}`"))?;
    let width = d.array.shape.get(1).copied().unwrap_or(1);
    let values = d.array.values.to_f64().ok_or_else(|| anyhow!("{file}: data/{name}/{field} is not numeric"))?;
    Ok(Rows::from_vec(width, values, &format!("{file}: data/{name}/{field}"))?)
}

/// Runs `mimicgen prepare`.
///
/// # Errors
/// Unreadable input, unknown task, a scene that does not compile, or a failure to write.
pub fn prepare(args: &PrepareArgs) -> anyhow::Result<()> {
    let file = args.file.display().to_string();
    let dataset = RobomimicDataset::open(&args.file).with_context(|| format!("opening {file}"))?;
    let env_args = dataset.env_args().map(str::to_owned);
    let task = match &args.task {
        Some(name) => registry::task(name, "D0").map_err(anyhow::Error::msg)?,
        None => {
            registry::task_from_env_args(env_args.as_deref()).map_err(|e| anyhow!("{file}: data attribute env_args: {e}; pass --task"))?.0
        }
    };
    let mut writer = DatasetWriter::create(&args.out, WriterOptions { env_args, compress_obs: true, valid_fraction: None, split_seed: 0 })?;
    let mut scenes: BTreeMap<String, Arc<Scene>> = BTreeMap::new();
    for name in dataset.demo_names().to_vec() {
        let demo = dataset.demo(&name).ok_or_else(|| anyhow!("{file}: data/{name} vanished"))?;
        let xml = demo
            .attrs
            .get("model_file")
            .and_then(|a| a.as_str())
            .ok_or_else(|| anyhow!("{file}: data/{name} has no model_file attribute"))?;
        let scene = match scenes.get(xml) {
            Some(s) => Arc::clone(s),
            None => {
                let s = Arc::new(Scene::from_model_file(xml, &format!("{file}: data/{name}/model_file"), task.as_ref())?);
                scenes.insert(xml.to_owned(), Arc::clone(&s));
                s
            }
        };
        let mut env = SimEnv::new(scene, Arc::clone(&task));
        let states = rows(demo, "states", &file, &name)?;
        let actions = rows(demo, "actions", &file, &name)?;
        if states.len() != actions.len() {
            anyhow::bail!("{file}: data/{name}: {} states but {} actions", states.len(), actions.len());
        }
        let mut info = DatagenInfo { gripper_actions: Rows::new(actions.width().saturating_sub(6)), ..DatagenInfo::default() };
        for (state, action) in states.iter().zip(actions.iter()) {
            env.reset_to_state(state).map_err(|e| anyhow!("{file}: data/{name}/states: {e}"))?;
            info.eef_poses.push(env.eef_pose());
            info.target_poses.push(env.action_to_target_pose(action));
            info.gripper_actions.push(&action[6.min(action.len())..])?;
            for (object, pose) in env.object_poses() {
                info.object_poses.entry(object).or_default().push(pose);
            }
            for (signal, value) in env.subtask_term_signals() {
                info.subtask_term_signals.entry(signal).or_default().push(value);
            }
        }
        let obs = demo
            .group("obs")
            .map(|g| {
                g.members
                    .keys()
                    .filter_map(|k| {
                        g.dataset(k).and_then(|d| d.array.values.to_f64().map(|v| (k.clone(), (d.array.shape[1..].to_vec(), v))))
                    })
                    .collect()
            })
            .unwrap_or_default();
        let column = |field: &str| demo.dataset(field).and_then(|d| d.array.values.to_f64());
        let data = DemoData {
            actions,
            states,
            rewards: column("rewards"),
            dones: demo.dataset("dones").and_then(|d| d.array.values.to_i64()),
            obs,
            datagen_info: Some(info),
            src_demo_inds: Vec::new(),
            src_demo_labels: Vec::new(),
            model_xml: Some(xml.to_owned()),
            attempt_index: None,
        };
        writer.append(&data)?;
        eprintln!("{name}: {} steps", data.actions.len());
    }
    let out = writer.finish()?;
    eprintln!("wrote {} demos to {}", dataset.demo_names().len(), out.display());
    Ok(())
}
