//! What a user asks of a run: every field of `mimicgen generate`.

use std::path::PathBuf;

use mimicgen_engine::Shard;
use serde::{Deserialize, Serialize};

use crate::{CameraConfig, SpecOverrides};

/// A run as the user describes it: every field of `mimicgen generate`. `None` means "the default"
/// or "what the inputs say".
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct RunConfig {
    /// Task (`stack`); default: what the config or the source file names, else `stack`.
    pub task: Option<String>,
    /// Variant (`D1`); default: what the config or the source file names, else `D0`.
    pub variant: Option<String>,
    /// Task spec file (our TOML or a MimicGen experiment JSON); default: the task's bundled spec.
    pub config: Option<PathBuf>,
    /// Source demos (MimicGen source layout); default: the task's bundled demos.
    pub source: Option<PathBuf>,
    /// Output dataset; failed attempts go to `<out>_failed.hdf5`, the report to `<out>.json`.
    pub out: PathBuf,
    /// Worker threads, each with its own simulator. The dataset does not depend on it.
    pub workers: usize,
    /// Attempts to make (successes to reach with `guarantee`); default: the spec's `num_trials`.
    pub num_demos: Option<usize>,
    /// Run seed; default: the spec's.
    pub seed: Option<u64>,
    /// Also write failed attempts (up to the spec's `max_num_failures`).
    pub keep_failed: bool,
    /// Keep attempting until `num_demos` successes.
    pub guarantee: bool,
    /// Hard cap on attempts with `guarantee`.
    pub max_attempts: Option<usize>,
    /// Fraction of demos, drawn with the run seed, in a `mask/valid` filter key.
    pub valid_fraction: Option<f64>,
    /// End an attempt as soon as a subtask ends without its signal (see `GenerationSettings`).
    pub early_abort: bool,
    /// Replace an existing output.
    pub overwrite: bool,
    /// Continue the interrupted run that left `<out>.partial`.
    pub resume: bool,
    /// Spec fields set for this run over the spec's (`--action-noise`, `--selection`, ...).
    #[serde(default)]
    pub spec: SpecOverrides,
    /// Make only this share of the attempts (`--shard 1/4`); `mimicgen merge` joins the shards
    /// into the dataset of the whole run.
    #[serde(default)]
    pub shard: Option<Shard>,
    /// Render these cameras into the dataset (`agentview_image`, ...); none by default.
    #[serde(default)]
    pub cameras: Option<CameraConfig>,
    /// The arm to generate with (`sawyer`); default: the sources' (their `model_file`), else the
    /// Panda. Another arm than the sources' runs in the task's scene composed with it.
    #[serde(default)]
    pub robot: Option<String>,
    /// Other forms of the actions written beside `actions` in every demo (`actions_abs`).
    #[serde(default)]
    pub actions: Vec<ActionForm>,
}

/// A form of a demo's actions beside robosuite's delta pose `actions`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ActionForm {
    /// `actions_abs`: the controller's absolute target at each step, as robomimic's
    /// `robosuite_add_absolute_actions.py` writes it: position (3, world frame), rotation as an
    /// axis-angle vector (3), then the rest of the action unchanged (gripper; a base's three).
    Abs,
    /// `actions_joint`: the arm's joint positions at the next step (one per arm joint), then the
    /// gripper action, for learners of joint-space policies; a joint-position controller replays
    /// them.
    Joint,
}

impl ActionForm {
    /// The dataset key of this form (`actions_abs`).
    #[must_use]
    pub fn key(self) -> &'static str {
        match self {
            Self::Abs => "actions_abs",
            Self::Joint => "actions_joint",
        }
    }

    /// The name a front end gives this form (`abs`).
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Abs => "abs",
            Self::Joint => "joint",
        }
    }
}

impl Default for RunConfig {
    fn default() -> Self {
        Self {
            task: None,
            variant: None,
            config: None,
            source: None,
            out: PathBuf::from("out/generated.hdf5"),
            workers: 1,
            num_demos: None,
            seed: None,
            keep_failed: false,
            guarantee: false,
            max_attempts: None,
            valid_fraction: None,
            early_abort: false,
            overwrite: false,
            resume: false,
            spec: SpecOverrides::default(),
            shard: None,
            cameras: None,
            robot: None,
            actions: Vec::new(),
        }
    }
}

impl RunConfig {
    /// The `mimicgen generate` arguments that describe this run (the flags; a field at its
    /// default is left out). Every field is named here, so a new field does not compile until it
    /// has its flag; the CLI's tests parse these back into the same config.
    #[must_use]
    pub fn to_args(&self) -> Vec<String> {
        let Self {
            task,
            variant,
            config,
            source,
            out,
            workers,
            num_demos,
            seed,
            keep_failed,
            guarantee,
            max_attempts,
            valid_fraction,
            early_abort,
            overwrite,
            resume,
            spec,
            shard,
            cameras,
            robot,
            actions,
        } = self;
        let mut args: Vec<String> = Vec::new();
        let mut value = |flag: &str, v: Option<String>| {
            if let Some(v) = v {
                args.extend([flag.to_owned(), v]);
            }
        };
        value("--task", task.clone());
        value("--variant", variant.clone());
        value("--robot", robot.clone());
        value("--config", config.as_ref().map(|p| p.display().to_string()));
        value("--source", source.as_ref().map(|p| p.display().to_string()));
        value("--num-demos", num_demos.map(|n| n.to_string()));
        value("--seed", seed.map(|n| n.to_string()));
        value("--workers", Some(workers.to_string()));
        value("--out", Some(out.display().to_string()));
        value("--max-attempts", max_attempts.map(|n| n.to_string()));
        value("--valid-fraction", valid_fraction.map(|f| f.to_string()));
        value("--shard", shard.map(|s| s.to_string()));
        value("--actions", (!actions.is_empty()).then(|| actions.iter().map(|a| a.name()).collect::<Vec<_>>().join(",")));
        if let Some(c) = cameras {
            value("--cameras", Some(c.names.join(",")));
            value("--camera-size", Some(if c.height == c.width { c.height.to_string() } else { format!("{}x{}", c.height, c.width) }));
        }
        for (on, flag) in [
            (*keep_failed, "--keep-failed"),
            (*guarantee, "--guarantee"),
            (*early_abort, "--early-abort"),
            (*overwrite, "--overwrite"),
            (*resume, "--resume"),
            (cameras.as_ref().is_some_and(|c| c.depth), "--camera-depth"),
            (cameras.as_ref().is_some_and(|c| c.fast), "--camera-fast"),
            (cameras.as_ref().is_some_and(|c| c.reflection), "--camera-reflection"),
        ] {
            if on {
                args.push(flag.to_owned());
            }
        }
        args.extend(spec.to_args());
        args
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flags_name_what_differs_from_the_default() {
        let args = RunConfig { num_demos: Some(3), guarantee: true, ..RunConfig::default() }.to_args();
        assert_eq!(args, ["--num-demos", "3", "--workers", "1", "--out", "out/generated.hdf5", "--guarantee"]);
        let cameras = CameraConfig { height: 120, width: 160, depth: true, ..CameraConfig::default() };
        let args = RunConfig { cameras: Some(cameras), robot: Some("ur5e".into()), ..RunConfig::default() }.to_args();
        let line = args.join(" ");
        assert!(line.contains("--robot ur5e") && line.contains("--cameras agentview,robot0_eye_in_hand --camera-size 120x160"), "{line}");
        assert!(line.ends_with("--camera-depth"), "{line}");
    }
}
