//! How a run's task, variant, spec, source demos and output `env_args` are worked out from its
//! description ([`crate::RunConfig`]): the one place that decides them (from the flags, the
//! spec file, the source file and the bundled defaults).

use std::path::{Path, PathBuf};
use std::sync::Arc;

use mimicgen_engine::{EngineError, SourceDataset, TaskSpec};
use mimicgen_sim::{Scene, Task, registry};

use crate::{CameraConfig, PipelineError, RunConfig};

/// What a run works on, decided from its description.
pub(crate) struct Resolved {
    pub task: Arc<dyn Task>,
    pub variant: String,
    /// The spec with the run's fields over it (`num_demos`, `seed`, `--action-noise`, ...).
    pub spec: TaskSpec,
    /// The spec's file (`None`: the task's bundled spec).
    pub spec_file: Option<PathBuf>,
    pub source_path: PathBuf,
    /// The source file, checked to be recorded with the controller generation drives.
    pub dataset: mimicgen_io::RobomimicDataset,
}

/// Decides the task and variant ([`resolve_task`]), the spec (`config.config`, else the task's
/// bundled one, with the run's fields applied) and the source demos (`config.source`, else the
/// task's bundled ones, checked by [`check_controller`]).
///
/// # Errors
/// [`PipelineError`] naming the flag or file at fault.
pub(crate) fn resolve(config: &RunConfig) -> Result<Resolved, PipelineError> {
    let spec_from_file = match &config.config {
        // The loader's errors name the file (and line) themselves.
        Some(path) => Some(TaskSpec::load(path).map_err(|e| PipelineError::engine("", e))?),
        None => None,
    };
    let source_file = match &config.source {
        Some(path) => {
            if !path.exists() {
                return Err(PipelineError::input(path.display().to_string(), "--source", "no such file"));
            }
            Some((path.clone(), mimicgen_io::RobomimicDataset::open(path)?))
        }
        None => None,
    };
    let (task, variant) = resolve_task(
        config.task.as_deref(),
        config.variant.as_deref(),
        spec_from_file.as_ref().zip(config.config.as_deref()),
        source_file.as_ref().and_then(|(p, d)| d.env_args().map(|a| (a, p.as_path()))),
    )?;
    let mut spec = match spec_from_file {
        Some(spec) => spec,
        None => crate::bundled::spec(task.name())?,
    };
    config.spec.apply(&mut spec)?;
    let g = &mut spec.generation;
    if let Some(n) = config.num_demos {
        g.num_trials = n;
    }
    if let Some(seed) = config.seed {
        g.seed = seed;
    }
    g.keep_failed |= config.keep_failed;
    g.guarantee |= config.guarantee;
    g.early_abort |= config.early_abort;
    if let Some(cap) = config.max_attempts {
        g.max_attempts = cap;
    }
    let (source_path, dataset) = match source_file {
        Some(found) => found,
        None => {
            let path = crate::bundled::source_demos(task.name())?;
            let dataset = mimicgen_io::RobomimicDataset::open(&path)?;
            (path, dataset)
        }
    };
    check_controller(dataset.env_args(), &source_path)?;
    Ok(Resolved { task, variant, spec, spec_file: config.config.clone(), source_path, dataset })
}

/// Checks that the objects and signals `spec` names exist in `sources`. An unknown one is the
/// spec's mistake, so the error names the spec's file and line (`spec_file`; `None` for `task`'s
/// bundled spec), the field, and the names that exist.
///
/// # Errors
/// [`PipelineError::Engine`] wrapping [`EngineError::UnknownName`].
pub(crate) fn check_spec_names(
    spec: &TaskSpec,
    spec_file: Option<&Path>,
    task: &str,
    sources: &SourceDataset,
) -> Result<(), PipelineError> {
    spec.check_names(&sources.object_names(), &sources.signal_names()).map_err(|e| {
        let label = match spec_file {
            Some(path) => {
                let line = match &e {
                    EngineError::UnknownName { field, .. } => {
                        std::fs::read_to_string(path).ok().and_then(|text| mimicgen_engine::spec::field_line(&text, field))
                    }
                    _ => None,
                };
                line.map_or_else(|| path.display().to_string(), |line| format!("{}:{line}", path.display()))
            }
            None => format!("the bundled spec of {task}"),
        };
        PipelineError::engine(label, e)
    })
}

/// Loads the spec in `path` and, when it is for one of our tasks, checks the objects and signals
/// it names against that task's bundled source demos (`mimicgen spec check`).
///
/// # Errors
/// [`PipelineError`] naming the file, line and field at fault.
pub fn check_spec_file(path: &Path) -> Result<TaskSpec, PipelineError> {
    // The loader's errors name the file (and line) themselves.
    let spec = TaskSpec::load(path).map_err(|e| PipelineError::engine("", e))?;
    if registry::default_spec_toml(&spec.name).is_some() {
        let sources = crate::bundled::source_demos(&spec.name)?;
        let dataset = mimicgen_io::RobomimicDataset::open(&sources)?.to_source_dataset(&spec.source)?;
        check_spec_names(&spec, Some(path), &spec.name, &dataset)?;
    }
    Ok(spec)
}

