//! One demo group read as MimicGen source data (its `datagen_info`, actions, states and
//! `model_file`), and the checks every demo of a file passes: per-step fields as long as its
//! actions. Each refusal names the file, group and field.

use std::collections::BTreeMap;

use mimicgen_engine::demo::{Rows, SimPayload, SourceDemo};
use mimicgen_engine::pose::{Mat4, Pose, pose_from_matrix};

use crate::error::{IoError, Result};
use crate::tree::{self, Array, Dataset, Group, Node};

/// Attribute of `data/<demo>`: the hand-marked start of each subtask's segment (one integer per
/// subtask, -1 where none is marked), written by `mimicgen annotate --starts`; planned transit
/// replays each segment from there. The reference MimicGen ignores it.
pub const STARTS_ATTR: &str = "mimicgen_subtask_starts";

/// Number of steps of a demo group (its `actions` rows).
#[must_use]
pub fn demo_steps(demo: &Group) -> usize {
    demo.dataset("actions").and_then(|a| a.array.shape.first().copied()).unwrap_or(0)
}

/// The demo `data/<name>` of `file` as MimicGen source data (its `datagen_info`, actions, states
/// and `model_file`), checked for shape and type.
///
/// # Errors
/// [`IoError::Missing`] for a missing `datagen_info` field, [`IoError::Shape`] or
/// [`IoError::Invalid`] naming the field that does not fit.
pub fn source_demo_from_group(file: &str, name: &str, demo: &Group) -> Result<SourceDemo> {
    source_demo_of_arm(file, name, demo, None)
}

/// [`source_demo_from_group`] as one arm of a two-arm demo sees it: the arm's own end effector
/// (`datagen_info/eef_pose/<arm>`, `target_pose/<arm>`, `gripper_action/<arm>`, Isaac Lab
/// Mimic's layout of several end effectors), the objects and signals both arms share.
///
/// # Errors
/// As [`source_demo_from_group`], naming the arm's field.
pub fn source_demo_of_arm(file: &str, name: &str, demo: &Group, arm: Option<&str>) -> Result<SourceDemo> {
    let group = format!("data/{name}");
    let steps = demo_steps(demo);
    let dg_group = format!("{group}/datagen_info");
    let info = demo.group("datagen_info").ok_or_else(|| missing(file, &group, "datagen_info"))?;
    let poses_of = |field: &str, g: &Group, gpath: &str| -> Result<Vec<Pose>> {
        let d = g.dataset(field).ok_or_else(|| missing(file, gpath, field))?;
        poses(file, gpath, field, d, steps)
    };
    let mut object_poses = BTreeMap::new();
    let objects_path = format!("{dg_group}/object_poses");
    let objects = info.group("object_poses").ok_or_else(|| missing(file, &dg_group, "object_poses"))?;
    for obj in objects.members.keys() {
        object_poses.insert(obj.clone(), poses_of(obj, objects, &objects_path)?);
    }
    let mut subtask_term_signals = BTreeMap::new();
    let signals_path = format!("{dg_group}/subtask_term_signals");
    let signals = info.group("subtask_term_signals").ok_or_else(|| missing(file, &dg_group, "subtask_term_signals"))?;
    for (sig, node) in &signals.members {
        let Node::Dataset(d) = node else { return Err(invalid(file, &signals_path, sig, "expected a dataset, found a group")) };
        let values = d
            .array
            .values
            .to_i64()
            .ok_or_else(|| invalid(file, &signals_path, sig, &format!("expected integers, found {}", d.array.values.dtype_name())))?;
        if values.len() != steps {
            return Err(shape(file, &signals_path, sig, &format!("has {} values but the demo has {steps} steps", values.len())));
        }
        subtask_term_signals.insert(sig.clone(), values);
    }
    let actions = rows(file, &group, "actions", demo.dataset("actions"))?;
    let states = rows(file, &group, "states", demo.dataset("states"))?;
    let manual_subtask_starts = match demo.attrs.get(STARTS_ATTR) {
        None => None,
        Some(a) => {
            let values =
                a.values.to_i64().ok_or_else(|| invalid(file, &group, STARTS_ATTR, "expected integers (-1 where no start is marked)"))?;
            Some(
                values
                    .iter()
                    .map(|&v| match usize::try_from(v) {
                        Ok(step) if step < steps => Ok(Some(step)),
                        Ok(step) => Err(invalid(file, &group, STARTS_ATTR, &format!("start {step} is past the demo's {steps} steps"))),
                        Err(_) if v == -1 => Ok(None),
                        Err(_) => Err(invalid(file, &group, STARTS_ATTR, &format!("{v} is neither a step nor -1"))),
                    })
                    .collect::<Result<Vec<_>>>()?,
            )
        }
    };
    // One arm's field: the dataset itself, or with `arm` the arm's dataset in its group.
    let arm_field = |field: &str| -> Result<(&Group, String, String)> {
        match arm {
            // A two-arm file read as one arm's: say so rather than that the field is missing.
            None if info.group(field).is_some() => Err(invalid(
                file,
                &dg_group,
                field,
                &format!(
                    "holds one end effector per arm ({}): a two-arm demo; `mimicgen generate --task two_arm_lift` (or two_arm_handover) and the app (annotate, preview, run) read it; this one-arm reader does not",
                    info.group(field).map(|g| g.members.keys().cloned().collect::<Vec<_>>().join(", ")).unwrap_or_default()
                ),
            )),
            None => Ok((info, dg_group.clone(), field.to_owned())),
            Some(arm) => {
                let g = info.group(field).ok_or_else(|| missing(file, &dg_group, field))?;
                Ok((g, format!("{dg_group}/{field}"), arm.to_owned()))
            }
        }
    };
    let (eef_group, eef_path, eef_field) = arm_field("eef_pose")?;
    let (target_group, target_path, target_field) = arm_field("target_pose")?;
    let (gripper_group, gripper_path, gripper_field) = arm_field("gripper_action")?;
    let eef_poses = poses_of(&eef_field, eef_group, &eef_path)?;
    let target_poses = poses_of(&target_field, target_group, &target_path)?;
    if arm.is_some() && gripper_group.dataset(&gripper_field).is_none() {
        return Err(missing(file, &gripper_path, &gripper_field));
    }
    Ok(SourceDemo {
        name: name.to_owned(),
        eef_poses,
        target_poses,
        gripper_actions: rows(file, &gripper_path, &gripper_field, gripper_group.dataset(&gripper_field))?,
        object_poses,
        subtask_term_signals,
        manual_subtask_ends: None,
        manual_subtask_starts,
        sim: SimPayload { actions, states, model_xml: demo.attrs.get("model_file").and_then(Array::as_str).map(str::to_owned) },
    })
}

