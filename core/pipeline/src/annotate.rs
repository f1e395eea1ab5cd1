//! Subtask ends for source demos: proposed from the recording (no privileged signals), or typed by
//! hand, and written where MimicGen reads them (`datagen_info/subtask_term_signals/<name>`, 0
//! before the step that ends the subtask, 1 from it on, as its annotation script writes them).

use std::collections::BTreeMap;
use std::path::Path;

use mimicgen_engine::SourceDemo;
use mimicgen_engine::TaskSpec;
use mimicgen_engine::detect::{Proposal, propose_subtask_ends, signal_for_end};
use mimicgen_engine::segment::subtask_end_from_signal;
use mimicgen_engine::spec::SourceSelection;
use mimicgen_io::tree::{Array, Dataset, Group, Node};
use mimicgen_io::{DatasetReport, DemoReader, DemoSource as _, IoError, ReadOptions, RobomimicDataset, source_demo_from_group};
use mimicgen_sim::{Scene, registry};
use serde::Serialize;

use crate::PipelineError;
use crate::config::resolve_task;

/// One demo's proposed subtask ends, beside the ends its stored signals give (if any).
#[derive(Debug, Clone, Serialize)]
pub struct DemoAnnotation {
    /// The demo's name.
    pub demo: String,
    /// Its length in steps.
    pub len: usize,
    /// The proposals, one per subtask but the last.
    #[serde(serialize_with = "proposals")]
    pub proposals: Vec<Proposal>,
    /// The ends the file's own signals give (exclusive), when it has them all.
    pub signal_ends: Option<Vec<usize>>,
    /// The distance between the fingers at every step (m), read from the stored states.
    #[serde(skip)]
    pub finger_width_m: Option<Vec<f64>>,
}

fn proposals<S: serde::Serializer>(p: &[Proposal], s: S) -> Result<S::Ok, S::Error> {
    use serde::ser::SerializeSeq as _;
    let mut seq = s.serialize_seq(Some(p.len()))?;
    for q in p {
        seq.serialize_element(&serde_json::json!({"subtask": q.subtask, "end": q.end, "confidence": q.confidence, "reason": q.reason}))?;
    }
    seq.end()
}

/// A source file read for annotation: its task's spec and its demos' proposals.
#[derive(Debug)]
pub struct Annotations {
    /// The spec whose subtasks are annotated (its `term_signal` names are written).
    pub spec: TaskSpec,
    /// Per demo, in file order.
    pub demos: Vec<DemoAnnotation>,
    /// The demos as read (poses, gripper actions, signals).
    pub sources: mimicgen_engine::SourceDataset,
    /// The scene the demos were recorded in (from their `model_file`, else the task's).
    pub scene: Scene,
}

impl Annotations {
    /// Distances in steps between proposed and signal-derived ends, over every boundary of every
    /// demo that has signals.
    #[must_use]
    pub fn distances(&self) -> Vec<usize> {
        self.demos
            .iter()
            .filter_map(|d| d.signal_ends.as_ref().map(|ends| (d, ends)))
            .flat_map(|(d, ends)| d.proposals.iter().zip(ends).map(|(p, &e)| p.end.abs_diff(e)))
            .collect()
    }
}

/// Proposes subtask ends one demo at a time: the task's spec, the scene (for finger openings) and
/// the signal names, worked out once per file.
#[derive(Debug)]
pub struct Proposer {
    label: String,
    spec: TaskSpec,
    scene: Scene,
    signal_names: Vec<String>,
}

