//! Bring your own simulator: a Python object with the environment protocol (see
//! `mimicgen_rs.Environment`) driven by the Rust engine in place of the MuJoCo backend, through
//! the same pipeline (writers, shards, resume, events, report).
//!
//! The trait's observers (`eef_pose`, ...) cannot fail; a Python exception there is kept and
//! returned by the next call that can (`step`, `reset`, ...), which ends the run with the
//! exception's text.

use std::collections::BTreeMap;
use std::sync::Mutex;
use std::sync::atomic::AtomicBool;

use mimicgen_engine::pose::{Mat4, Pose, pose_from_matrix, pose_to_matrix};
use mimicgen_engine::{Attempt, EngineError, EnvError, Environment};
use mimicgen_io::Observation;
use mimicgen_pipeline::{Event, Observed, Pipeline, Report, RunConfig};
use numpy::{PyArray1, PyArrayMethods as _};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use rand::RngCore;

/// A Python callable that returns a new environment (one per worker).
pub struct Factory(pub Py<PyAny>);

/// `value` as flat floats (any array-like).
fn floats(value: &Bound<'_, PyAny>) -> PyResult<Vec<f64>> {
    let np = value.py().import("numpy")?;
    np.call_method1("asarray", (value, "float64"))?.call_method0("ravel")?.call_method0("tolist")?.extract()
}

fn pose(value: &Bound<'_, PyAny>, what: &str) -> PyResult<Pose> {
    let v = floats(value)?;
    if v.len() != 16 {
        return Err(crate::error(format!("{what}: expected a 4x4 matrix, got {} numbers", v.len())));
    }
    pose_from_matrix(&Mat4::from_row_slice(&v), what).map_err(crate::error)
}

fn matrix<'py>(py: Python<'py>, p: &Pose) -> PyResult<Bound<'py, PyAny>> {
    let m = pose_to_matrix(p);
    // Row-major (nalgebra stores columns first).
    let rows: Vec<f64> = m.transpose().iter().copied().collect();
    Ok(PyArray1::from_vec(py, rows).reshape([4, 4])?.into_any())
}

fn vector<'py>(py: Python<'py>, v: &[f64]) -> Bound<'py, PyAny> {
    PyArray1::from_slice(py, v).into_any()
}

/// A Python environment, as the engine's [`Environment`].
pub struct PyEnv {
    obj: Py<PyAny>,
    action_dim: usize,
    /// The first exception of a call that could not return it.
    pending: Mutex<Option<String>>,
}

impl PyEnv {
    fn new(obj: Py<PyAny>) -> PyResult<Self> {
        let action_dim = Python::attach(|py| obj.call_method0(py, "action_dim")?.extract::<usize>(py))?;
        Ok(Self { obj, action_dim, pending: Mutex::new(None) })
    }

    /// Calls `f` with the GIL; an exception is kept for the next fallible call, `fallback` returned.
    fn observe<T>(&self, fallback: T, f: impl FnOnce(Python<'_>, &Bound<'_, PyAny>) -> PyResult<T>) -> T {
        Python::attach(|py| match f(py, self.obj.bind(py)) {
            Ok(v) => v,
            Err(e) => {
                if let Ok(mut pending) = self.pending.lock()
                    && pending.is_none()
                {
                    *pending = Some(e.to_string());
                }
                fallback
            }
        })
    }

    /// Calls `f` with the GIL, after reporting an exception an observer kept.
    fn act(&self, f: impl FnOnce(Python<'_>, &Bound<'_, PyAny>) -> PyResult<()>) -> Result<(), EnvError> {
        if let Some(reason) = self.pending.lock().ok().and_then(|mut p| p.take()) {
            return Err(EnvError::Fatal { reason: format!("the Python environment raised {reason}") });
        }
        Python::attach(|py| f(py, self.obj.bind(py))).map_err(|e| EnvError::Fatal { reason: format!("the Python environment raised {e}") })
    }
}

impl Environment for PyEnv {
    fn reset(&mut self, rng: &mut dyn RngCore) -> Result<(), EnvError> {
        let seed = rng.next_u64();
        self.act(|_, env| env.call_method1("reset", (seed,)).map(drop))
    }

    fn eef_pose(&self) -> Pose {
        self.observe(Pose::identity(), |_, env| pose(&env.call_method0("eef_pose")?, "eef_pose()"))
    }

    fn object_poses(&self) -> BTreeMap<String, Pose> {
        self.observe(BTreeMap::new(), |_, env| {
            let found = env.call_method0("object_poses")?;
            let dict = found.cast::<PyDict>().map_err(|_| crate::error("object_poses() must return a dict of 4x4 matrices"))?;
            dict.iter().map(|(k, v)| Ok((k.extract::<String>()?, pose(&v, &format!("object_poses()[{k}]"))?))).collect()
        })
    }

