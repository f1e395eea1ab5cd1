//! Reading robomimic / MimicGen HDF5 datasets: the whole file losslessly ([`RobomimicDataset`]),
//! and the part MimicGen needs as engine types ([`RobomimicDataset::to_source_dataset`]).
//!
//! About 500 lines: the lossless file and the streaming reader share their checks (one demo group
//! is read in `source_demo.rs`).

use std::collections::BTreeMap;
use std::fmt;
use std::path::Path;

use mimicgen_engine::demo::{SourceDataset, SourceDemo};
use mimicgen_engine::spec::SourceSelection;
use serde::Serialize;

use crate::error::{IoError, Result};
pub use crate::source_demo::{STARTS_ATTR, demo_steps, source_demo_from_group, source_demo_of_arm};
use crate::source_demo::{check_demo, collect_paths, missing};
use crate::tree::{self, Array, Group, Node};

/// Root attribute the [`crate::DatasetWriter`] sets to 0 while writing and to 1 when finished.
pub const COMPLETE_ATTR: &str = "mimicgen_complete";

/// Fields a demo needs to serve as a MimicGen source demo (paths below `data/demo_N`).
pub const REQUIRED_FIELDS: [&str; 6] = [
    "actions",
    "datagen_info/eef_pose",
    "datagen_info/target_pose",
    "datagen_info/gripper_action",
    "datagen_info/object_poses",
    "datagen_info/subtask_term_signals",
];

/// How to open a dataset.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ReadOptions {
    /// Open a file an interrupted writer left behind, keeping only its completely written demos.
    pub recover: bool,
}

/// What a dataset holds and which MimicGen fields it lacks.
#[derive(Debug, Clone, PartialEq, Default, Serialize)]
pub struct DatasetReport {
    /// The file.
    pub file: String,
    /// Number of demos.
    pub num_demos: usize,
    /// Fields (paths below `data/demo_N`) found in at least one demo.
    pub present: Vec<String>,
    /// Each missing required field with the demos that lack it.
    pub missing: BTreeMap<String, Vec<String>>,
}

impl DatasetReport {
    /// Adds one demo's fields to the report.
    pub fn add_demo(&mut self, name: &str, demo: &Group) {
        let mut present: std::collections::BTreeSet<String> = self.present.drain(..).collect();
        collect_paths(demo, "", &mut present);
        self.present = present.into_iter().collect();
        for field in REQUIRED_FIELDS {
            let found = match field.rsplit_once('/') {
                Some((dir, leaf)) => demo.group(dir).is_some_and(|g| g.members.contains_key(leaf)),
                None => demo.members.contains_key(field),
            };
            if !found {
                self.missing.entry(field.to_owned()).or_default().push(name.to_owned());
            }
        }
        self.num_demos += 1;
    }

    /// True when every demo has every field MimicGen needs.
    #[must_use]
    pub fn is_mimicgen_source(&self) -> bool {
        self.num_demos > 0 && self.missing.is_empty()
    }
}

impl fmt::Display for DatasetReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.num_demos == 0 {
            return write!(f, "group `data` holds no demos");
        }
        let gaps: Vec<String> = self
            .missing
            .iter()
            .map(|(field, demos)| {
                let shown: Vec<&str> = demos.iter().take(3).map(String::as_str).collect();
                let more = if demos.len() > 3 { ", ..." } else { "" };
                format!("`{field}` missing in {} of {} demos ({}{more})", demos.len(), self.num_demos, shown.join(", "))
            })
            .collect();
        write!(f, "{}; present: {}", gaps.join("; "), self.present.join(", "))?;
        if self.missing.keys().any(|k| k.starts_with("datagen_info")) {
            write!(f, " (run MimicGen's prepare_src_dataset.py on it first to add datagen_info)")?;
        }
        Ok(())
    }
}

/// A robomimic-layout HDF5 file held in memory with every group, dataset and attribute, so it can
/// be inspected, converted, and written back bit for bit.
#[derive(Debug, Clone, PartialEq)]
pub struct RobomimicDataset {
    /// The file it was read from.
    pub file: String,
    /// The whole file.
    pub root: Group,
    demo_names: Vec<String>,
}

/// Demo order as robomimic uses it: `demo_N` by N numerically, other names after, by name.
#[must_use]
pub fn sort_demo_names(mut names: Vec<String>) -> Vec<String> {
    names.sort_by_key(|n| (n.strip_prefix("demo_").and_then(|i| i.parse::<u64>().ok()).map_or((1, 0), |i| (0, i)), n.clone()));
    names
}