impl Proposer {
    /// Works out the task (`task`, else the file's `env_args`) and spec (`config`, else the task's
    /// bundled one) of `path`, and its scene (from `model_xml`, a demo's `model_file`, else the
    /// task's own).
    ///
    /// # Errors
    /// [`PipelineError`] naming the file and field for unknown tasks, specs that do not load and
    /// scenes that do not compile.
    pub fn new(
        path: &Path,
        env_args: Option<&str>,
        model_xml: Option<&str>,
        task: Option<&str>,
        config: Option<&Path>,
    ) -> Result<Self, PipelineError> {
        let label = path.display().to_string();
        let spec_from_file =
            config.map(|c| TaskSpec::load(c).map_err(|e| PipelineError::engine(c.display().to_string(), e))).transpose()?;
        let (task, _) = resolve_task(task, None, spec_from_file.as_ref().zip(config), env_args.map(|a| (a, path)))?;
        let spec = match spec_from_file {
            Some(spec) => spec,
            None => TaskSpec::from_toml_str(
                registry::default_spec_toml(task.name()).unwrap_or_default(),
                &format!("bundled {} spec", task.name()),
            )
            .map_err(|e| PipelineError::engine("bundled spec", e))?,
        };
        let scene = match model_xml {
            Some(xml) => Scene::from_model_file(xml, &format!("{label} (model_file)"), task.as_ref())?,
            None => Scene::for_task(task.as_ref())?,
        };
        let signal_names = spec.subtasks.iter().take(spec.subtasks.len().saturating_sub(1)).filter_map(|s| s.term_signal.clone()).collect();
        Ok(Self { label, spec, scene, signal_names })
    }

    /// The spec whose subtasks are annotated.
    #[must_use]
    pub fn spec(&self) -> &TaskSpec {
        &self.spec
    }

    /// The scene the demos were recorded in.
    #[must_use]
    pub fn scene(&self) -> &Scene {
        &self.scene
    }

    /// Proposes `demo`'s subtask ends and reads the ends its own signals give.
    ///
    /// # Errors
    /// [`PipelineError`] naming the file and demo when its states do not fit the scene or its
    /// gripper commands cannot be read.
    pub fn annotate(&self, demo: &SourceDemo) -> Result<DemoAnnotation, PipelineError> {
        let widths = if demo.sim.states.is_empty() { None } else { self.scene.finger_widths(&demo.sim.states)? };
        let proposals =
            propose_subtask_ends(demo, &self.spec, widths.as_deref()).map_err(|e| PipelineError::engine(self.label.clone(), e))?;
        let signal_ends = (self.signal_names.len() + 1 == self.spec.subtasks.len())
            .then(|| {
                let mut start = 0;
                self.signal_names
                    .iter()
                    .map(|name| {
                        let end = subtask_end_from_signal(demo.subtask_term_signals.get(name)?, start)?;
                        start = end;
                        Some(end)
                    })
                    .collect::<Option<Vec<usize>>>()
            })
            .flatten();
        Ok(DemoAnnotation { demo: demo.name.clone(), len: demo.len(), proposals, signal_ends, finger_width_m: widths })
    }
}

/// Reads `path` (MimicGen source layout), works out its task (`task`, else its `env_args`) and
/// spec (`config`, else the task's bundled one), and proposes every demo's subtask ends from its
/// gripper commands, finger openings (from the stored states and the scene) and object poses.
///
/// # Errors
/// [`PipelineError`] naming the file and field for unreadable files, unknown tasks, or demos whose
/// gripper commands cannot be read.
pub fn propose(path: &Path, task: Option<&str>, config: Option<&Path>) -> Result<Annotations, PipelineError> {
    let file = RobomimicDataset::open(path)?;
    let sources = file.to_source_dataset(&SourceSelection::default())?;
    let model_xml = sources.demos.first().and_then(|d| d.sim.model_xml.as_deref());
    let proposer = Proposer::new(path, file.env_args(), model_xml, task, config)?;
    let demos = sources.demos.iter().map(|d| proposer.annotate(d)).collect::<Result<Vec<_>, _>>()?;
    Ok(Annotations { spec: proposer.spec, demos, sources, scene: proposer.scene })
}

