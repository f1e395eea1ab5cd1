//! Streaming writer for generated datasets in robomimic layout.
//!
//! One writer's lifecycle (create or resume a `.partial`, append demos, commit progress, finish by
//! rename), whose steps share its open file and checkpoint.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use mimicgen_engine::demo::Rows;
use mimicgen_engine::generate::Attempt;
use mimicgen_engine::image::{ImageStream, Pixels};
use mimicgen_engine::pose::{Pose, pose_to_matrix};

use crate::dataset::COMPLETE_ATTR;
use crate::error::{IoError, Result};
use crate::tree::{self, Array, Dataset, Group, Node, Values};

/// An observation stream: shape of one step's value, then all steps' values row-major.
pub type Observation = (Vec<usize>, Vec<f64>);

/// MimicGen's per-step annotations (`datagen_info`).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct DatagenInfo {
    /// `world_from_eef` per step.
    pub eef_poses: Vec<Pose>,
    /// `world_from_target` per step.
    pub target_poses: Vec<Pose>,
    /// Gripper actions, `(T, gripper_dim)`.
    pub gripper_actions: Rows,
    /// `world_from_object` per object, per step.
    pub object_poses: BTreeMap<String, Vec<Pose>>,
    /// Subtask-end signals per name, per step.
    pub subtask_term_signals: BTreeMap<String, Vec<i64>>,
    /// Two arms: each arm's own end effector, written in place of `eef_poses`, `target_poses`
    /// and `gripper_actions` as `datagen_info/eef_pose/<arm>` (Isaac Lab Mimic's layout of
    /// several end effectors); empty for one arm.
    pub arms: Vec<ArmInfo>,
}

/// One arm's per-step annotations in a two-arm demo.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ArmInfo {
    /// The arm (`robot0`).
    pub name: String,
    /// `world_from_eef` per step.
    pub eef_poses: Vec<Pose>,
    /// `world_from_target` per step.
    pub target_poses: Vec<Pose>,
    /// Gripper actions, `(T, gripper_dim)`.
    pub gripper_actions: Rows,
}

/// Everything written for one demo.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct DemoData {
    /// Actions, `(T, action_dim)`.
    pub actions: Rows,
    /// The same actions in other forms, by dataset key (`actions_abs`), `(T, width)` each.
    pub other_actions: BTreeMap<String, Rows>,
    /// Flattened simulator states, `(T, state_dim)` (may be empty).
    pub states: Rows,
    /// Reward per step, if known.
    pub rewards: Option<Vec<f64>>,
    /// Done flag per step, if known.
    pub dones: Option<Vec<i64>>,
    /// Observations by key (`robot0_eef_pos` -> per-step shape `[3]` and `T * 3` values).
    pub obs: BTreeMap<String, Observation>,
    /// Camera observations by key (`agentview_image`), written under `obs/` as robomimic has them:
    /// `(T, H, W, C)`, `uint8` for RGB, one gzip-compressed chunk per frame.
    pub images: BTreeMap<String, ImageStream>,
    /// MimicGen annotations, if any.
    pub datagen_info: Option<DatagenInfo>,
    /// Source demo index used for each subtask.
    pub src_demo_inds: Vec<i64>,
    /// Source demo index behind each step.
    pub src_demo_labels: Vec<i64>,
    /// The scene XML (`model_file` attribute).
    pub model_xml: Option<String>,
    /// Index of the generation attempt this demo came from (`mimicgen_attempt` attribute), which
    /// lets an interrupted run resume exactly where its last kept attempt was decided.
    pub attempt_index: Option<u64>,
    /// Where and why the attempt failed (written as [`FAILURE_ATTR`]).
    pub failure: Option<String>,
    /// What went wrong there, as JSON (written as [`CAUSE_ATTR`]).
    pub cause: Option<String>,
    /// Which of a variant's object instances the episode used (written as [`INSTANCE_ATTR`]).
    pub object_instance: Option<String>,
}

