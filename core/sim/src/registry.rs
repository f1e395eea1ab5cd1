//! The tasks this backend knows, their variants, and robosuite's `env_args` metadata for them.

use std::sync::{Arc, OnceLock};

use crate::data_task::DataTask;
use crate::task::Task;
use crate::task_file::TaskFile;

/// `(name, task file, generation spec)` of every task we ship, by name: each
/// `core/sim/tasks/<name>.task.toml` with `<name>.toml` beside it, listed by the build script (a
/// new task is a new file there, and no line of code).
const BUNDLED: &[(&str, &str, Option<&str>)] = include!(concat!(env!("OUT_DIR"), "/bundled_tasks.rs"));

/// The environment variable naming a directory of the user's own task files: every
/// `<name>.task.toml` there (with its generation spec `<name>.toml` beside it, if any) joins the
/// bundled tasks, replacing a bundled task of the same name.
pub const TASK_DIR_VAR: &str = "MIMICGEN_TASK_DIR";

/// A task file and its generation spec.
struct Entry {
    file: TaskFile,
    spec: Option<&'static str>,
}

/// A task file that cannot be used, by the task name its file name gives.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Broken {
    /// The task's name (`tower` for `tower.task.toml`).
    pub name: String,
    /// Why, naming the file and the field.
    pub error: String,
}

/// The task files: those that parse, and those that do not.
struct Registry {
    entries: Vec<Entry>,
    broken: Vec<Broken>,
}

/// The bundled task files and the user's, parsed once. A file that does not parse hides only its
/// own task: using that task reports its error, and the others work.
fn parsed() -> &'static Registry {
    static FILES: OnceLock<Registry> = OnceLock::new();
    FILES.get_or_init(|| {
        let mut registry = Registry { entries: Vec::new(), broken: Vec::new() };
        for (name, text, spec) in BUNDLED {
            match TaskFile::from_toml_str(text, &format!("core/sim/tasks/{name}.task.toml")) {
                Ok(file) => registry.entries.push(Entry { file, spec: *spec }),
                Err(error) => registry.broken.push(Broken { name: (*name).to_owned(), error }),
            }
        }
        if let Some(dir) = std::env::var_os(TASK_DIR_VAR) {
            user_tasks(std::path::Path::new(&dir), &mut registry);
        }
        registry
    })
}

/// Adds the task files in `dir`, by file name, replacing a bundled task of the same name. Each is
/// read once per process, so its text is kept for the process's life.
fn user_tasks(dir: &std::path::Path, registry: &mut Registry) {
    let listing = match std::fs::read_dir(dir) {
        Ok(listing) => listing,
        Err(e) => {
            let error = format!("{TASK_DIR_VAR}={}: {e}", dir.display());
            registry.broken.push(Broken { name: TASK_DIR_VAR.to_owned(), error });
            return;
        }
    };
    let mut paths: Vec<std::path::PathBuf> =
        listing.filter_map(Result::ok).map(|e| e.path()).filter(|p| p.to_string_lossy().ends_with(".task.toml")).collect();
    paths.sort();
    for path in paths {
        let stem = path.file_name().map(|n| n.to_string_lossy().trim_end_matches(".task.toml").to_owned()).unwrap_or_default();
        match user_task(&path) {
            Ok(entry) => {
                registry.broken.retain(|b| b.name != entry.file.name);
                match registry.entries.iter_mut().find(|e| e.file.name == entry.file.name) {
                    Some(bundled) => *bundled = entry,
                    None => registry.entries.push(entry),
                }
            }
            Err(error) => {
                // The user's file meant to replace a bundled task of its name: that task is broken.
                registry.entries.retain(|e| e.file.name != stem);
                registry.broken.push(Broken { name: stem, error });
            }
        }
    }
}

fn user_task(path: &std::path::Path) -> Result<Entry, String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let file = TaskFile::from_toml_str(&text, &path.display().to_string())?;
    let spec_path = path.with_file_name(format!("{}.toml", file.name));
    let spec = match std::fs::read_to_string(&spec_path) {
        Ok(spec) => Some(&*Box::leak(spec.into_boxed_str())),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => None,
        Err(e) => return Err(format!("{}: {e}", spec_path.display())),
    };
    Ok(Entry { file, spec })
}

/// Every task that can be used, in the order `mimicgen tasks` lists them: the bundled ones by
/// name, then the user's ([`TASK_DIR_VAR`]).
pub fn tasks() -> impl Iterator<Item = &'static TaskFile> {
    parsed().entries.iter().map(|e| &e.file)
}

/// The task files that cannot be used, each with its error (naming the file and field).
#[must_use]
pub fn broken() -> &'static [Broken] {
    &parsed().broken
}

fn names() -> String {
    tasks().map(|t| t.name.as_str()).collect::<Vec<_>>().join(", ")
}

/// The instruction of task `name` (its name when unknown).
#[must_use]
pub fn instruction(name: &str) -> String {
    tasks().find(|t| t.name == name).map_or_else(|| name.replace('_', " "), |t| t.instruction.clone())
}