/// [`propose`] for large files, demo by demo without reading observations: `on_start` gets the
/// proposer and the number of demos once the first demo is read, then `on_chunk` gets every
/// `chunk` demos (read, checked and annotated) as they are ready. A file without `datagen_info` is
/// [`IoError::NotMimicGen`] before anything is reported.
///
/// # Errors
/// As [`propose`], naming the demo at fault; demos reported before it stay reported.
pub fn propose_streaming(
    path: &Path,
    chunk: usize,
    on_start: impl FnOnce(&Proposer, usize),
    mut on_chunk: impl FnMut(Vec<(SourceDemo, DemoAnnotation)>),
) -> Result<(), PipelineError> {
    let reader = DemoReader::open_with(path, ReadOptions::default())?.without_observations();
    let label = path.display().to_string();
    let names = reader.demo_names().to_vec();
    let read = |name: &str| -> Result<SourceDemo, PipelineError> {
        let group = reader.load_demo(name)?;
        let mut report = DatasetReport { file: label.clone(), ..DatasetReport::default() };
        report.add_demo(name, &group);
        if !report.is_mimicgen_source() {
            return Err(IoError::NotMimicGen { file: label.clone(), report: Box::new(report) }.into());
        }
        let demo = source_demo_from_group(&label, name, &group)?;
        demo.validate().map_err(|e| PipelineError::engine(label.clone(), e))?;
        Ok(demo)
    };
    let Some(first_name) = names.first() else {
        return Err(PipelineError::input(label, "data", "holds no demos"));
    };
    let first = read(first_name)?;
    let proposer = Proposer::new(path, reader.env_args_json(), first.sim.model_xml.as_deref(), None, None)?;
    on_start(&proposer, names.len());
    let mut batch = Vec::with_capacity(chunk);
    let first_annotation = proposer.annotate(&first)?;
    batch.push((first, first_annotation));
    for name in names.iter().skip(1) {
        if batch.len() >= chunk.max(1) {
            on_chunk(std::mem::take(&mut batch));
        }
        let demo = read(name)?;
        let annotation = proposer.annotate(&demo)?;
        batch.push((demo, annotation));
    }
    on_chunk(batch);
    Ok(())
}

/// Writes `input` to `out` with each demo of `ends` given the subtask-end signals of those ends
/// (exclusive, one per subtask but the last), named by the spec's `term_signal`s. As MimicGen's
/// annotation script does, a demo's `subtask_term_signals` group is replaced by the annotated
/// signals. Each demo of `starts` gets its hand-marked segment starts (one per subtask, `None`
/// where not marked) in the `mimicgen_subtask_starts` attribute. Other demos are copied unchanged.
///
/// # Errors
/// [`PipelineError::Input`] for an unknown demo, a wrong number of ends, ends out of order or
/// out of the demo, or a spec subtask without a `term_signal`; I/O errors naming the file.
pub fn write_annotations(
    input: &Path,
    out: &Path,
    spec: &TaskSpec,
    ends: &BTreeMap<String, Vec<usize>>,
    starts: &BTreeMap<String, Vec<Option<usize>>>,
) -> Result<(), PipelineError> {
    let names: Vec<String> = spec
        .subtasks
        .iter()
        .take(spec.subtasks.len().saturating_sub(1))
        .enumerate()
        .map(|(i, s)| {
            s.term_signal.clone().ok_or_else(|| {
                PipelineError::input(
                    String::new(),
                    format!("subtask[{i}].term_signal"),
                    "the spec names no signal to write this subtask's end to",
                )
            })
        })
        .collect::<Result<_, _>>()?;
    write_signals(input, out, &names, ends, starts)
}

/// One arm of a two-arm source file as the annotate screen sees it: its spec's subtasks, and per
/// demo its view (its end effector) with proposed ends and the ends its stored signals give.
#[derive(Debug)]
pub struct ArmAnnotations {
    /// The arm (`robot0`).
    pub name: String,
    /// The arm's subtasks, as a one-arm spec.
    pub spec: TaskSpec,
    /// Per demo: the arm's view and its annotation.
    pub demos: Vec<(SourceDemo, DemoAnnotation)>,
}