impl RobomimicDataset {
    /// Reads a whole dataset, refusing files an interrupted writer left incomplete.
    ///
    /// # Errors
    /// [`IoError::Hdf5`] for an unreadable or truncated file, [`IoError::Missing`] without a `data`
    /// group or a demo without `actions`, [`IoError::Shape`] when datasets of one demo disagree in
    /// length, [`IoError::Incomplete`] for an unfinished file.
    pub fn open(path: impl AsRef<Path>) -> Result<Self> {
        Self::open_with(path, ReadOptions::default())
    }

    /// [`Self::open`] with options (e.g. recovering an interrupted file).
    ///
    /// # Errors
    /// As [`Self::open`].
    pub fn open_with(path: impl AsRef<Path>, options: ReadOptions) -> Result<Self> {
        let file = path.as_ref().display().to_string();
        let h5 = IoError::open_h5(path.as_ref())?;
        let mut root = tree::read_group(&file, &h5, "/")?;
        let complete_flag = root.attrs.get(COMPLETE_ATTR).and_then(Array::as_i64);
        let Some(Node::Group(data)) = root.members.get_mut("data") else {
            return Err(IoError::Missing {
                file,
                group: "/".into(),
                field: "data".into(),
                hint: "robomimic datasets keep their demos under `data`".into(),
            });
        };
        add_robosuite_env_args(&mut data.attrs);
        if complete_flag == Some(0) {
            let complete = |g: &Node| matches!(g, Node::Group(g) if g.attrs.contains_key("num_samples"));
            if !options.recover {
                return Err(IoError::Incomplete {
                    file,
                    field: COMPLETE_ATTR.into(),
                    complete_demos: data.members.values().filter(|g| complete(g)).count(),
                });
            }
            data.members.retain(|_, g| complete(g));
        }
        let names: Vec<String> = data.members.iter().filter(|(_, n)| matches!(n, Node::Group(_))).map(|(k, _)| k.clone()).collect();
        let demo_names = sort_demo_names(names);
        for name in &demo_names {
            if let Some(Node::Group(demo)) = data.members.get(name) {
                check_demo(&file, name, demo)?;
            }
        }
        Ok(Self { file, root, demo_names })
    }

    /// The `data` group.
    #[must_use]
    pub fn data(&self) -> &Group {
        self.root.group("data").unwrap_or(&EMPTY)
    }

    /// Demo names in robomimic order.
    #[must_use]
    pub fn demo_names(&self) -> &[String] {
        &self.demo_names
    }

    /// The demo group `name`.
    #[must_use]
    pub fn demo(&self, name: &str) -> Option<&Group> {
        self.data().group(name)
    }

    /// Number of steps of demo `name` (its `actions` rows).
    #[must_use]
    pub fn demo_len(&self, name: &str) -> usize {
        self.demo(name).and_then(|d| d.dataset("actions")).and_then(|a| a.array.shape.first().copied()).unwrap_or(0)
    }

    /// The `data` attribute `env_args` (robomimic's environment metadata JSON).
    #[must_use]
    pub fn env_args(&self) -> Option<&str> {
        self.data().attrs.get("env_args").and_then(Array::as_str)
    }

    /// Filter keys under `mask/` with the demo names each selects.
    ///
    /// # Errors
    /// [`IoError::Invalid`] when a mask is not an array of strings.
    pub fn masks(&self) -> Result<BTreeMap<String, Vec<String>>> {
        parse_masks(&self.file, self.root.group("mask"))
    }

    /// The demos a selection picks, in robomimic order: the filter key's demos (or all), sorted,
    /// then `start` skipped and at most `n` kept.
    ///
    /// # Errors
    /// [`IoError::Missing`] for an unknown filter key or a mask naming a demo that does not exist.
    pub fn select(&self, selection: &SourceSelection) -> Result<Vec<String>> {
        let mut names = match &selection.filter_key {
            None => self.demo_names.clone(),
            Some(key) => {
                let masks = self.masks()?;
                let Some(listed) = masks.get(key) else {
                    return Err(IoError::Missing {
                        file: self.file.clone(),
                        group: "mask".into(),
                        field: key.clone(),
                        hint: format!("filter keys in the file: {:?}", masks.keys().collect::<Vec<_>>()),
                    });
                };
                if let Some(bad) = listed.iter().find(|n| self.demo(n).is_none()) {
                    return Err(IoError::Missing {
                        file: self.file.clone(),
                        group: "data".into(),
                        field: bad.clone(),
                        hint: format!("listed by mask/{key}"),
                    });
                }
                sort_demo_names(listed.clone())
            }
        };
        let start = selection.start.unwrap_or(0).min(names.len());
        names.drain(..start);
        if let Some(n) = selection.n {
            names.truncate(n);
        }
        Ok(names)
    }