/// The demo attribute holding [`DemoData::attempt_index`].
pub const ATTEMPT_ATTR: &str = "mimicgen_attempt";
/// Demo attribute of a failed attempt: where and why it failed (`subtask 0: signal "grasp" never
/// turned on`), so a failed-attempts file explains itself.
pub const FAILURE_ATTR: &str = "mimicgen_failure";
/// Demo attribute of a failed attempt: its cause ([`mimicgen_engine::diagnose::Cause`]) as JSON,
/// `{"kind": "grasp_missed", "object": "cubeA", "step": 61, "off_source_m": 0.004}`.
pub const CAUSE_ATTR: &str = "mimicgen_failure_cause";
/// Demo attribute naming the object instance an object-transfer episode drew (`tall_green`).
pub const INSTANCE_ATTR: &str = "mimicgen_object_instance";

impl DemoData {
    /// A generation attempt as a demo: its trajectory, annotations and source labels, with
    /// reward 1 and done 1 on the last step of a successful attempt.
    #[must_use]
    pub fn from_attempt(attempt: &Attempt, obs: BTreeMap<String, Observation>, model_xml: Option<String>) -> Self {
        let t = &attempt.trajectory;
        let n = t.len();
        let last = |on: bool| (0..n).map(|i| i64::from(on && i + 1 == n)).collect::<Vec<i64>>();
        let to_i64 = |v: &[usize]| v.iter().map(|&x| i64::try_from(x).unwrap_or(i64::MAX)).collect::<Vec<i64>>();
        Self {
            actions: t.actions.clone(),
            other_actions: BTreeMap::new(),
            states: t.states.clone(),
            #[allow(clippy::cast_precision_loss)]
            rewards: Some(last(attempt.success).iter().map(|&x| x as f64).collect()),
            dones: Some(last(attempt.success)),
            obs,
            images: BTreeMap::new(),
            datagen_info: Some(DatagenInfo {
                eef_poses: t.eef_poses.clone(),
                target_poses: t.target_poses.clone(),
                gripper_actions: t.gripper_actions.clone(),
                object_poses: t.object_poses.clone(),
                subtask_term_signals: t.subtask_term_signals.clone(),
                arms: Vec::new(),
            }),
            src_demo_inds: to_i64(&attempt.src_demo_per_subtask),
            src_demo_labels: to_i64(&t.src_demo_labels),
            model_xml,
            attempt_index: Some(attempt.index),
            failure: attempt.failure.as_ref().map(|f| format!("subtask {}: {}", f.subtask, f.reason)),
            cause: attempt.cause.as_ref().and_then(|c| serde_json::to_string(c).ok()),
            object_instance: None,
        }
    }

    /// A two-arm attempt (or a scripted two-arm demo) as a demo: both arms' actions in one row,
    /// each arm's poses, targets and gripper under `datagen_info/<field>/<arm>` (`arms` names
    /// them: `robot0`, `robot1`), reward and done 1 on the last step of a success.
    /// `src_demo_inds` lists arm 0's subtasks' source demos, then arm 1's; `src_demo_labels`
    /// are arm 0's.
    #[must_use]
    pub fn from_two_arm_attempt(
        attempt: &mimicgen_engine::two_arm::TwoArmAttempt,
        arms: &[&str],
        obs: BTreeMap<String, Observation>,
        model_xml: Option<String>,
    ) -> Self {
        let n = attempt.actions.len();
        let last = |on: bool| (0..n).map(|i| i64::from(on && i + 1 == n)).collect::<Vec<i64>>();
        let to_i64 = |v: &mut dyn Iterator<Item = usize>| v.map(|x| i64::try_from(x).unwrap_or(i64::MAX)).collect::<Vec<i64>>();
        let arm_infos = attempt
            .arms
            .iter()
            .zip(arms)
            .map(|(track, name)| ArmInfo {
                name: (*name).to_owned(),
                eef_poses: track.eef_poses.clone(),
                target_poses: track.target_poses.clone(),
                gripper_actions: track.gripper_actions.clone(),
            })
            .collect();
        Self {
            actions: attempt.actions.clone(),
            other_actions: BTreeMap::new(),
            states: attempt.states.clone(),
            #[allow(clippy::cast_precision_loss)]
            rewards: Some(last(attempt.success).iter().map(|&x| x as f64).collect()),
            dones: Some(last(attempt.success)),
            obs,
            images: BTreeMap::new(),
            datagen_info: Some(DatagenInfo {
                eef_poses: Vec::new(),
                target_poses: Vec::new(),
                gripper_actions: Rows::new(0),
                object_poses: attempt.object_poses.clone(),
                subtask_term_signals: attempt.subtask_term_signals.clone(),
                arms: arm_infos,
            }),
            src_demo_inds: to_i64(&mut attempt.arms.iter().flat_map(|t| t.plans.iter().map(|p| p.src_demo))),
            src_demo_labels: attempt.arms.first().map(|t| to_i64(&mut t.src_demo_labels.iter().copied())).unwrap_or_default(),
            model_xml,
            attempt_index: Some(attempt.index),
            failure: attempt.failure.as_ref().map(ToString::to_string),
            cause: None,
            object_instance: None,
        }
    }

