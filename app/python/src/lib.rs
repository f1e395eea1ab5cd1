//! `mimicgen_rs._native`: the Rust side of the Python package. Thin: each function calls the
//! pipeline crate (the one behind the CLI and the app) and converts at the edge: arrays become
//! numpy arrays (moved, not copied), specs, reports and events cross as JSON the Python side
//! turns into dicts, and every error is a `MimicgenError` whose message names file and field
//! and, where the caller has a choice, the keyword to pass. Long calls release the GIL; the
//! Python layer (`python/mimicgen_rs`) adds keyword arguments, docstrings and the Ray helpers.
//!
//! The whole Python API surface, one `#[pyfunction]` per call, so the binding reads as the API it
//! is.
// PyO3 hands functions their arguments by value (extracted from Python objects).
#![allow(clippy::needless_pass_by_value)]

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use mimicgen_engine::TaskSpec;
use mimicgen_io::tree::{Array, Group, Node, Values};
use mimicgen_io::{DemoReader, DemoSource as _, ReadOptions};
use mimicgen_pipeline::{Event, FrontEnd, Outcome, Pipeline, PipelineError, Report, RunConfig};
use numpy::{PyArray1, PyArrayMethods as _};
use pyo3::exceptions::PyException;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

mod policy;
mod pyenv;

pyo3::create_exception!(_native, MimicgenError, PyException, "An error of mimicgen_rs: the message names the file and field at fault.");

/// Any error, as a `MimicgenError` with its whole message.
fn error(e: impl std::fmt::Display) -> PyErr {
    MimicgenError::new_err(e.to_string())
}

/// A pipeline error as a `MimicgenError`, worded for Python: a run's fields by their keywords,
/// and what to pass where the caller has a choice (`pass overwrite=True`).
fn pipeline_error(e: PipelineError) -> PyErr {
    MimicgenError::new_err(worded(&e))
}

/// `e`'s message as Python words it.
pub(crate) fn worded(e: &PipelineError) -> String {
    e.worded(FrontEnd::Python)
}

/// `text` (JSON) as Python objects.
fn from_json<'py>(py: Python<'py>, text: &str) -> PyResult<Bound<'py, PyAny>> {
    py.import("json")?.call_method1("loads", (text,))
}

/// Python objects as JSON text.
fn to_json(value: &Bound<'_, PyAny>) -> PyResult<String> {
    value.py().import("json")?.call_method1("dumps", (value,))?.extract()
}

fn json_of(value: &impl serde::Serialize) -> PyResult<String> {
    serde_json::to_string(value).map_err(error)
}

/// One HDF5 array as a numpy array of its shape (numbers, moved without copying) or a list of
/// strings.
fn array<'py>(py: Python<'py>, a: Array) -> PyResult<Bound<'py, PyAny>> {
    fn shaped<'py, T: numpy::Element>(py: Python<'py>, v: Vec<T>, shape: &[usize]) -> PyResult<Bound<'py, PyAny>> {
        let flat = PyArray1::from_vec(py, v);
        if shape.len() == 1 {
            return Ok(flat.into_any());
        }
        Ok(flat.reshape(shape.to_vec())?.into_any())
    }
    let shape = if a.shape.is_empty() { vec![a.values.len()] } else { a.shape.clone() };
    match a.values {
        Values::F64(v) => shaped(py, v, &shape),
        Values::F32(v) => shaped(py, v, &shape),
        Values::I64(v) => shaped(py, v, &shape),
        Values::I32(v) => shaped(py, v, &shape),
        Values::I16(v) => shaped(py, v, &shape),
        Values::I8(v) => shaped(py, v, &shape),
        Values::U64(v) => shaped(py, v, &shape),
        Values::U32(v) => shaped(py, v, &shape),
        Values::U16(v) => shaped(py, v, &shape),
        Values::U8(v) => shaped(py, v, &shape),
        Values::Bool(v) => shaped(py, v, &shape),
        Values::Utf8(s) | Values::Ascii(s) | Values::Fixed { strings: s, .. } => Ok(PyList::new(py, s)?.into_any()),
    }
}

/// Every dataset under `group` as `{"path/in/group": array}`.
fn flatten<'py>(py: Python<'py>, group: Group, prefix: &str, out: &Bound<'py, PyDict>) -> PyResult<()> {
    for (name, node) in group.members {
        let path = if prefix.is_empty() { name } else { format!("{prefix}/{name}") };
        match node {
            Node::Group(g) => flatten(py, g, &path, out)?,
            Node::Dataset(d) => out.set_item(path, array(py, d.array)?)?,
        }
    }
    Ok(())
}