/// Reads a two-arm source file of `task` and proposes each arm's subtask ends from that arm's
/// gripper, fingers and end effector (the task's two-arm spec names each arm's subtasks).
/// Returns the arms and the task's scene.
///
/// # Errors
/// An unreadable file or one without per-arm `datagen_info`, a scene that does not compile.
pub fn propose_two_arm(path: &Path, task: mimicgen_sim::two_arm::TwoArmTask) -> Result<(Vec<ArmAnnotations>, Scene), PipelineError> {
    let label = path.display().to_string();
    let file = RobomimicDataset::open(path)?;
    let arms = crate::two_arm::ARMS;
    let views = file.to_arm_source_datasets(&SourceSelection::default(), &arms)?;
    let spec = task.spec().map_err(|e| PipelineError::engine("bundled spec", e))?;
    let model_xml = views.first().and_then(|v| v.demos.first()).and_then(|d| d.sim.model_xml.clone());
    let scene = match model_xml {
        Some(xml) => task.scene_from_model_file(&xml, &format!("{label} (model_file)"))?,
        None => task.scene()?,
    };
    let mut out = Vec::new();
    for (arm, (name, view)) in arms.iter().zip(views).enumerate() {
        let arm_spec =
            spec.arm_spec(arm).ok_or_else(|| PipelineError::input(label.clone(), "arm", format!("the spec has no arm {arm}")))?;
        let robot = scene
            .robots()
            .get(arm)
            .copied()
            .cloned()
            .ok_or_else(|| PipelineError::input(label.clone(), "arm", format!("the scene has no arm {arm}")))?;
        let signal_names: Vec<String> =
            arm_spec.subtasks.iter().take(arm_spec.subtasks.len().saturating_sub(1)).filter_map(|s| s.term_signal.clone()).collect();
        let mut demos = Vec::new();
        for demo in view.demos {
            let widths = if demo.sim.states.is_empty() { None } else { scene.finger_widths_of(&robot, &demo.sim.states)? };
            let mut start = 0;
            let signal_ends = signal_names
                .iter()
                .map(|name| {
                    let end = subtask_end_from_signal(demo.subtask_term_signals.get(name)?, start)?;
                    start = end;
                    Some(end)
                })
                .collect::<Option<Vec<usize>>>();
            // The detector reads a grasp and a release per subtask; an arm's subtasks that hold on
            // (a carry, a wait) have none, and then its stored signals are the proposal.
            let proposals = match propose_subtask_ends(&demo, &arm_spec, widths.as_deref()) {
                Ok(p) => p,
                Err(e) => match &signal_ends {
                    Some(ends) => ends
                        .iter()
                        .enumerate()
                        .map(|(subtask, &end)| Proposal { subtask, end, confidence: 0.5, reason: format!("the stored signal ({e})") })
                        .collect(),
                    None => return Err(PipelineError::engine(label.clone(), e)),
                },
            };
            let annotation = DemoAnnotation { demo: demo.name.clone(), len: demo.len(), proposals, signal_ends, finger_width_m: widths };
            demos.push((demo, annotation));
        }
        out.push(ArmAnnotations { name: (*name).to_owned(), spec: arm_spec, demos });
    }
    Ok((out, scene))
}

/// `data/<demo>/datagen_info` of `file` (read from `label`), to write a demo's signals into.
fn datagen_info_mut<'a>(file: &'a mut RobomimicDataset, label: &str, demo: &str) -> Result<&'a mut Group, PipelineError> {
    let field = format!("data/{demo}");
    let Some(Node::Group(data)) = file.root.members.get_mut("data") else {
        return Err(PipelineError::input(label, "data", "missing"));
    };
    let Some(Node::Group(group)) = data.members.get_mut(demo) else {
        return Err(PipelineError::input(label, field, "not a group"));
    };
    let Some(Node::Group(info)) = group.members.get_mut("datagen_info") else {
        return Err(PipelineError::input(label, format!("{field}/datagen_info"), "missing: prepare the file first (`mimicgen prepare`)"));
    };
    Ok(info)
}

/// One arm's signal names (one per subtask but the last) and its ends per demo.
pub type ArmEnds = (Vec<String>, BTreeMap<String, Vec<usize>>);