    /// The demo as a [`Group`] tree, checking that every per-step array has `actions.len()` rows.
    fn to_group(&self, file: &str, group: &str, compress_obs: bool) -> Result<Group> {
        let steps = self.actions.len();
        let usage = |field: &str, reason: String| IoError::Usage {
            file: file.to_owned(),
            group: group.to_owned(),
            field: field.to_owned(),
            reason,
        };
        let check = |field: &str, len: usize| {
            if len == steps { Ok(()) } else { Err(usage(field, format!("has {len} steps but `actions` has {steps}"))) }
        };
        let mut g = Group::default();
        let put = |g: &mut Group, name: &str, array: Array| g.members.insert(name.to_owned(), Node::Dataset(Dataset::new(array)));
        put(&mut g, "actions", rows_array(&self.actions));
        for (key, rows) in &self.other_actions {
            check(key, rows.len())?;
            put(&mut g, key, rows_array(rows));
        }
        if !self.states.is_empty() {
            check("states", self.states.len())?;
            put(&mut g, "states", rows_array(&self.states));
        }
        if let Some(r) = &self.rewards {
            check("rewards", r.len())?;
            put(&mut g, "rewards", Array::f64(vec![r.len()], r.clone()));
        }
        if let Some(d) = &self.dones {
            check("dones", d.len())?;
            put(&mut g, "dones", Array::i64(vec![d.len()], d.clone()));
        }
        if !self.obs.is_empty() {
            let mut obs = Group::default();
            for (key, (shape, values)) in &self.obs {
                let per_step: usize = shape.iter().product();
                if per_step * steps != values.len() {
                    return Err(usage(
                        &format!("obs/{key}"),
                        format!("{} values do not make {steps} steps of shape {shape:?}", values.len()),
                    ));
                }
                let mut full = vec![steps];
                full.extend_from_slice(shape);
                let mut d = Dataset::new(Array::f64(full.clone(), values.clone()));
                if compress_obs && steps > 0 {
                    d.chunks = Some(full);
                    d.deflate = Some(4);
                }
                obs.members.insert(key.clone(), Node::Dataset(d));
            }
            g.members.insert("obs".into(), Node::Group(obs));
        }
        if !self.images.is_empty() {
            let Node::Group(obs) = g.members.entry("obs".into()).or_insert_with(|| Node::Group(Group::default())) else {
                return Err(usage("obs", "is not a group".to_owned()));
            };
            for (key, stream) in &self.images {
                if obs.members.contains_key(key) {
                    return Err(usage(&format!("obs/{key}"), "is both a low-dim and a camera observation".to_owned()));
                }
                if stream.steps() != steps || stream.steps() * stream.shape.iter().product::<usize>() != stream.len() {
                    return Err(usage(
                        &format!("obs/{key}"),
                        format!("{} values do not make {steps} images of shape {:?}", stream.len(), stream.shape),
                    ));
                }
                let d = image_dataset(stream);
                obs.members.insert(key.clone(), Node::Dataset(d));
            }
        }
        if let Some(info) = &self.datagen_info {
            let mut dg = Group::default();
            if info.arms.is_empty() {
                check("datagen_info/eef_pose", info.eef_poses.len())?;
                check("datagen_info/target_pose", info.target_poses.len())?;
                check("datagen_info/gripper_action", info.gripper_actions.len())?;
                put(&mut dg, "eef_pose", poses_array(&info.eef_poses));
                put(&mut dg, "target_pose", poses_array(&info.target_poses));
                put(&mut dg, "gripper_action", rows_array(&info.gripper_actions));
            } else {
                let (mut eef, mut target, mut gripper) = (Group::default(), Group::default(), Group::default());
                for arm in &info.arms {
                    check(&format!("datagen_info/eef_pose/{}", arm.name), arm.eef_poses.len())?;
                    check(&format!("datagen_info/target_pose/{}", arm.name), arm.target_poses.len())?;
                    check(&format!("datagen_info/gripper_action/{}", arm.name), arm.gripper_actions.len())?;
                    put(&mut eef, &arm.name, poses_array(&arm.eef_poses));
                    put(&mut target, &arm.name, poses_array(&arm.target_poses));
                    put(&mut gripper, &arm.name, rows_array(&arm.gripper_actions));
                }
                dg.members.insert("eef_pose".into(), Node::Group(eef));
                dg.members.insert("target_pose".into(), Node::Group(target));
                dg.members.insert("gripper_action".into(), Node::Group(gripper));
            }
            let mut objects = Group::default();
            for (name, poses) in &info.object_poses {
                check(&format!("datagen_info/object_poses/{name}"), poses.len())?;
                put(&mut objects, name, poses_array(poses));
            }
            let mut signals = Group::default();
            for (name, values) in &info.subtask_term_signals {
                check(&format!("datagen_info/subtask_term_signals/{name}"), values.len())?;
                put(&mut signals, name, Array::i64(vec![values.len()], values.clone()));
            }
            dg.members.insert("object_poses".into(), Node::Group(objects));
            dg.members.insert("subtask_term_signals".into(), Node::Group(signals));
            g.members.insert("datagen_info".into(), Node::Group(dg));
        }
        if !self.src_demo_inds.is_empty() {
            put(&mut g, "src_demo_inds", Array::i64(vec![self.src_demo_inds.len()], self.src_demo_inds.clone()));
        }
        if !self.src_demo_labels.is_empty() {
            check("src_demo_labels", self.src_demo_labels.len())?;
            put(&mut g, "src_demo_labels", Array::i64(vec![self.src_demo_labels.len(), 1], self.src_demo_labels.clone()));
        }
        if let Some(xml) = &self.model_xml {
            g.attrs.insert("model_file".into(), Array::string(xml));
        }
        if let Some(index) = self.attempt_index {
            g.attrs.insert(ATTEMPT_ATTR.into(), Array::int(i64::try_from(index).unwrap_or(i64::MAX)));
        }
        if let Some(failure) = &self.failure {
            g.attrs.insert(FAILURE_ATTR.into(), Array::string(failure));
        }
        if let Some(cause) = &self.cause {
            g.attrs.insert(CAUSE_ATTR.into(), Array::string(cause));
        }
        if let Some(instance) = &self.object_instance {
            g.attrs.insert(INSTANCE_ATTR.into(), Array::string(instance));
        }
        Ok(g)
    }
}