/// A robomimic / MimicGen HDF5 dataset opened for reading one demo at a time.
#[pyclass(module = "mimicgen_rs._native")]
struct Dataset {
    reader: Mutex<DemoReader>,
    /// The same file, read without `obs` and `next_obs` (for `datagen_info` and `observations=False`).
    low_dim: Mutex<DemoReader>,
    path: PathBuf,
    names: Vec<String>,
    env_args: Option<String>,
}

impl Dataset {
    fn load(&self, py: Python<'_>, name: &str, observations: bool) -> PyResult<Group> {
        let reader = if observations { &self.reader } else { &self.low_dim };
        py.detach(|| reader.lock().map_err(|e| e.to_string())?.load_demo(name).map(std::borrow::Cow::into_owned).map_err(|e| e.to_string()))
            .map_err(error)
    }
}

#[pymethods]
impl Dataset {
    #[new]
    #[pyo3(signature = (path, recover = false))]
    fn new(py: Python<'_>, path: PathBuf, recover: bool) -> PyResult<Self> {
        let open = || DemoReader::open_with(&path, ReadOptions { recover });
        let (reader, low_dim) = py.detach(|| Ok::<_, mimicgen_io::IoError>((open()?, open()?.without_observations()))).map_err(error)?;
        let names = reader.demo_names().to_vec();
        let env_args = reader.data_attrs().get("env_args").and_then(Array::as_str).map(str::to_owned);
        Ok(Self { reader: Mutex::new(reader), low_dim: Mutex::new(low_dim), path, names, env_args })
    }

    /// Demo names in robomimic's order.
    #[getter]
    fn demo_names(&self) -> Vec<String> {
        self.names.clone()
    }

    /// The `data` attribute `env_args` (robomimic's environment metadata JSON), if any.
    #[getter]
    fn env_args(&self) -> Option<String> {
        self.env_args.clone()
    }

    /// The file.
    #[getter]
    fn path(&self) -> PathBuf {
        self.path.clone()
    }

    fn __len__(&self) -> usize {
        self.names.len()
    }

    /// Every array of demo `name`, by its path in the demo group.
    #[pyo3(signature = (name, observations = true))]
    fn demo<'py>(&self, py: Python<'py>, name: &str, observations: bool) -> PyResult<Bound<'py, PyDict>> {
        let group = self.load(py, name, observations)?;
        let out = PyDict::new(py);
        flatten(py, group, "", &out)?;
        Ok(out)
    }

    /// The demo's `datagen_info`: `eef_pose` and `target_pose` (T, 4, 4), `gripper_action`
    /// (T, 1), `object_poses` and `subtask_term_signals` as dicts by name.
    fn datagen_info<'py>(&self, py: Python<'py>, name: &str) -> PyResult<Bound<'py, PyDict>> {
        let mut group = self.load(py, name, false)?;
        let Some(Node::Group(info)) = group.members.remove("datagen_info") else {
            return Err(error(format!("{}: data/{name} has no datagen_info (not a MimicGen source file)", self.path.display())));
        };
        let out = PyDict::new(py);
        for (key, node) in info.members {
            match node {
                Node::Dataset(d) => out.set_item(key, array(py, d.array)?)?,
                Node::Group(g) => {
                    let inner = PyDict::new(py);
                    flatten(py, g, "", &inner)?;
                    out.set_item(key, inner)?;
                }
            }
        }
        Ok(out)
    }
}

/// A task spec: the subtasks (object, end signal, offsets, selection, noise, interpolation) and
/// the generation settings.
#[pyclass(module = "mimicgen_rs._native")]
#[derive(Clone)]
struct Spec {
    inner: TaskSpec,
}

#[pymethods]
impl Spec {
    /// Reads our TOML or a MimicGen experiment JSON.
    #[staticmethod]
    fn load(path: PathBuf) -> PyResult<Self> {
        TaskSpec::load(&path).map(|inner| Self { inner }).map_err(error)
    }

    /// The spec bundled for a task (`stack`, `stack_three`, `square`).
    #[staticmethod]
    fn bundled(task: &str) -> PyResult<Self> {
        mimicgen_pipeline::bundled::spec(task).map(|inner| Self { inner }).map_err(pipeline_error)
    }

