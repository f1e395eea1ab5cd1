//! The paper's support-coverage analysis of a dataset's initial scenes (appendix "Bias and
//! Artifacts in Generated Data"), from a file: what `mimicgen coverage` prints and the Python
//! package returns.

use std::collections::BTreeMap;
use std::path::Path;

use mimicgen_engine::coverage::{Coverage, coverage};
use mimicgen_engine::pose::{Mat4, Pose, pose_from_matrix};
use mimicgen_io::{DemoReader, DemoSource as _, ReadOptions};
use mimicgen_sim::registry;

use crate::PipelineError;

/// A dataset's coverage, with the task and variant whose reset region made the bins.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct DatasetCoverage {
    /// Task.
    pub task: String,
    /// Variant.
    pub variant: String,
    /// The analysis.
    #[serde(flatten)]
    pub coverage: Coverage,
    /// Demos per object instance (object-transfer datasets: each demo's
    /// `mimicgen_object_instance`); empty for the others.
    pub instances: BTreeMap<String, usize>,
}

/// Support coverage of the initial scenes of `path` (each demo's first
/// `datagen_info/object_poses`), `bins` bins per object coordinate over the reset region of
/// `task` / `variant` (default: what the file's env_args name).
///
/// # Errors
/// [`PipelineError`] naming the file and field: unreadable file, unknown task, a demo without
/// object poses.
pub fn dataset_coverage(path: &Path, task: Option<&str>, variant: Option<&str>, bins: usize) -> Result<DatasetCoverage, PipelineError> {
    let file = path.display().to_string();
    let reader = DemoReader::open_with(path, ReadOptions::default())?.without_observations();
    let (name, variant) = match task {
        Some(name) => (name.to_owned(), variant.unwrap_or("D0").to_owned()),
        None => {
            let env_args = reader.data_attrs().get("env_args").and_then(mimicgen_io::tree::Array::as_str);
            let (task, from_file) = registry::task_from_env_args(env_args)
                .map_err(|e| PipelineError::input(file.clone(), "data attribute env_args", format!("{e}; pass the task and variant")))?;
            (task.name().to_owned(), variant.map_or(from_file, str::to_owned))
        }
    };
    let task = registry::task(&name, &variant).map_err(|e| PipelineError::input("", "task", e))?;
    let dims = task.coverage_dimensions();
    let mut scenes = Vec::with_capacity(reader.demo_names().len());
    let mut instances: BTreeMap<String, usize> = BTreeMap::new();
    for demo_name in reader.demo_names() {
        let demo = reader.load_demo(demo_name)?;
        if let Some(label) = demo.attrs.get(mimicgen_io::INSTANCE_ATTR).and_then(mimicgen_io::tree::Array::as_str) {
            // One instance per object: `pan+carrot` counts under both.
            for part in label.split('+') {
                *instances.entry(part.to_owned()).or_default() += 1;
            }
        }
        let mut scene: BTreeMap<String, Pose> = BTreeMap::new();
        for d in &dims {
            if scene.contains_key(&d.object) {
                continue;
            }
            let field = format!("data/{demo_name}/datagen_info/object_poses/{}", d.object);
            let values = demo
                .dataset_at(&format!("datagen_info/object_poses/{}", d.object))
                .and_then(|x| x.array.values.to_f64())
                .ok_or_else(|| PipelineError::input(file.clone(), field.clone(), "missing: the initial scene needs the object's poses"))?;
            let first: [f64; 16] = values
                .get(..16)
                .and_then(|v| v.try_into().ok())
                .ok_or_else(|| PipelineError::input(file.clone(), field.clone(), "is empty"))?;
            let pose = pose_from_matrix(&Mat4::from_row_slice(&first), &format!("{file}: {field}[0]"))
                .map_err(|e| PipelineError::engine(file.clone(), e))?;
            scene.insert(d.object.clone(), pose);
        }
        scenes.push(scene);
    }
    let coverage = coverage(&scenes, &dims, bins).map_err(|e| PipelineError::engine(file, e))?;
    Ok(DatasetCoverage { task: task.name().to_owned(), variant, coverage, instances })
}