/// A camera stream as robomimic stores it: `(T, H, W, C)`, `uint8` RGB or `float32` depth, one
/// gzip-compressed chunk per frame.
#[must_use]
pub fn image_dataset(stream: &ImageStream) -> Dataset {
    let steps = stream.steps();
    let mut full = vec![steps];
    full.extend_from_slice(&stream.shape);
    let values = match &stream.pixels {
        Pixels::Rgb(p) => Values::U8(p.clone()),
        Pixels::Depth(p) => Values::F32(p.clone()),
    };
    let mut d = Dataset::new(Array { shape: full.clone(), values });
    if steps > 0 {
        if let Some(rows) = full.first_mut() {
            *rows = 1;
        }
        d.chunks = Some(full);
        d.deflate = Some(4);
    }
    d
}

/// A demo's `obs` group split as [`DemoData`] holds it: low-dim streams as `f64`, and camera
/// streams (`uint8` RGB or `float32` depth, `(T, H, W, C)`) as images, their type kept.
#[must_use]
pub fn observations_from_group(obs: &Group) -> (BTreeMap<String, Observation>, BTreeMap<String, ImageStream>) {
    let (mut low_dim, mut images) = (BTreeMap::new(), BTreeMap::new());
    for (key, node) in &obs.members {
        let Node::Dataset(d) = node else { continue };
        let shape = &d.array.shape;
        let image_shape = match shape.as_slice() {
            &[_, h, w, c] => Some([h, w, c]),
            _ => None,
        };
        match (&d.array.values, image_shape) {
            (Values::U8(p), Some(shape)) => {
                images.insert(key.clone(), ImageStream { shape, pixels: Pixels::Rgb(p.clone()) });
            }
            (Values::F32(p), Some(shape)) if key.ends_with("_depth") => {
                images.insert(key.clone(), ImageStream { shape, pixels: Pixels::Depth(p.clone()) });
            }
            (values, _) => {
                if let Some(v) = values.to_f64() {
                    low_dim.insert(key.clone(), (shape.get(1..).unwrap_or_default().to_vec(), v));
                }
            }
        }
    }
    (low_dim, images)
}