    /// A spec from the dict `to_dict` gives (checked as a TOML file would be).
    #[staticmethod]
    fn from_dict(value: &Bound<'_, PyAny>) -> PyResult<Self> {
        let spec: TaskSpec = serde_json::from_str(&to_json(value)?).map_err(|e| error(format!("spec dict: {e}")))?;
        let text = spec.to_toml_string().map_err(error)?;
        TaskSpec::from_toml_str(&text, "spec dict").map(|inner| Self { inner }).map_err(error)
    }

    /// The spec as nested dicts and lists.
    fn to_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        from_json(py, &json_of(&self.inner)?)
    }

    /// The spec as our TOML.
    fn to_toml(&self) -> PyResult<String> {
        self.inner.to_toml_string().map_err(error)
    }

    /// Writes the spec as TOML.
    fn save(&self, path: PathBuf) -> PyResult<()> {
        std::fs::write(&path, self.to_toml()?).map_err(|e| error(format!("{}: {e}", path.display())))
    }

    fn __repr__(&self) -> String {
        let objects: Vec<String> = self.inner.subtasks.iter().map(|s| s.object_ref.clone().unwrap_or_else(|| "-".to_owned())).collect();
        format!("Spec({:?}, subtasks relative to [{}])", self.inner.name, objects.join(", "))
    }
}

/// Proposed subtask ends of every demo of `path`, as `{demo: [{"end", "confidence", "reason"}]}`.
#[pyfunction]
#[pyo3(signature = (path, task = None, config = None))]
fn propose_subtask_ends(py: Python<'_>, path: PathBuf, task: Option<String>, config: Option<PathBuf>) -> PyResult<String> {
    let found = py.detach(|| mimicgen_pipeline::annotate::propose(&path, task.as_deref(), config.as_deref())).map_err(pipeline_error)?;
    let ends: BTreeMap<&str, serde_json::Value> = found
        .demos
        .iter()
        .map(|d| {
            let proposals: Vec<serde_json::Value> =
                d.proposals.iter().map(|p| serde_json::json!({"end": p.end, "confidence": p.confidence, "reason": p.reason})).collect();
            (d.demo.as_str(), serde_json::Value::Array(proposals))
        })
        .collect();
    json_of(&ends)
}

/// Writes `source` to `out` with the subtask ends `ends_json` (`{demo: [end, ...]}`) as the
/// signals MimicGen reads.
#[pyfunction]
#[pyo3(signature = (source, out, ends_json, task = None, config = None))]
fn write_subtask_ends(
    py: Python<'_>,
    source: PathBuf,
    out: PathBuf,
    ends_json: &str,
    task: Option<String>,
    config: Option<PathBuf>,
) -> PyResult<()> {
    let ends: BTreeMap<String, Vec<usize>> = serde_json::from_str(ends_json).map_err(|e| error(format!("ends: {e}")))?;
    py.detach(|| {
        let found = mimicgen_pipeline::annotate::propose(&source, task.as_deref(), config.as_deref())?;
        mimicgen_pipeline::annotate::write_annotations(&source, &out, &found.spec, &ends, &std::collections::BTreeMap::new())
    })
    .map_err(pipeline_error)
}

/// The paper's support coverage of a dataset's initial scenes (what `mimicgen coverage --json`
/// prints).
#[pyfunction]
#[pyo3(signature = (path, task = None, variant = None, bins = 3))]
fn coverage(py: Python<'_>, path: PathBuf, task: Option<String>, variant: Option<String>, bins: usize) -> PyResult<String> {
    let found = py
        .detach(|| mimicgen_pipeline::coverage::dataset_coverage(&path, task.as_deref(), variant.as_deref(), bins))
        .map_err(pipeline_error)?;
    let mut value = serde_json::to_value(&found).map_err(error)?;
    if let Some(fields) = value.as_object_mut() {
        fields.insert("support_coverage".to_owned(), serde_json::json!(found.coverage.support_coverage()));
    }
    json_of(&value)
}

