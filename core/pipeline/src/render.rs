//! `mimicgen render`: camera observations for a dataset that has none, from its stored states,
//! afterwards (what robomimic's `dataset_states_to_obs.py` does for images). Every demo's scene
//! comes from its `model_file`; the images are those `generate --cameras` writes. Everything else
//! of the file (actions, states, low-dim observations, `datagen_info`, attributes, filter keys)
//! is copied as it is.

use std::collections::BTreeMap;
use std::path::Path;
use std::sync::Arc;

use mimicgen_io::tree::{Group, Node};
use mimicgen_io::{DatasetWriter, DemoReader, DemoSource as _, ReadOptions, WriterOptions};
use mimicgen_sim::camera::{CameraConfig, Cameras};
use mimicgen_sim::{Scene, SimEnv, registry};

use crate::PipelineError;

/// Renders `cameras` for every stored state of every demo of `input` into a copy at `out`;
/// `on_demo(done, total)` after each demo. `task` names the task when `env_args` do not. Returns
/// the number of demos written.
///
/// # Errors
/// [`PipelineError`] naming the file and field: unreadable input, unknown task, a demo without
/// `states` or `model_file`, a camera the scene lacks, an existing output without `overwrite`,
/// or a failure to write (the output is then left as an incomplete `.partial`).
pub fn render(
    input: &Path,
    out: &Path,
    cameras: &CameraConfig,
    task: Option<&str>,
    overwrite: bool,
    mut on_demo: impl FnMut(usize, usize),
) -> Result<usize, PipelineError> {
    let file = input.display().to_string();
    let reader = DemoReader::open_with(input, ReadOptions::default())?;
    let env_args = reader.env_args_json().map(str::to_owned);
    let task = crate::prepare::task_of(task, env_args.as_deref(), &file)?;
    crate::outputs::clear_outputs(out, None, overwrite, false)?;
    let options = WriterOptions {
        env_args: env_args.map(|a| registry::env_args_with_cameras(&a, cameras)),
        compress_obs: true,
        valid_fraction: None,
        split_seed: 0,
    };
    let mut writer = DatasetWriter::create(out, options)?;
    let mut current: Option<(String, Cameras, SimEnv)> = None;
    let names = reader.demo_names().to_vec();
    let mut renamed = BTreeMap::new();
    for (done, name) in names.iter().enumerate() {
        let mut demo: Group = reader.load_demo(name)?.into_owned();
        let xml = demo
            .attrs
            .get("model_file")
            .and_then(|a| a.as_str())
            .ok_or_else(|| PipelineError::input(file.clone(), format!("data/{name}"), "has no model_file attribute"))?
            .to_owned();
        if current.as_ref().is_none_or(|(made_from, _, _)| *made_from != xml) {
            let scene = Arc::new(Scene::from_model_file(&xml, &format!("{file}: data/{name}/model_file"), task.as_ref())?);
            let rig = Cameras::new(&scene, cameras.clone())?;
            current = Some((xml, rig, SimEnv::new(scene, Arc::clone(&task))));
        }
        let Some((_, rig, env)) = current.as_mut() else { continue };
        let states = crate::prepare::rows(&demo, "states", &file, name)?;
        let images = env
            .images_for_states(&states, rig)
            .map_err(|e| PipelineError::input(file.clone(), format!("data/{name}/states"), e.to_string()))?;
        let Node::Group(obs) = demo.members.entry("obs".into()).or_insert_with(|| Node::Group(Group::default())) else {
            return Err(PipelineError::input(file.clone(), format!("data/{name}/obs"), "is not a group"));
        };
        for (key, stream) in &images {
            obs.members.insert(key.clone(), Node::Dataset(mimicgen_io::image_dataset(stream)));
        }
        renamed.insert(name.clone(), writer.append_group(&demo)?);
        on_demo(done + 1, names.len());
    }
    let masks = reader.filter_keys()?.into_iter().map(|(key, demos)| (key, demos.iter().filter_map(|d| renamed.get(d).cloned()).collect()));
    writer.set_masks(masks.collect());
    writer.finish()?;
    Ok(names.len())
}

/// One demo of `input` ready to be drawn again: the demo's own scene (`model_file`), its task and
/// its stored states (`mimicgen bench-render`).
pub type DemoToRender = (Arc<Scene>, Arc<dyn mimicgen_sim::Task>, mimicgen_engine::Rows);

/// Reads [`DemoToRender`] for `demo` of `input` (`task` when `env_args` do not name it).
///
/// # Errors
/// [`PipelineError`] naming the file and field: unreadable input, unknown task or demo, a demo
/// without `states` or `model_file`, a scene that does not compile.
pub fn demo_to_render(input: &Path, demo: &str, task: Option<&str>) -> Result<DemoToRender, PipelineError> {
    let file = input.display().to_string();
    let reader = DemoReader::open_with(input, ReadOptions::default())?;
    let task = crate::prepare::task_of(task, reader.env_args_json(), &file)?;
    if !reader.demo_names().iter().any(|n| n == demo) {
        return Err(PipelineError::input(file, "--demo", format!("no demo {demo:?} (the file has {})", reader.demo_names().join(", "))));
    }
    let group: Group = reader.load_demo(demo)?.into_owned();
    let xml = group
        .attrs
        .get("model_file")
        .and_then(|a| a.as_str())
        .ok_or_else(|| PipelineError::input(file.clone(), format!("data/{demo}"), "has no model_file attribute"))?;
    let scene = Arc::new(Scene::from_model_file(xml, &format!("{file}: data/{demo}/model_file"), task.as_ref())?);
    let states = crate::prepare::rows(&group, "states", &file, demo)?;
    Ok((scene, task, states))
}