/// The generation spec (our TOML; the paper's settings for the bundled tasks) for `name`.
#[must_use]
pub fn default_spec_toml(name: &str) -> Option<&'static str> {
    parsed().entries.iter().find(|e| e.file.name == name).and_then(|e| e.spec)
}

/// Builds `name` / `variant`.
///
/// # Errors
/// A message naming the known tasks or variants.
pub fn task(name: &str, variant: &str) -> Result<Arc<dyn Task>, String> {
    let wanted = name.to_ascii_lowercase();
    if let Some(broken) = broken().iter().find(|b| b.name == wanted) {
        return Err(broken.error.clone());
    }
    let entry = parsed()
        .entries
        .iter()
        .find(|e| e.file.name == wanted)
        .ok_or_else(|| format!("unknown task {wanted:?}; known tasks: {}", names()))?;
    Ok(Arc::new(DataTask::new(entry.file.clone(), variant)?))
}

/// The task and variant a robosuite `env_name` names (`Stack_D0` -> stack, D0; `StackThree_D1`
/// -> stack_three, D1; `MugCleanup_O2` -> mug_cleanup, O2; a bare `Stack` is D0).
///
/// # Errors
/// A message naming the known environments when `env_name` is not one of them.
pub fn task_from_env_name(env_name: &str) -> Result<(Arc<dyn Task>, String), String> {
    let is_variant = |base: &str, v: &str| {
        v.starts_with('D') || tasks().any(|t| t.env_name.eq_ignore_ascii_case(base) && t.variants.iter().any(|x| x.eq_ignore_ascii_case(v)))
    };
    let (base, variant) = env_name.rsplit_once('_').filter(|(base, v)| is_variant(base, v)).unwrap_or((env_name, "D0"));
    let info = tasks().find(|t| t.env_name.eq_ignore_ascii_case(base)).ok_or_else(|| {
        if let Some(two_arm) = crate::two_arm::TwoArmTask::ALL.into_iter().find(|t| t.env_name().eq_ignore_ascii_case(base)) {
            return format!(
                "environment {env_name:?} is two-arm ({}): `mimicgen generate --task {}`, `mimicgen prepare` and the app's annotate screen read it; this command is one-arm only so far",
                two_arm.name(),
                two_arm.name()
            );
        }
        let envs: Vec<&str> = tasks().map(|t| t.env_name.as_str()).collect();
        format!("environment {env_name:?} is not one of ours ({})", envs.join(", "))
    })?;
    Ok((task(&info.name, variant)?, variant.to_owned()))
}

/// The task and variant a dataset's `env_args` JSON names through its `env_name`.
///
/// # Errors
/// A message saying what is missing or unknown.
pub fn task_from_env_args(env_args: Option<&str>) -> Result<(Arc<dyn Task>, String), String> {
    let env_name = env_args
        .and_then(|a| serde_json::from_str::<serde_json::Value>(a).ok())
        .and_then(|v| v.get("env_name").and_then(|n| n.as_str()).map(str::to_owned))
        .ok_or_else(|| "the dataset has no env_args with an env_name, so its task is unknown".to_owned())?;
    task_from_env_name(&env_name)
}

/// `env_args` for data generated on `name` / `variant` from sources whose file had
/// `source_env_args`: the sources' metadata (their controller settings) with `env_name` set to
/// the generated variant, or [`env_args`] when the sources have none.
#[must_use]
pub fn env_args_for_variant(source_env_args: Option<&str>, name: &str, variant: &str) -> String {
    let ours: serde_json::Value = serde_json::from_str(&env_args(name, variant)).unwrap_or_default();
    match source_env_args.and_then(|a| serde_json::from_str::<serde_json::Value>(a).ok()) {
        Some(serde_json::Value::Object(mut theirs)) => {
            theirs.insert("env_name".to_owned(), ours.get("env_name").cloned().unwrap_or_default());
            serde_json::Value::Object(theirs).to_string()
        }
        _ => ours.to_string(),
    }
}

/// `env_args` with `edit` applied to its `env_kwargs` (made an object if missing); unchanged when
/// it is not a JSON object.
fn with_env_kwargs(env_args: &str, edit: impl FnOnce(&mut serde_json::Value)) -> String {
    let mut args: serde_json::Value = serde_json::from_str(env_args).unwrap_or_default();
    let Some(fields) = args.as_object_mut() else { return env_args.to_owned() };
    let kwargs = fields.entry("env_kwargs").or_insert_with(|| serde_json::json!({}));
    if !kwargs.is_object() {
        *kwargs = serde_json::json!({});
    }
    edit(kwargs);
    args.to_string()
}