fn rows_array(rows: &Rows) -> Array {
    Array::f64(vec![rows.len(), rows.width()], rows.as_slice().to_vec())
}

fn poses_array(poses: &[Pose]) -> Array {
    let mut data = Vec::with_capacity(poses.len() * 16);
    for p in poses {
        // Row-major, as robomimic stores poses (nalgebra's own storage is column-major).
        data.extend(pose_to_matrix(p).transpose().iter());
    }
    Array::f64(vec![poses.len(), 4, 4], data)
}

/// How the writer lays out a dataset.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct WriterOptions {
    /// robomimic's environment metadata JSON (the `data` attribute `env_args`).
    pub env_args: Option<String>,
    /// gzip observations in one chunk per demo, as MimicGen does.
    pub compress_obs: bool,
    /// Write `mask/train` and `mask/valid` with this fraction of demos in `valid`.
    pub valid_fraction: Option<f64>,
    /// Seed of the random train/valid split (robomimic shuffles demos before splitting).
    pub split_seed: u64,
}

/// robomimic's train/valid split: `floor(n * fraction)` demos drawn at random (seeded) for `valid`,
/// the rest in `train`; each list in the order of `names`.
#[must_use]
pub fn split_train_valid(names: &[String], fraction: f64, seed: u64) -> (Vec<String>, Vec<String>) {
    use rand::SeedableRng as _;
    use rand::seq::SliceRandom as _;
    #[allow(clippy::cast_precision_loss, clippy::cast_possible_truncation, clippy::cast_sign_loss)]
    let num_valid = ((names.len() as f64 * fraction.clamp(0.0, 1.0)).floor() as usize).min(names.len());
    let mut order: Vec<usize> = (0..names.len()).collect();
    order.shuffle(&mut rand_chacha::ChaCha8Rng::seed_from_u64(seed));
    let mut is_valid = vec![false; names.len()];
    for &i in order.iter().take(num_valid) {
        if let Some(v) = is_valid.get_mut(i) {
            *v = true;
        }
    }
    let (valid, train): (Vec<_>, Vec<_>) = names.iter().cloned().zip(is_valid).partition(|(_, v)| *v);
    (train.into_iter().map(|(n, _)| n).collect(), valid.into_iter().map(|(n, _)| n).collect())
}

/// Writes a robomimic-layout dataset one demo at a time; memory does not grow with the number of
/// demos (only their names are kept, for the masks).
///
/// Crash safety: the file is written as `<out>.partial` with the root attribute
/// `mimicgen_complete = 0`; each demo's `num_samples` attribute is written last and the file is
/// flushed after every demo. [`Self::finish`] writes the totals and masks, sets the marker to 1
/// and renames the file to `<out>`. Readers refuse a file whose marker is 0 unless asked to
/// recover, which keeps only demos with `num_samples`.
#[derive(Debug)]
pub struct DatasetWriter {
    h5: hdf5::File,
    data: hdf5::Group,
    label: String,
    partial: PathBuf,
    out: PathBuf,
    options: WriterOptions,
    names: Vec<String>,
    total: i64,
    masks: Option<BTreeMap<String, Vec<String>>>,
}

impl DatasetWriter {
    /// The temporary path a dataset is written under until [`Self::finish`].
    #[must_use]
    pub fn partial_path(out: &Path) -> PathBuf {
        let mut s = out.as_os_str().to_owned();
        s.push(".partial");
        PathBuf::from(s)
    }