fn poses(file: &str, group: &str, field: &str, d: &Dataset, steps: usize) -> Result<Vec<Pose>> {
    if d.array.shape.as_slice() != [steps, 4, 4] {
        return Err(shape(file, group, field, &format!("expected ({steps}, 4, 4) (one 4x4 pose per step), found {:?}", d.array.shape)));
    }
    let values = floats(file, group, field, d)?;
    values
        .chunks_exact(16)
        .enumerate()
        .map(|(t, m)| {
            pose_from_matrix(&Mat4::from_row_slice(m), &format!("step {t}")).map_err(|e| invalid(file, group, field, &e.to_string()))
        })
        .collect()
}

fn rows(file: &str, group: &str, field: &str, d: Option<&Dataset>) -> Result<Rows> {
    let Some(d) = d else { return Ok(Rows::new(0)) };
    let width = match d.array.shape.as_slice() {
        [_, w] => *w,
        [_] => 1,
        other => return Err(shape(file, group, field, &format!("expected (T, D), found {other:?}"))),
    };
    Rows::from_vec(width, floats(file, group, field, d)?, field).map_err(|e| shape(file, group, field, &e.to_string()))
}

fn floats(file: &str, group: &str, field: &str, d: &Dataset) -> Result<Vec<f64>> {
    d.array.values.to_f64().ok_or_else(|| invalid(file, group, field, &format!("expected numbers, found {}", d.array.values.dtype_name())))
}

pub(crate) fn missing(file: &str, group: &str, field: &str) -> IoError {
    IoError::Missing { file: file.to_owned(), group: group.to_owned(), field: field.to_owned(), hint: String::new() }
}

pub(crate) fn invalid(file: &str, group: &str, field: &str, reason: &str) -> IoError {
    IoError::Invalid { file: file.to_owned(), group: group.to_owned(), field: field.to_owned(), reason: reason.to_owned() }
}

pub(crate) fn shape(file: &str, group: &str, field: &str, reason: &str) -> IoError {
    IoError::Shape { file: file.to_owned(), group: group.to_owned(), field: field.to_owned(), reason: reason.to_owned() }
}

pub(crate) fn collect_paths(g: &Group, prefix: &str, out: &mut std::collections::BTreeSet<String>) {
    for (name, node) in &g.members {
        let path = tree::join(prefix, name);
        match node {
            Node::Dataset(_) => {
                out.insert(path);
            }
            Node::Group(sub) => collect_paths(sub, &path, out),
        }
    }
}

/// Checks that every per-step dataset of a demo has as many rows as `actions`.
pub(crate) fn check_demo(file: &str, name: &str, demo: &Group) -> Result<()> {
    let group = format!("data/{name}");
    let Some(actions) = demo.dataset("actions") else {
        return Err(IoError::Missing {
            file: file.to_owned(),
            group,
            field: "actions".into(),
            hint: "every robomimic demo needs its actions".into(),
        });
    };
    let Some(&steps) = actions.array.shape.first() else {
        return Err(IoError::Shape {
            file: file.to_owned(),
            group,
            field: "actions".into(),
            reason: "is a scalar, expected (T, action_dim)".into(),
        });
    };
    if let Some(n) = demo.attrs.get("num_samples").and_then(Array::as_i64)
        && usize::try_from(n).ok() != Some(steps)
    {
        return Err(IoError::Shape {
            file: file.to_owned(),
            group,
            field: "num_samples".into(),
            reason: format!("attribute says {n} but `actions` has {steps} rows"),
        });
    }
    let mut per_step = std::collections::BTreeSet::new();
    collect_paths(demo, "", &mut per_step);
    for path in per_step {
        if path == "src_demo_inds" {
            continue; // one entry per subtask, not per step
        }
        if let Some(d) = demo.dataset_at(&path)
            && d.array.shape.first() != Some(&steps)
        {
            let (g, field) =
                path.rsplit_once('/').map_or((group.clone(), path.clone()), |(dir, leaf)| (format!("{group}/{dir}"), leaf.to_owned()));
            return Err(IoError::Shape {
                file: file.to_owned(),
                group: g,
                field,
                reason: format!("has shape {:?} but `actions` has {steps} rows", d.array.shape),
            });
        }
    }
    Ok(())
}