/// `env_args` with robosuite's camera settings for `cameras` (what robomimic reads to render the
/// same images in the environment it rebuilds).
#[must_use]
pub fn env_args_with_cameras(env_args: &str, cameras: &crate::camera::CameraConfig) -> String {
    with_env_kwargs(env_args, |kwargs| {
        kwargs["use_camera_obs"] = true.into();
        kwargs["has_offscreen_renderer"] = true.into();
        kwargs["camera_names"] = cameras.names.clone().into();
        kwargs["camera_heights"] = cameras.height.into();
        kwargs["camera_widths"] = cameras.width.into();
        kwargs["camera_depths"] = cameras.depth.into();
    })
}

/// `env_args` naming `robot` as robosuite names it (`env_kwargs.robots`), so robosuite builds the
/// same arm.
#[must_use]
pub fn env_args_with_robot(env_args: &str, robot: &crate::robot::RobotModel) -> String {
    with_env_kwargs(env_args, |kwargs| kwargs["robots"] = serde_json::json!([robot.robosuite_name]))
}

/// robosuite/robomimic's `env_args` JSON for `name` / `variant`, as the reference writes it
/// (OSC_POSE, kp 150, 20 Hz, Panda), so robomimic can rebuild the environment.
#[must_use]
pub fn env_args(name: &str, variant: &str) -> String {
    let env_name = tasks().find(|t| t.name == name).map_or(name, |t| t.env_name.as_str());
    serde_json::json!({
        "env_name": format!("{env_name}_{}", variant.to_ascii_uppercase()),
        "env_version": "1.4.1",
        "type": 1,
        "env_kwargs": {
            "has_renderer": false,
            "has_offscreen_renderer": false,
            "ignore_done": true,
            "use_object_obs": true,
            "use_camera_obs": false,
            "control_freq": 20,
            "controller_configs": {
                "type": "OSC_POSE",
                "input_max": 1,
                "input_min": -1,
                "output_max": [0.05, 0.05, 0.05, 0.5, 0.5, 0.5],
                "output_min": [-0.05, -0.05, -0.05, -0.5, -0.5, -0.5],
                "kp": 150,
                "damping_ratio": 1,
                "impedance_mode": "fixed",
                "kp_limits": [0, 300],
                "damping_ratio_limits": [0, 10],
                "position_limits": null,
                "orientation_limits": null,
                "uncouple_pos_ori": true,
                "control_delta": true,
                "interpolation": null,
                "ramp_ratio": 0.2
            },
            "robots": ["Panda"],
            "camera_depths": false,
            "camera_heights": 84,
            "camera_widths": 84,
            "reward_shaping": false
        }
    })
    .to_string()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_bundled_task_file_parses_and_builds_each_variant() {
        assert!(broken().is_empty(), "{:?}", broken());
        let files: Vec<&TaskFile> = tasks().collect();
        assert_eq!(files.len(), BUNDLED.len());
        assert!(files.len() >= 9 && files.iter().any(|f| f.name == "stack"), "the build script listed {}", files.len());
        for (file, (name, ..)) in files.iter().zip(BUNDLED) {
            assert_eq!(&file.name, name);
            for variant in &file.variants {
                let task = task(name, variant).unwrap_or_else(|e| panic!("{e}"));
                // Each variant's objects (C0's clutter is in C0 only).
                assert_eq!(task.coverage_dimensions().len(), 3 * task.objects().len());
            }
        }
    }

    #[test]
    fn env_names_map_to_tasks() {
        let (task, variant) = task_from_env_name("StackThree_D1").unwrap_or_else(|e| panic!("{e}"));
        assert_eq!((task.name(), variant.as_str()), ("stack_three", "D1"));
        assert_eq!(task_from_env_name("Stack").map(|(t, v)| (t.name().to_owned(), v)), Ok(("stack".to_owned(), "D0".to_owned())));
        assert!(task_from_env_name("NoSuchTask_D0").is_err());
        assert_eq!(
            task_from_env_name("GearAssembly_D2").map(|(t, v)| (t.name().to_owned(), v)),
            Ok(("gear_assembly".to_owned(), "D2".to_owned()))
        );
        assert_eq!(task_from_env_name("Kitchen_D1").map(|(t, v)| (t.name().to_owned(), v)), Ok(("kitchen".to_owned(), "D1".to_owned())));
        let (task, variant) = task_from_env_name("MugCleanup_O2").unwrap_or_else(|e| panic!("{e}"));
        assert_eq!((task.name(), variant.as_str(), task.instances().len()), ("mug_cleanup", "O2", 12));
        assert_eq!(task_from_env_name("Lift").map(|(t, v)| (t.name().to_owned(), v)), Ok(("lift".to_owned(), "D0".to_owned())));
        let args: serde_json::Value = serde_json::from_str(&env_args("stack_three", "d1")).unwrap_or_default();
        assert_eq!(args["env_name"], "StackThree_D1");
        let carried: serde_json::Value =
            serde_json::from_str(&env_args_for_variant(Some(r#"{"env_name": "Stack_D0", "env_version": "9"}"#), "stack", "D1"))
                .unwrap_or_default();
        assert_eq!((carried["env_name"].as_str(), carried["env_version"].as_str()), (Some("Stack_D1"), Some("9")));
    }
}