/// The `env_args` a run's outputs carry: the sources' (their controller settings) naming the
/// generated task variant, the arm generation used and the cameras rendered.
pub(crate) fn output_env_args(
    source_env_args: Option<&str>,
    task: &dyn Task,
    variant: &str,
    scene: &Scene,
    cameras: Option<&CameraConfig>,
) -> String {
    let env_args = registry::env_args_for_variant(source_env_args, task.name(), variant);
    let env_args = registry::env_args_with_robot(&env_args, scene.robot.model);
    match cameras {
        Some(cameras) => registry::env_args_with_cameras(&env_args, cameras),
        None => env_args,
    }
}

/// The task and variant one input names, with where it said so.
#[derive(Debug, Clone)]
struct Named {
    task: String,
    variant: String,
    origin: String,
}

/// Works out the task and variant: `--task/--variant` first, then the config's
/// `experiment.task.name`, then the source file's `env_args`, then `stack` / `D0`. Inputs that
/// name different tasks are an error naming both; the variant of an earlier one wins, since
/// source demos are usually recorded in D0 and generated in a wider variant.
///
/// # Errors
/// [`PipelineError::Input`] for unknown names or contradicting inputs.
pub(crate) fn resolve_task(
    explicit_task: Option<&str>,
    explicit_variant: Option<&str>,
    spec: Option<(&TaskSpec, &Path)>,
    source_env_args: Option<(&str, &Path)>,
) -> Result<(Arc<dyn Task>, String), PipelineError> {
    let mut named: Vec<Named> = Vec::new();
    if let Some(task) = explicit_task {
        let variant = explicit_variant.unwrap_or_default().to_owned();
        named.push(Named { task: task.to_ascii_lowercase(), variant, origin: "--task".to_owned() });
    }
    if let Some((spec, path)) = spec
        && let Some(env_name) = &spec.env_name
    {
        let (task, variant) = registry::task_from_env_name(env_name)
            .map_err(|reason| PipelineError::input(path.display().to_string(), "experiment.task.name", reason))?;
        named.push(Named {
            task: task.name().to_owned(),
            variant,
            origin: format!("{} (experiment.task.name {env_name:?})", path.display()),
        });
    }
    if let Some((env_args, path)) = source_env_args {
        // A source file whose env is not one of ours (or has none) names no task.
        if let Ok((task, variant)) = registry::task_from_env_args(Some(env_args)) {
            named.push(Named { task: task.name().to_owned(), variant, origin: format!("{} (data attribute env_args)", path.display()) });
        }
    }
    if let Some(first) = named.first()
        && let Some(other) = named.iter().find(|n| n.task != first.task)
    {
        return Err(PipelineError::input(
            String::new(),
            "task",
            format!(
                "{} names task {:?} but {} names task {:?}; pass the inputs of one task (or fix the one that is wrong)",
                first.origin, first.task, other.origin, other.task
            ),
        ));
    }
    let task = named.first().map_or("stack", |n| n.task.as_str());
    let variant = explicit_variant
        .map(str::to_owned)
        .or_else(|| named.iter().map(|n| n.variant.clone()).find(|v| !v.is_empty()))
        .unwrap_or_else(|| "D0".to_owned());
    let task = registry::task(task, &variant).map_err(|reason| PipelineError::input(String::new(), "--task/--variant", reason))?;
    Ok((task, variant))
}