    /// Starts a dataset that will end up at `out`.
    ///
    /// # Errors
    /// [`IoError::Write`] when the file cannot be created.
    pub fn create(out: impl AsRef<Path>, options: WriterOptions) -> Result<Self> {
        let out = out.as_ref().to_path_buf();
        let partial = Self::partial_path(&out);
        let label = partial.display().to_string();
        let err = |g: &str, f: &str, e: &hdf5::Error| IoError::hdf5_write(&label, g, f, e);
        let h5 = hdf5::File::create(&partial).map_err(|e| err("/", "", &e))?;
        tree::write_attr(&label, &h5, "/", COMPLETE_ATTR, &Array::int(0))?;
        let data = h5.create_group("data").map_err(|e| err("/", "data", &e))?;
        if let Some(env_args) = &options.env_args {
            tree::write_attr(&label, &data, "data", "env_args", &Array::string(env_args))?;
        }
        h5.flush().map_err(|e| err("/", "", &e))?;
        Ok(Self { h5, data, label, partial, out, options, names: Vec::new(), total: 0, masks: None })
    }

    /// Reopens the `<out>.partial` file an interrupted writer left, to go on appending: keeps the
    /// demos that were completely written (`num_samples` set) and whose attempt index (if any) is
    /// below `next_attempt`, and drops the rest, so the file holds exactly the demos of the
    /// attempts before `next_attempt`.
    ///
    /// The killed file is read, not edited: a process killed while HDF5 was writing can leave
    /// metadata flushed past the file's recorded end, which HDF5 then refuses to extend ("addr
    /// overflow"). The kept demos (arrays, chunking, attributes as they were) and the root and
    /// `data` attributes are copied into a fresh file, which replaces the partial one by a rename.
    ///
    /// # Errors
    /// [`IoError::Fs`] if there is no such file, [`IoError::Hdf5`] if it cannot be read,
    /// [`IoError::Write`] if the fresh file cannot be written.
    pub fn resume(out: impl AsRef<Path>, options: WriterOptions, next_attempt: u64) -> Result<Self> {
        let out = out.as_ref().to_path_buf();
        let partial = Self::partial_path(&out);
        let label = partial.display().to_string();
        if !partial.is_file() {
            return Err(IoError::Fs { file: label, reason: "no interrupted run to resume here (the file does not exist)".to_owned() });
        }
        let old = IoError::open_h5(&partial)?;
        let old_data = old.group("data").map_err(|e| IoError::hdf5(&label, "/", "data", &e))?;
        let mut root_attrs = tree::read_group_attrs(&label, &old, "/")?;
        root_attrs.remove(COMPLETE_ATTR);
        let mut data_attrs = tree::read_group_attrs(&label, &old_data, "data")?;
        data_attrs.remove("total");
        let mut fresh = PathBuf::from(&partial).into_os_string();
        fresh.push(".resume");
        let fresh = PathBuf::from(fresh);
        let fresh_label = fresh.display().to_string();
        let err = |g: &str, f: &str, e: &hdf5::Error| IoError::hdf5_write(&fresh_label, g, f, e);
        let h5 = hdf5::File::create(&fresh).map_err(|e| err("/", "", &e))?;
        tree::write_attr(&fresh_label, &h5, "/", COMPLETE_ATTR, &Array::int(0))?;
        tree::write_attrs(&fresh_label, &h5, "/", &root_attrs)?;
        let data = h5.create_group("data").map_err(|e| err("/", "data", &e))?;
        tree::write_attrs(&fresh_label, &data, "data", &data_attrs)?;
        let mut writer =
            Self { h5, data, label: fresh_label, partial: partial.clone(), out, options, names: Vec::new(), total: 0, masks: None };
        for i in 0.. {
            let name = format!("demo_{i}");
            if !old_data.link_exists(&name) {
                break;
            }
            let path = format!("data/{name}");
            // A demo half written when the writer died can be unreadable: it is dropped, as is
            // every one after it.
            let Ok(demo) = old_data
                .group(&name)
                .map_err(|e| IoError::hdf5(&label, "data", &name, &e))
                .and_then(|g| tree::read_group(&label, &g, &path))
            else {
                break;
            };
            let int_attr = |attr: &str| demo.attrs.get(attr).and_then(Array::as_i64);
            let attempt = int_attr(ATTEMPT_ATTR).and_then(|a| u64::try_from(a).ok());
            if int_attr("num_samples").is_none() || attempt.is_some_and(|a| a >= next_attempt) {
                break;
            }
            writer.append_group(&demo)?;
        }
        drop(old_data);
        drop(old);
        writer.h5.flush().map_err(|e| IoError::hdf5_write(&writer.label, "/", "", &e))?;
        std::fs::rename(&fresh, &partial).map_err(|e| IoError::Fs {
            file: label.clone(),
            reason: format!("replacing it with the resumed copy {}: {e}", fresh.display()),
        })?;
        writer.label = label;
        Ok(writer)
    }