/// Writes `input` to `out` with each arm's subtask ends as its signals: per arm its signal names
/// (one per subtask but the last) and its ends per demo. A signal both arms end on (a handover's
/// `at_handover`) must end on the same step in both.
///
/// # Errors
/// As [`write_signals`], and [`PipelineError::Input`] naming the demo and signal where the two
/// arms disagree.
pub fn write_arm_signals(input: &Path, out: &Path, arms: &[ArmEnds]) -> Result<(), PipelineError> {
    let mut file = RobomimicDataset::open(input)?;
    let label = input.display().to_string();
    let demos: std::collections::BTreeSet<&String> = arms.iter().flat_map(|(_, ends)| ends.keys()).collect();
    for demo in demos {
        let (len, field) = (file.demo_len(demo), format!("data/{demo}"));
        if file.demo(demo).is_none() {
            return Err(PipelineError::input(label.clone(), field, "no such demo"));
        }
        let mut signals: BTreeMap<String, usize> = BTreeMap::new();
        for (arm, (names, ends)) in arms.iter().enumerate() {
            let Some(demo_ends) = ends.get(demo) else { continue };
            if demo_ends.len() != names.len() {
                return Err(PipelineError::input(
                    label.clone(),
                    field,
                    format!("arm {arm}: {} subtask ends given for {} signals", demo_ends.len(), names.len()),
                ));
            }
            let mut previous = 0;
            for (name, &end) in names.iter().zip(demo_ends) {
                if end <= previous + 1 || end >= len {
                    return Err(PipelineError::input(
                        label.clone(),
                        field,
                        format!("arm {arm}: subtask end {end} must come after {} and before the demo's {len} steps", previous + 1),
                    ));
                }
                previous = end;
                if let Some(&other) = signals.get(name)
                    && other != end
                {
                    return Err(PipelineError::input(
                        label.clone(),
                        field,
                        format!(
                            "both arms end a subtask on signal {name:?}, at steps {} and {}: move one to the other",
                            other - 1,
                            end - 1
                        ),
                    ));
                }
                signals.insert(name.clone(), end);
            }
        }
        let info = datagen_info_mut(&mut file, &label, demo)?;
        let mut group = Group::default();
        for (name, end) in signals {
            group.members.insert(name, Node::Dataset(Dataset::new(Array::i64(vec![len], signal_for_end(end, len)))));
        }
        info.members.insert("subtask_term_signals".to_owned(), Node::Group(group));
    }
    file.write(out)?;
    Ok(())
}

/// [`write_annotations`] with the signal names given (one per subtask but the last).
///
/// # Errors
/// As [`write_annotations`].
pub fn write_signals(
    input: &Path,
    out: &Path,
    names: &[String],
    ends: &BTreeMap<String, Vec<usize>>,
    starts: &BTreeMap<String, Vec<Option<usize>>>,
) -> Result<(), PipelineError> {
    let mut file = RobomimicDataset::open(input)?;
    let label = input.display().to_string();
    for (demo, demo_starts) in starts {
        let (len, field) = (file.demo_len(demo), format!("data/{demo}"));
        if demo_starts.len() != names.len() + 1 {
            return Err(PipelineError::input(
                label.clone(),
                field,
                format!("{} segment starts given, the task has {} subtasks", demo_starts.len(), names.len() + 1),
            ));
        }
        if let Some(step) = demo_starts.iter().flatten().find(|&&s| s >= len) {
            return Err(PipelineError::input(label.clone(), field, format!("segment start {step} is past the demo's {len} steps")));
        }
        let Some(Node::Group(data)) = file.root.members.get_mut("data") else {
            return Err(PipelineError::input(label.clone(), "data", "missing"));
        };
        let Some(Node::Group(group)) = data.members.get_mut(demo) else {
            return Err(PipelineError::input(label.clone(), field, "no such demo"));
        };
        let values: Vec<i64> = demo_starts.iter().map(|s| s.and_then(|s| i64::try_from(s).ok()).unwrap_or(-1)).collect();
        group.attrs.insert(mimicgen_io::dataset::STARTS_ATTR.to_owned(), Array::i64(vec![values.len()], values));
    }
    for (demo, demo_ends) in ends {
        let len = file.demo_len(demo);
        let field = format!("data/{demo}");
        if file.demo(demo).is_none() {
            return Err(PipelineError::input(label.clone(), field, "no such demo"));
        }
        if demo_ends.len() != names.len() {
            return Err(PipelineError::input(
                label.clone(),
                field,
                format!("{} subtask ends given, the task has {} subtasks and so needs {}", demo_ends.len(), names.len() + 1, names.len()),
            ));
        }
        let mut previous = 0;
        for &end in demo_ends {
            if end <= previous + 1 || end >= len {
                return Err(PipelineError::input(
                    label.clone(),
                    field,
                    format!("subtask end {end} must come after {} and before the demo's {len} steps", previous + 1),
                ));
            }
            previous = end;
        }
        let info = datagen_info_mut(&mut file, &label, demo)?;
        let mut signals = Group::default();
        for (name, &end) in names.iter().zip(demo_ends) {
            signals.members.insert(name.clone(), Node::Dataset(Dataset::new(Array::i64(vec![len], signal_for_end(end, len)))));
        }
        info.members.insert("subtask_term_signals".to_owned(), Node::Group(signals));
    }
    file.write(out)?;
    Ok(())
}