    /// What the file holds and which MimicGen fields its demos lack.
    #[must_use]
    pub fn report(&self) -> DatasetReport {
        let mut report = DatasetReport { file: self.file.clone(), ..DatasetReport::default() };
        for name in &self.demo_names {
            if let Some(demo) = self.demo(name) {
                report.add_demo(name, demo);
            }
        }
        report
    }

    /// The selected demos as an engine [`SourceDataset`], validated.
    ///
    /// # Errors
    /// [`IoError::NotMimicGen`] listing every missing field of a plain robomimic dataset;
    /// [`IoError::Invalid`] for a NaN or non-rigid pose (naming demo, field and step);
    /// [`IoError::Shape`] for arrays of the wrong shape; [`IoError::Engine`] when the engine's
    /// validation fails; the errors of [`Self::select`].
    pub fn to_source_dataset(&self, selection: &SourceSelection) -> Result<SourceDataset> {
        let names = self.select(selection)?;
        let mut report = self.report();
        report.missing.retain(|_, demos| {
            demos.retain(|d| names.contains(d));
            !demos.is_empty()
        });
        if names.is_empty() || !report.missing.is_empty() {
            return Err(IoError::NotMimicGen { file: self.file.clone(), report: Box::new(report) });
        }
        let demos = names.iter().map(|n| self.source_demo(n)).collect::<Result<Vec<_>>>()?;
        let dataset = SourceDataset { demos, env_args: self.env_args().map(str::to_owned) };
        dataset.validate().map_err(|source| IoError::Engine { file: self.file.clone(), field: String::new(), source: Box::new(source) })?;
        Ok(dataset)
    }

    /// The source demos a selection picks, one view per arm of a two-arm file: each arm's own
    /// `datagen_info/eef_pose/<arm>`, `target_pose/<arm>` and `gripper_action/<arm>`, the objects
    /// and signals shared ([`crate::source_demo::source_demo_of_arm`]).
    ///
    /// # Errors
    /// As [`RobomimicDataset::to_source_dataset`], naming the arm's missing field.
    pub fn to_arm_source_datasets(&self, selection: &SourceSelection, arms: &[&str]) -> Result<Vec<SourceDataset>> {
        let names = self.select(selection)?;
        arms.iter()
            .map(|&arm| {
                let demos = names
                    .iter()
                    .map(|n| {
                        let demo = self.demo(n).ok_or_else(|| self.missing("data", n))?;
                        source_demo_of_arm(&self.file, n, demo, Some(arm))
                    })
                    .collect::<Result<Vec<_>>>()?;
                let dataset = SourceDataset { demos, env_args: self.env_args().map(str::to_owned) };
                dataset.validate().map_err(|source| IoError::Engine {
                    file: self.file.clone(),
                    field: format!("datagen_info (arm {arm})"),
                    source: Box::new(source),
                })?;
                Ok(dataset)
            })
            .collect()
    }

    fn source_demo(&self, name: &str) -> Result<SourceDemo> {
        let demo = self.demo(name).ok_or_else(|| self.missing("data", name))?;
        source_demo_from_group(&self.file, name, demo)
    }

    fn missing(&self, group: &str, field: &str) -> IoError {
        missing(&self.file, group, field)
    }

    /// Writes the whole file back out (an exact copy of what was read, plus any edits to `root`).
    ///
    /// # Errors
    /// [`IoError::Write`] when the file cannot be created or written.
    pub fn write(&self, path: impl AsRef<Path>) -> Result<()> {
        write_tree(path, &self.root)
    }
}