    /// String attributes `names` of the root of the `<out>.partial` file an interrupted writer left
    /// (`None` for each one it lacks).
    ///
    /// # Errors
    /// [`IoError::Fs`] if there is no such file, [`IoError::Write`] if it cannot be read.
    pub fn partial_root_attrs(out: impl AsRef<Path>, names: &[&str]) -> Result<Vec<Option<String>>> {
        let partial = Self::partial_path(out.as_ref());
        let label = partial.display().to_string();
        if !partial.is_file() {
            return Err(IoError::Fs { file: label, reason: "no interrupted run to resume here (the file does not exist)".to_owned() });
        }
        crate::dataset::root_string_attrs(&partial, names)
    }

    /// Sets a string attribute on the file's root (replacing an earlier value) and flushes.
    ///
    /// # Errors
    /// [`IoError::Write`] on write errors.
    pub fn set_root_attr(&mut self, name: &str, value: &str) -> Result<()> {
        if self.h5.attr_names().is_ok_and(|names| names.iter().any(|n| n == name)) {
            self.h5.delete_attr(name).map_err(|e| IoError::hdf5_write(&self.label, "/", name, &e))?;
        }
        tree::write_attr(&self.label, &self.h5, "/", name, &Array::string(value))?;
        self.h5.flush().map_err(|e| IoError::hdf5_write(&self.label, "/", name, &e))
    }

    /// Number of demos written so far.
    #[must_use]
    pub fn len(&self) -> usize {
        self.names.len()
    }