/// Every task (its name, robosuite environment, variants, description, instruction and objects),
/// the task files that cannot be used (with their errors) and every arm, as JSON.
#[pyfunction]
fn tasks() -> PyResult<String> {
    let broken: Vec<serde_json::Value> =
        mimicgen_sim::registry::broken().iter().map(|b| serde_json::json!({"name": b.name, "error": b.error})).collect();
    let tasks: Vec<serde_json::Value> = mimicgen_sim::registry::tasks()
        .map(|t| {
            serde_json::json!({
                "name": t.name,
                "env_name": t.env_name,
                "variants": t.variants,
                "description": t.description,
                "instruction": t.instruction,
                "objects": t.objects.iter().map(|o| o.name.as_str()).collect::<Vec<_>>(),
                "signals": t.signals.keys().collect::<Vec<_>>(),
            })
        })
        .collect();
    let robots: Vec<serde_json::Value> = mimicgen_sim::robot::ROBOTS
        .iter()
        .map(|r| serde_json::json!({"name": r.name, "robosuite_name": r.robosuite_name, "status": r.status}))
        .collect();
    json_of(&serde_json::json!({"tasks": tasks, "broken": broken, "robots": robots}))
}

/// The task and variant of a robosuite / MimicGen environment name (`Stack_D1` -> `stack`,
/// `D1`), as datasets' `env_args` name them.
#[pyfunction]
fn task_from_env_name(env_name: &str) -> PyResult<(String, String)> {
    let (task, variant) = mimicgen_sim::registry::task_from_env_name(env_name).map_err(error)?;
    Ok((task.name().to_owned(), variant))
}

/// Joins the shards of a run into the whole run's dataset; returns the report.
#[pyfunction]
#[pyo3(signature = (shards, out, overwrite = false))]
fn merge(py: Python<'_>, shards: Vec<PathBuf>, out: PathBuf, overwrite: bool) -> PyResult<String> {
    let report = py.detach(|| mimicgen_pipeline::merge::merge(&shards, &out, overwrite, |_, _| {})).map_err(pipeline_error)?;
    json_of(&report)
}

/// Exports `path` as the LeRobot dataset `out` (what `mimicgen export --lerobot` writes);
/// returns the summary.
#[pyfunction]
#[pyo3(signature = (path, out, state_keys = None, instruction = None, ffmpeg = None, overwrite = false))]
fn export_lerobot(
    py: Python<'_>,
    path: PathBuf,
    out: PathBuf,
    state_keys: Option<Vec<String>>,
    instruction: Option<String>,
    ffmpeg: Option<PathBuf>,
    overwrite: bool,
) -> PyResult<String> {
    let request = mimicgen_pipeline::lerobot::ExportRequest { state_keys, instruction, ffmpeg, overwrite };
    let summary = py.detach(|| mimicgen_pipeline::lerobot::export(&path, &out, &request, |_, _| {})).map_err(pipeline_error)?;
    json_of(&summary)
}

/// What the generation thread sends: an event (as JSON), or the end.
enum Message {
    Event(String),
    Done(Box<Result<Report, String>>),
}

/// An event of a run as JSON: `started` (the run), `attempt` (one decided attempt with the
/// statistics so far).
fn event_json(event: &Event) -> Option<String> {
    let value = match event {
        Event::Started(info) => {
            let mut v = serde_json::to_value(info.as_ref()).ok()?;
            v.as_object_mut()?.insert("kind".to_owned(), "started".into());
            v
        }
        Event::Attempt(a) => serde_json::json!({
            "kind": "attempt",
            "index": a.attempt.index,
            "success": a.attempt.success,
            "outcome": match &a.outcome { Outcome::Written { .. } => "written", Outcome::KeptFailed { .. } => "kept_failed", Outcome::Discarded => "discarded" },
            "demo": match &a.outcome { Outcome::Written { demo } | Outcome::KeptFailed { demo } => Some(demo.clone()), Outcome::Discarded => None },
            "sources": a.attempt.src_demo_per_subtask,
            "failure": a.attempt.failure.as_ref().map(|f| serde_json::json!({"subtask": f.subtask, "reason": f.reason.to_string()})),
            "cause": a.attempt.cause,
            "steps": a.attempt.trajectory.len(),
            "stats": a.stats,
            "elapsed_s": a.elapsed_s,
            "instance": a.instance,
        }),
        Event::Finished(_) => return None,
    };
    serde_json::to_string(&value).ok()
}