/// Filter keys of a `mask` group with the demo names each lists.
fn parse_masks(file: &str, mask: Option<&Group>) -> Result<BTreeMap<String, Vec<String>>> {
    let Some(mask) = mask else { return Ok(BTreeMap::new()) };
    let mut out = BTreeMap::new();
    for (key, node) in &mask.members {
        let strings = match node {
            Node::Dataset(d) => d.array.values.strings(),
            Node::Group(_) => None,
        };
        let Some(strings) = strings else {
            return Err(IoError::Invalid {
                file: file.to_owned(),
                group: "mask".into(),
                field: key.clone(),
                reason: "a filter key must be a 1-D array of demo names (byte strings)".into(),
            });
        };
        out.insert(key.clone(), strings.to_vec());
    }
    Ok(out)
}

/// Read access to a dataset's demos, whether held in memory ([`RobomimicDataset`]) or read one at
/// a time from disk ([`DemoReader`]).
pub trait DemoSource {
    /// The file.
    fn file(&self) -> &str;
    /// Demo names in robomimic order.
    fn demo_names(&self) -> &[String];
    /// Demo `name` (borrowed when in memory, read from disk otherwise).
    ///
    /// # Errors
    /// [`IoError::Missing`] for an unknown name; read and shape errors as [`RobomimicDataset::open`].
    fn load_demo(&self, name: &str) -> Result<std::borrow::Cow<'_, Group>>;
    /// Attributes of the `data` group.
    fn data_attrs(&self) -> &BTreeMap<String, Array>;
    /// Filter keys under `mask/` with their demo names.
    ///
    /// # Errors
    /// [`IoError::Invalid`] when a mask is not an array of strings.
    fn filter_keys(&self) -> Result<BTreeMap<String, Vec<String>>>;
    /// The `data` attribute `env_args`.
    fn env_args_json(&self) -> Option<&str> {
        self.data_attrs().get("env_args").and_then(Array::as_str)
    }
}

impl DemoSource for RobomimicDataset {
    fn file(&self) -> &str {
        &self.file
    }

    fn demo_names(&self) -> &[String] {
        &self.demo_names
    }

    fn load_demo(&self, name: &str) -> Result<std::borrow::Cow<'_, Group>> {
        self.demo(name).map(std::borrow::Cow::Borrowed).ok_or_else(|| self.missing("data", name))
    }

    fn data_attrs(&self) -> &BTreeMap<String, Array> {
        &self.data().attrs
    }

    fn filter_keys(&self) -> Result<BTreeMap<String, Vec<String>>> {
        self.masks()
    }
}

/// A dataset opened for reading one demo at a time: memory stays at one demo however large the
/// file (for `info` and `export` on big generated datasets).
#[derive(Debug)]
pub struct DemoReader {
    file: String,
    data: hdf5::Group,
    data_attrs: BTreeMap<String, Array>,
    mask: Option<Group>,
    demo_names: Vec<String>,
    /// Demo members not read (observations, for readers that need only MimicGen's fields).
    skip: &'static [&'static str],
}

impl DemoReader {
    /// The same reader, leaving each demo's `obs` and `next_obs` unread (most of a generated
    /// dataset's bytes, and compressed): for readers of poses, actions, states and signals.
    #[must_use]
    pub fn without_observations(mut self) -> Self {
        self.skip = &["obs", "next_obs"];
        self
    }

    /// Opens a dataset, reading only its names, attributes and masks (same checks and options
    /// as [`RobomimicDataset::open_with`], per demo when it is read).
    ///
    /// # Errors
    /// As [`RobomimicDataset::open`].
    pub fn open_with(path: impl AsRef<Path>, options: ReadOptions) -> Result<Self> {
        let file = path.as_ref().display().to_string();
        let h5 = IoError::open_h5(path.as_ref())?;
        let complete_flag = match h5.attr(COMPLETE_ATTR) {
            Ok(a) => tree::read_array(&file, "/", COMPLETE_ATTR, &a)?.as_i64(),
            Err(_) => None,
        };
        let data = h5.group("data").map_err(|_| IoError::Missing {
            file: file.clone(),
            group: "/".into(),
            field: "data".into(),
            hint: "robomimic datasets keep their demos under `data`".into(),
        })?;
        let mut names = Vec::new();
        let mut complete = 0;
        for name in data.member_names().map_err(|e| IoError::hdf5(&file, "data", "", &e))? {
            let Ok(g) = data.group(&name) else { continue };
            let done = g.attr_names().is_ok_and(|a| a.iter().any(|n| n == "num_samples"));
            complete += usize::from(done);
            if done || complete_flag != Some(0) {
                names.push(name);
            }
        }
        if complete_flag == Some(0) && !options.recover {
            return Err(IoError::Incomplete { file, field: COMPLETE_ATTR.into(), complete_demos: complete });
        }
        let mut data_attrs = tree::read_group_attrs(&file, &data, "data")?;
        add_robosuite_env_args(&mut data_attrs);
        let mask = match h5.group("mask") {
            Ok(g) => Some(tree::read_group(&file, &g, "mask")?),
            Err(_) => None,
        };
        Ok(Self { file, data, data_attrs, mask, demo_names: sort_demo_names(names), skip: &[] })
    }
}