    fn subtask_term_signals(&self) -> BTreeMap<String, i64> {
        self.observe(BTreeMap::new(), |_, env| env.call_method0("subtask_term_signals")?.extract())
    }

    fn is_success(&self) -> bool {
        self.observe(false, |_, env| env.call_method0("is_success")?.is_truthy())
    }

    fn unmet_success(&self) -> Option<String> {
        self.observe(None, |_, env| if env.hasattr("unmet_success")? { env.call_method0("unmet_success")?.extract() } else { Ok(None) })
    }

    fn target_pose_to_action(&self, world_from_target: &Pose) -> [f64; 6] {
        self.observe([0.0; 6], |py, env| {
            let v = floats(&env.call_method1("target_pose_to_action", (matrix(py, world_from_target)?,))?)?;
            v.try_into().map_err(|v: Vec<f64>| crate::error(format!("target_pose_to_action() must return 6 numbers, got {}", v.len())))
        })
    }

    fn action_to_target_pose(&self, action: &[f64]) -> Pose {
        self.observe(Pose::identity(), |py, env| {
            pose(&env.call_method1("action_to_target_pose", (vector(py, action),))?, "action_to_target_pose()")
        })
    }

    fn action_dim(&self) -> usize {
        self.action_dim
    }

    fn step(&mut self, action: &[f64]) -> Result<(), EnvError> {
        self.act(|py, env| env.call_method1("step", (vector(py, action),)).map(drop))
    }

    fn state(&self) -> Vec<f64> {
        self.observe(Vec::new(), |_, env| floats(&env.call_method0("get_state")?))
    }

    fn place_objects(&mut self, world_from_objects: &BTreeMap<String, Pose>) -> Result<(), EnvError> {
        if world_from_objects.is_empty() {
            return Ok(());
        }
        self.act(|py, env| {
            let poses = PyDict::new(py);
            for (name, p) in world_from_objects {
                poses.set_item(name, matrix(py, p)?)?;
            }
            env.call_method1("place_objects", (poses,)).map(drop)
        })
    }

    fn set_state(&mut self, state: &[f64]) -> Result<(), EnvError> {
        self.act(|py, env| env.call_method1("set_state", (vector(py, state),)).map(drop))
    }
}

/// Observations of a kept attempt: with an `observations()` method, the environment is set to
/// each stored state and observed; without, none (the dataset holds actions, states and
/// `datagen_info`).
fn observations(env: &mut PyEnv, attempt: &Attempt) -> Result<Observed, EngineError> {
    let wrap = |e: PyErr| EngineError::Env { attempt: attempt.index, source: EnvError::Fatal { reason: format!("observations(): {e}") } };
    let has = Python::attach(|py| env.obj.bind(py).hasattr("observations")).map_err(wrap)?;
    if !has {
        return Ok(Observed::default());
    }
    let mut obs: BTreeMap<String, Observation> = BTreeMap::new();
    for state in attempt.trajectory.states.iter() {
        env.set_state(state).map_err(|source| EngineError::Env { attempt: attempt.index, source })?;
        Python::attach(|py| -> PyResult<()> {
            let found = env.obj.bind(py).call_method0("observations")?;
            let dict = found.cast::<PyDict>().map_err(|_| crate::error("observations() must return a dict of arrays"))?;
            for (k, v) in dict.iter() {
                let shape: Vec<usize> = py.import("numpy")?.call_method1("shape", (&v,))?.extract()?;
                let entry = obs.entry(k.extract()?).or_insert_with(|| (shape, Vec::new()));
                entry.1.extend(floats(&v)?);
            }
            Ok(())
        })
        .map_err(wrap)?;
    }
    Ok(Observed { obs, ..Observed::default() })
}

/// Runs `config` through the pipeline on environments made by `factory` (one per worker).
pub fn run(config: &RunConfig, factory: &Factory, cancel: &AtomicBool, on_event: impl FnMut(&Event)) -> Result<Report, String> {
    let pipeline = Pipeline::prepare(config).map_err(|e| crate::worded(&e))?;
    let mut envs = (0..config.workers.max(1))
        .map(|_| Python::attach(|py| factory.0.call0(py)).and_then(PyEnv::new))
        .collect::<PyResult<Vec<_>>>()
        .map_err(|e| format!("making the Python environment: {e}"))?;
    pipeline.run_on(&mut envs, observations, cancel, on_event).map_err(|e| crate::worded(&e))
}