    /// True before the first demo.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.names.is_empty()
    }

    /// Appends one demo as `data/demo_<i>` and flushes; returns its name.
    ///
    /// # Errors
    /// [`IoError::Usage`] when the demo's arrays disagree in length, [`IoError::Write`] on write errors.
    pub fn append(&mut self, demo: &DemoData) -> Result<String> {
        let name = format!("demo_{}", self.names.len());
        let group_path = format!("data/{name}");
        let tree = demo.to_group(&self.label, &group_path, self.options.compress_obs)?;
        let g = self.data.create_group(&name).map_err(|e| IoError::hdf5_write(&self.label, "data", &name, &e))?;
        tree::write_group(&self.label, &g, &group_path, &tree)?;
        let steps = i64::try_from(demo.actions.len()).unwrap_or(i64::MAX);
        tree::write_attr(&self.label, &g, &group_path, "num_samples", &Array::int(steps))?;
        self.h5.flush().map_err(|e| IoError::hdf5_write(&self.label, &group_path, "", &e))?;
        self.total += steps;
        self.names.push(name.clone());
        Ok(name)
    }

    /// Appends a demo group read from another dataset (its `num_samples` attribute included) as
    /// the next `data/demo_<i>`, arrays, chunking, compression and attributes as they were.
    ///
    /// # Errors
    /// [`IoError::Missing`] when `demo` has no `num_samples`, [`IoError::Write`] on write errors.
    pub fn append_group(&mut self, demo: &Group) -> Result<String> {
        let name = format!("demo_{}", self.names.len());
        let group_path = format!("data/{name}");
        let steps = demo.attrs.get("num_samples").and_then(Array::as_i64).ok_or_else(|| IoError::Missing {
            file: self.label.clone(),
            group: group_path.clone(),
            field: "num_samples".into(),
            hint: "only completely written demos can be copied".into(),
        })?;
        // `num_samples` last, as `append` writes it: a demo without it was not finished.
        let mut body = demo.clone();
        body.attrs.remove("num_samples");
        let g = self.data.create_group(&name).map_err(|e| IoError::hdf5_write(&self.label, "data", &name, &e))?;
        tree::write_group(&self.label, &g, &group_path, &body)?;
        tree::write_attr(&self.label, &g, &group_path, "num_samples", &Array::int(steps))?;
        self.h5.flush().map_err(|e| IoError::hdf5_write(&self.label, &group_path, "", &e))?;
        self.total += steps;
        self.names.push(name.clone());
        Ok(name)
    }

    /// Appends a generation attempt (see [`DemoData::from_attempt`]).
    ///
    /// # Errors
    /// As [`Self::append`].
    pub fn append_attempt(&mut self, attempt: &Attempt, obs: BTreeMap<String, Observation>, model_xml: Option<String>) -> Result<String> {
        self.append(&DemoData::from_attempt(attempt, obs, model_xml))
    }

    /// Filter keys to write as they are (`mask/<key>` with these demo names) in place of the
    /// train/valid split of [`WriterOptions::valid_fraction`].
    pub fn set_masks(&mut self, masks: BTreeMap<String, Vec<String>>) {
        self.masks = Some(masks);
    }

    /// Writes totals and masks, marks the file complete and moves it to its final path.
    ///
    /// # Errors
    /// [`IoError::Write`] on write errors, [`IoError::Fs`] when the rename fails.
    pub fn finish(self) -> Result<PathBuf> {
        let label = self.label.clone();
        tree::write_attr(&label, &self.data, "data", "total", &Array::int(self.total))?;
        let masks: Option<Vec<(String, Vec<String>)>> = match (&self.masks, self.options.valid_fraction) {
            (Some(masks), _) => Some(masks.iter().map(|(k, v)| (k.clone(), v.clone())).collect()),
            (None, Some(fraction)) => {
                let (train, valid) = split_train_valid(&self.names, fraction, self.options.split_seed);
                Some(vec![("train".to_owned(), train), ("valid".to_owned(), valid)])
            }
            (None, None) => None,
        };
        if let Some(masks) = masks.filter(|m| !m.is_empty()) {
            let mask = self.h5.create_group("mask").map_err(|e| IoError::hdf5_write(&label, "/", "mask", &e))?;
            for (key, names) in masks {
                let key = key.as_str();
                let len = names.iter().map(String::len).max().unwrap_or(1).max(1);
                let d = Dataset::new(Array { shape: vec![names.len()], values: Values::Fixed { len, strings: names } });
                tree::write_dataset(&label, &mask, "mask", key, &d)?;
            }
        }
        tree::write_attr(&label, &self.h5, "/", COMPLETE_ATTR, &Array::int(1)).or_else(|_| {
            // The attribute exists: overwrite its value in place.
            let a = self.h5.attr(COMPLETE_ATTR).map_err(|e| IoError::hdf5_write(&label, "/", COMPLETE_ATTR, &e))?;
            a.write_scalar(&1_i64).map_err(|e| IoError::hdf5_write(&label, "/", COMPLETE_ATTR, &e))
        })?;
        let Self { h5, data, partial, out, .. } = self;
        drop(data);
        h5.close().map_err(|e| IoError::hdf5_write(&label, "/", "", &e))?;
        std::fs::rename(&partial, &out).map_err(|e| IoError::Fs {
            file: out.display().to_string(),
            reason: format!("renaming {} into place: {e}", partial.display()),
        })?;
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::split_train_valid;

    #[test]
    fn the_valid_split_is_random_but_seeded() {
        let names: Vec<String> = (0..40).map(|i| format!("demo_{i}")).collect();
        let (train, valid) = split_train_valid(&names, 0.1, 1);
        assert_eq!((train.len(), valid.len()), (36, 4));
        assert!(valid.iter().all(|v| !train.contains(v)));
        // In the names' order, the same for the same seed, different for another.
        assert!(valid.windows(2).all(|w| names.iter().position(|n| *n == w[0]) < names.iter().position(|n| *n == w[1])));
        assert_eq!(split_train_valid(&names, 0.1, 1).1, valid);
        let others: Vec<Vec<String>> = (2..6).map(|seed| split_train_valid(&names, 0.1, seed).1).collect();
        assert!(others.iter().any(|o| *o != valid), "seeds 1-5 all chose {valid:?}");
        // Not the evenly spread demo_9, demo_19, ... of a deterministic split.
        let even: Vec<String> = [9, 19, 29, 39].iter().map(|i| format!("demo_{i}")).collect();
        assert!(std::iter::once(&valid).chain(&others).any(|v| *v != even));
        assert_eq!(split_train_valid(&names, 0.0, 1).1.len(), 0);
        assert_eq!(split_train_valid(&names, 1.0, 1).0.len(), 0);
    }
}