impl DemoSource for DemoReader {
    fn file(&self) -> &str {
        &self.file
    }

    fn demo_names(&self) -> &[String] {
        &self.demo_names
    }

    fn load_demo(&self, name: &str) -> Result<std::borrow::Cow<'_, Group>> {
        let group = format!("data/{name}");
        let g = self.data.group(name).map_err(|_| IoError::Missing {
            file: self.file.clone(),
            group: "data".into(),
            field: name.to_owned(),
            hint: String::new(),
        })?;
        let demo = tree::read_group_except(&self.file, &g, &group, self.skip)?;
        check_demo(&self.file, name, &demo)?;
        Ok(std::borrow::Cow::Owned(demo))
    }

    fn data_attrs(&self) -> &BTreeMap<String, Array> {
        &self.data_attrs
    }

    fn filter_keys(&self) -> Result<BTreeMap<String, Vec<String>>> {
        parse_masks(&self.file, self.mask.as_ref())
    }
}

/// robosuite's own demonstration files (what its `collect_human_demonstrations.py` writes: `data`
/// attributes `env`, `env_info` and `repository_version`, no `env_args`) get the `env_args`
/// robomimic's conversion script makes of them: `{"type": 1, "env_name": env, "env_version":
/// repository_version, "env_kwargs": env_info}` (without `env_info`'s own `env_name`), so they read
/// like any robomimic dataset.
fn add_robosuite_env_args(attrs: &mut BTreeMap<String, Array>) {
    if attrs.contains_key("env_args") {
        return;
    }
    let (Some(env), Some(info)) = (attrs.get("env").and_then(Array::as_str), attrs.get("env_info").and_then(Array::as_str)) else { return };
    let Ok(serde_json::Value::Object(mut kwargs)) = serde_json::from_str::<serde_json::Value>(info) else { return };
    kwargs.remove("env_name");
    let version = attrs.get("repository_version").and_then(Array::as_str);
    let args = serde_json::json!({"env_name": env, "env_version": version, "type": 1, "env_kwargs": kwargs});
    attrs.insert("env_args".to_owned(), Array::string(&args.to_string()));
}

static EMPTY: Group = Group { attrs: BTreeMap::new(), members: BTreeMap::new() };

/// String attributes `names` of a file's root (`None` for each one it lacks or that is not a
/// string).
///
/// # Errors
/// [`IoError::Hdf5`] when the file cannot be opened.
pub fn root_string_attrs(path: impl AsRef<Path>, names: &[&str]) -> Result<Vec<Option<String>>> {
    let label = path.as_ref().display().to_string();
    let h5 = IoError::open_h5(path.as_ref())?;
    Ok(names
        .iter()
        .map(|name| {
            let a = h5.attr(name).ok()?;
            tree::read_array(&label, "/", name, &a).ok()?.as_str().map(str::to_owned)
        })
        .collect())
}

/// Writes a [`Group`] tree as a new HDF5 file.
///
/// # Errors
/// [`IoError::Hdf5`] when the file cannot be created or written.
pub fn write_tree(path: impl AsRef<Path>, root: &Group) -> Result<()> {
    let file = path.as_ref().display().to_string();
    let h5 = hdf5::File::create(path.as_ref()).map_err(|e| IoError::hdf5_write(&file, "/", "", &e))?;
    tree::write_group(&file, &h5, "/", root)?;
    h5.close().map_err(|e| IoError::hdf5_write(&file, "/", "", &e))
}

/// Reads the source demos a selection picks from a MimicGen source dataset.
///
/// # Errors
/// See [`RobomimicDataset::open`] and [`RobomimicDataset::to_source_dataset`].
pub fn read_source_dataset(path: impl AsRef<Path>, selection: &SourceSelection) -> Result<SourceDataset> {
    RobomimicDataset::open(path)?.to_source_dataset(selection)
}