/// Runs `config` as a two-arm run (`task="two_arm_lift"`), its events as JSON as [`event_json`]
/// writes a one-arm run's: subtasks numbered through both arms (arm 0's, then arm 1's), a
/// failure naming its arm and the arm's own subtask too.
fn run_two_arm(config: &RunConfig, cancel: &AtomicBool, send: &dyn Fn(String)) -> Result<Report, String> {
    use mimicgen_pipeline::two_arm::{TwoArmEvent, TwoArmRun, run_and_report};
    let run = TwoArmRun::from_config(config).map_err(|e| worded(&e))?;
    let started = std::time::Instant::now();
    let result = run_and_report(&run, cancel, &mut |event| {
        let value = match event {
            TwoArmEvent::Started { source_names, .. } => {
                let mut v = serde_json::to_value(run.info(source_names.len())).unwrap_or_default();
                if let Some(o) = v.as_object_mut() {
                    o.insert("kind".to_owned(), "started".into());
                }
                v
            }
            TwoArmEvent::Attempt { attempt, stats, written, subtask_counts, .. } => serde_json::json!({
                "kind": "attempt",
                "index": attempt.index,
                "success": attempt.success,
                "outcome": if written.is_some() { "written" } else { "discarded" },
                "demo": written,
                "sources": attempt.flat_sources(subtask_counts).map(|(_, d)| d).collect::<Vec<_>>(),
                "failure": attempt.failure.as_ref().zip(attempt.flat_failure(subtask_counts)).map(|(f, flat)| serde_json::json!({
                    "subtask": flat.subtask, "arm": f.arm, "arm_subtask": f.subtask, "reason": f.reason.to_string(),
                })),
                "steps": attempt.actions.len(),
                "stats": stats,
                "elapsed_s": started.elapsed().as_secs_f64(),
            }),
        };
        send(value.to_string());
    });
    result.map(|(_, report)| report).map_err(|e| worded(&e))
}

/// A generation run going on in the background: iterate it for its events, `wait()` for its
/// report, `cancel()` to stop it after the attempts already decided (the outputs stay valid).
#[pyclass(module = "mimicgen_rs._native")]
struct Run {
    events: Mutex<Receiver<Message>>,
    cancel: Arc<AtomicBool>,
    report: Mutex<Option<Result<Report, String>>>,
}

impl Run {
    fn start(config: RunConfig, env: Option<pyenv::Factory>) -> PyResult<Self> {
        let (tx, rx) = mpsc::channel();
        let cancel = Arc::new(AtomicBool::new(false));
        let flag = Arc::clone(&cancel);
        std::thread::Builder::new()
            .name("mimicgen-python-run".to_owned())
            .spawn(move || {
                let on_event = |e: &Event| {
                    if let Some(text) = event_json(e) {
                        let _ = tx.send(Message::Event(text));
                    }
                };
                let two_arm = config.task.as_deref().is_some_and(|t| mimicgen_sim::two_arm::TwoArmTask::from_name(t).is_some());
                let result = match env {
                    None if two_arm => run_two_arm(&config, &flag, &|text| {
                        let _ = tx.send(Message::Event(text));
                    }),
                    None => Pipeline::prepare(&config).and_then(|p| p.run(&flag, on_event)).map_err(|e| worded(&e)),
                    Some(factory) => pyenv::run(&config, &factory, &flag, on_event),
                };
                let _ = tx.send(Message::Done(Box::new(result)));
            })
            .map_err(error)?;
        Ok(Self { events: Mutex::new(rx), cancel, report: Mutex::new(None) })
    }

    /// The next message, waiting without the GIL; Ctrl-C cancels the run, waits for its outputs
    /// to be finished, and raises `KeyboardInterrupt`.
    fn next_message(&self, py: Python<'_>) -> PyResult<Option<Message>> {
        if self.report.lock().map_err(error)?.is_some() {
            return Ok(None);
        }
        loop {
            let events = &self.events;
            let got = py.detach(|| events.lock().map(|rx| rx.recv_timeout(Duration::from_millis(100))).map_err(|e| e.to_string()));
            match got.map_err(error)? {
                Ok(m) => return Ok(Some(m)),
                Err(RecvTimeoutError::Disconnected) => return Ok(None),
                Err(RecvTimeoutError::Timeout) => {
                    if let Err(interrupt) = py.check_signals() {
                        self.cancel.store(true, Ordering::Relaxed);
                        // Let the run finish its outputs (valid, marked cancelled), then raise.
                        while let Some(m) = self.next_message_quietly(py)? {
                            if let Message::Done(r) = m {
                                *self.report.lock().map_err(error)? = Some(*r);
                                break;
                            }
                        }
                        return Err(interrupt);
                    }
                }
            }
        }
    }