/// The controller the MuJoCo backend drives: robosuite's OSC_POSE with delta poses, kp 150,
/// damping ratio 1, fixed impedance, 20 Hz, actions scaled to 5 cm / 0.5 rad.
///
/// Refuses a source file recorded with anything else (absolute poses, another controller or
/// gains), since its actions would mean something else here.
///
/// # Errors
/// [`PipelineError::Input`] naming the file and the field that differs.
pub(crate) fn check_controller(env_args: Option<&str>, file: &Path) -> Result<(), PipelineError> {
    let Some(text) = env_args else { return Ok(()) };
    let file = file.display().to_string();
    let value: serde_json::Value = serde_json::from_str(text)
        .map_err(|e| PipelineError::input(file.clone(), "data attribute env_args", format!("is not JSON: {e}")))?;
    let kwargs = value.get("env_kwargs").unwrap_or(&serde_json::Value::Null);
    let differs = |field: &str, got: &serde_json::Value, want: &str| {
        PipelineError::input(
            file.clone(),
            format!("env_args env_kwargs.{field}"),
            format!(
                "is {got}, but generation drives robosuite's OSC_POSE controller with {want}; \
                 these source demos' actions would mean something else here (re-record them with that controller)"
            ),
        )
    };
    if let Some(freq) = kwargs.get("control_freq").filter(|f| !f.is_null())
        && freq.as_f64().is_none_or(|f| (f - 20.0).abs() > 1e-9)
    {
        return Err(differs("control_freq", freq, "control_freq 20"));
    }
    let Some(controller) = kwargs.get("controller_configs").filter(|c| !c.is_null()) else { return Ok(()) };
    let field = |name: &str| format!("controller_configs.{name}");
    match controller.get("type") {
        Some(t) if t.as_str() == Some("OSC_POSE") => {}
        Some(t) => return Err(differs(&field("type"), t, "type OSC_POSE")),
        None => return Err(differs("controller_configs", controller, "a robosuite 1.4 `type: OSC_POSE` config")),
    }
    if let Some(delta) = controller.get("control_delta")
        && delta.as_bool() != Some(true)
    {
        return Err(differs(&field("control_delta"), delta, "delta poses (control_delta true); absolute poses are not implemented"));
    }
    let numbers: [(&str, f64); 2] = [("kp", 150.0), ("damping_ratio", 1.0)];
    for (name, want) in numbers {
        if let Some(v) = controller.get(name)
            && v.as_f64().is_none_or(|x| (x - want).abs() > 1e-9)
        {
            return Err(differs(&field(name), v, &format!("{name} {want}")));
        }
    }
    if let Some(mode) = controller.get("impedance_mode")
        && mode.as_str() != Some("fixed")
    {
        return Err(differs(&field("impedance_mode"), mode, "impedance_mode fixed"));
    }
    let limits: [(&str, [f64; 6]); 2] =
        [("output_max", [0.05, 0.05, 0.05, 0.5, 0.5, 0.5]), ("output_min", [-0.05, -0.05, -0.05, -0.5, -0.5, -0.5])];
    for (name, want) in limits {
        if let Some(v) = controller.get(name) {
            let got: Option<Vec<f64>> = match v {
                serde_json::Value::Array(a) => a.iter().map(serde_json::Value::as_f64).collect(),
                serde_json::Value::Number(n) => n.as_f64().map(|x| vec![x; 6]),
                _ => None,
            };
            if got.is_none_or(|g| g.len() != 6 || g.iter().zip(want).any(|(a, b)| (a - b).abs() > 1e-9)) {
                return Err(differs(&field(name), v, &format!("{name} {want:?}")));
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn args(controller: &str) -> String {
        format!(r#"{{"env_name": "Stack_D0", "env_kwargs": {{"control_freq": 20, "controller_configs": {controller}}}}}"#)
    }

    #[test]
    fn our_controller_passes_and_others_are_refused_by_field() {
        let path = Path::new("src.hdf5");
        assert!(check_controller(Some(&registry::env_args("stack", "D0")), path).is_ok());
        assert!(check_controller(None, path).is_ok());
        for (controller, field) in [
            (r#"{"type": "OSC_POSITION"}"#, "controller_configs.type"),
            (r#"{"type": "OSC_POSE", "control_delta": false}"#, "controller_configs.control_delta"),
            (r#"{"type": "OSC_POSE", "kp": 300}"#, "controller_configs.kp"),
            (r#"{"type": "OSC_POSE", "impedance_mode": "variable"}"#, "controller_configs.impedance_mode"),
            (r#"{"type": "OSC_POSE", "output_max": 0.1}"#, "controller_configs.output_max"),
            (r#"{"body_parts": {}}"#, "controller_configs"),
        ] {
            let err = check_controller(Some(&args(controller)), path).unwrap_err().to_string();
            assert!(err.contains("src.hdf5") && err.contains(field), "{controller}: {err}");
        }
        let err = check_controller(Some(r#"{"env_kwargs": {"control_freq": 10}}"#), path).unwrap_err().to_string();
        assert!(err.contains("control_freq"), "{err}");
    }

    #[test]
    fn the_task_comes_from_the_inputs_unless_given() {
        let mut spec = TaskSpec::from_toml_str(registry::default_spec_toml("stack").unwrap(), "stack.toml").unwrap();
        spec.env_name = Some("Stack_D1".to_owned());
        let cfg = Path::new("config_D1.json");
        let src = Path::new("src.hdf5");
        let d0 = registry::env_args("stack", "D0");
        let pick = |t: Option<&str>, v: Option<&str>, s: Option<(&TaskSpec, &Path)>, e: Option<(&str, &Path)>| {
            resolve_task(t, v, s, e).map(|(task, variant)| (task.name().to_owned(), variant))
        };
        let got = |t, v, s, e| pick(t, v, s, e).unwrap();
        assert_eq!(got(None, None, Some((&spec, cfg)), Some((&d0, src))), ("stack".into(), "D1".into()));
        assert_eq!(got(None, None, None, Some((&d0, src))), ("stack".into(), "D0".into()));
        assert_eq!(got(None, Some("D0"), Some((&spec, cfg)), None), ("stack".into(), "D0".into()));
        assert_eq!(got(None, None, None, None), ("stack".into(), "D0".into()));
        let square = registry::env_args("square", "D0");
        assert_eq!(got(None, None, None, Some((&square, src))), ("square".into(), "D0".into()));
        let err = pick(None, None, Some((&spec, cfg)), Some((&square, src))).unwrap_err().to_string();
        assert!(err.contains("config_D1.json") && err.contains("src.hdf5") && err.contains("square"), "{err}");
        let err = pick(Some("square"), None, Some((&spec, cfg)), None).unwrap_err().to_string();
        assert!(err.contains("--task") && err.contains("config_D1.json"), "{err}");
    }
}