    fn next_message_quietly(&self, py: Python<'_>) -> PyResult<Option<Message>> {
        let events = &self.events;
        py.detach(|| events.lock().map(|rx| rx.recv().ok()).map_err(|e| e.to_string())).map_err(error)
    }

    fn finished_report<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        match self.report.lock().map_err(error)?.as_ref() {
            None => Ok(None),
            Some(Ok(r)) => Ok(Some(from_json(py, &json_of(r)?)?)),
            Some(Err(e)) => Err(error(e)),
        }
    }
}

#[pymethods]
impl Run {
    fn __iter__(slf: PyRef<'_, Self>) -> PyRef<'_, Self> {
        slf
    }

    fn __next__<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        match self.next_message(py)? {
            Some(Message::Event(text)) => Ok(Some(from_json(py, &text)?)),
            Some(Message::Done(result)) => {
                let failed = result.as_ref().as_ref().err().cloned();
                *self.report.lock().map_err(error)? = Some(*result);
                match failed {
                    Some(e) => Err(error(e)),
                    None => Ok(None),
                }
            }
            None => Ok(None),
        }
    }

    /// Waits for the end (skipping the remaining events) and returns the report.
    fn wait<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        while self.__next__(py)?.is_some() {}
        self.finished_report(py)?.ok_or_else(|| error("the run ended without a report"))
    }

    /// Stops the run after the attempts already decided; its outputs are finished as valid
    /// datasets (the report says `cancelled`).
    fn cancel(&self) {
        self.cancel.store(true, Ordering::Relaxed);
    }

    /// The report once the run has ended (`None` before); after a cancel, the report of the
    /// cancelled run (waiting the moment its outputs take to finish).
    #[getter]
    fn report<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        if self.cancel.load(Ordering::Relaxed) && self.report.lock().map_err(error)?.is_none() {
            while let Some(m) = self.next_message_quietly(py)? {
                if let Message::Done(r) = m {
                    *self.report.lock().map_err(error)? = Some(*r);
                    break;
                }
            }
        }
        self.finished_report(py)
    }
}

/// Starts a run of `config_json` (the pipeline's `RunConfig` as JSON); with `env_factory`, a
/// Python callable returning an environment, that simulator is driven instead of MuJoCo.
#[pyfunction]
#[pyo3(signature = (config_json, env_factory = None))]
fn generate(config_json: &str, env_factory: Option<Py<PyAny>>) -> PyResult<Run> {
    // The Python layer fills in every field of the run description, neither more nor fewer: a
    // field the pipeline gains fails here (and in the tests) until `generate` takes it.
    let value: serde_json::Value = serde_json::from_str(config_json).map_err(|e| error(format!("run config: {e}")))?;
    let fields = serde_json::to_value(RunConfig::default()).map_err(error)?;
    let keys = |v: &serde_json::Value| {
        let mut keys = v.as_object().map(|o| o.keys().cloned().collect::<Vec<_>>()).unwrap_or_default();
        keys.sort();
        keys
    };
    if keys(&value) != keys(&fields) {
        return Err(error(format!("run config: fields {:?}, the pipeline's are {:?}", keys(&value), keys(&fields))));
    }
    let config: RunConfig = serde_json::from_value(value).map_err(|e| error(format!("run config: {e}")))?;
    Run::start(config, env_factory.map(pyenv::Factory))
}

/// The Rust side of `mimicgen_rs`.
#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("MimicgenError", m.py().get_type::<MimicgenError>())?;
    m.add_class::<Dataset>()?;
    m.add_class::<Spec>()?;
    m.add_class::<Run>()?;
    m.add_class::<policy::Env>()?;
    m.add_function(wrap_pyfunction!(propose_subtask_ends, m)?)?;
    m.add_function(wrap_pyfunction!(write_subtask_ends, m)?)?;
    m.add_function(wrap_pyfunction!(coverage, m)?)?;
    m.add_function(wrap_pyfunction!(tasks, m)?)?;
    m.add_function(wrap_pyfunction!(task_from_env_name, m)?)?;
    m.add_function(wrap_pyfunction!(merge, m)?)?;
    m.add_function(wrap_pyfunction!(export_lerobot, m)?)?;
    m.add_function(wrap_pyfunction!(generate, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
