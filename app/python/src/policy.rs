//! `mimicgen_rs._native.Env`: the pipeline's [`PolicyEnv`] for Python (the package's `Env`,
//! robomimic's `EnvMimicGenRs` and the gymnasium wrapper sit on it). Steps release the GIL.

use std::sync::Mutex;

use mimicgen_engine::image::Pixels;
use mimicgen_pipeline::{PolicyEnv, RunConfig};
use numpy::{PyArray1, PyArrayMethods as _};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::{error, pipeline_error};

/// One environment for policy rollouts.
#[pyclass(module = "mimicgen_rs._native")]
pub struct Env {
    inner: Mutex<PolicyEnv>,
}

impl Env {
    fn with<T>(&self, py: Python<'_>, f: impl FnOnce(&mut PolicyEnv) -> T + Send, detach: bool) -> PyResult<T>
    where
        T: Send,
    {
        let run = || self.inner.lock().map(|mut env| f(&mut env)).map_err(|e| e.to_string());
        if detach { py.detach(run) } else { run() }.map_err(error)
    }
}

#[pymethods]
impl Env {
    /// `config_json`: a run config's task, variant, robot and cameras (the rest is ignored).
    #[new]
    fn new(py: Python<'_>, config_json: &str, seed: u64) -> PyResult<Self> {
        let config: RunConfig = serde_json::from_str(config_json).map_err(|e| error(format!("env config: {e}")))?;
        let env = py.detach(|| PolicyEnv::new(&config, seed)).map_err(pipeline_error)?;
        Ok(Self { inner: Mutex::new(env) })
    }

    fn env_args(&self, py: Python<'_>) -> PyResult<String> {
        self.with(py, |env| env.env_args().to_owned(), false)
    }

    fn action_dim(&self, py: Python<'_>) -> PyResult<usize> {
        self.with(py, |env| env.action_dim(), false)
    }

    fn reseed(&self, py: Python<'_>, seed: u64) -> PyResult<()> {
        self.with(py, |env| env.reseed(seed), false)
    }

    fn reset(&self, py: Python<'_>) -> PyResult<()> {
        self.with(py, PolicyEnv::reset, true)?.map_err(pipeline_error)
    }

    fn reset_to(&self, py: Python<'_>, state: Vec<f64>) -> PyResult<()> {
        self.with(py, |env| env.reset_to(&state), true)?.map_err(pipeline_error)
    }

    fn step(&self, py: Python<'_>, action: Vec<f64>) -> PyResult<()> {
        self.with(py, |env| env.step(&action), true)?.map_err(pipeline_error)
    }

    /// Low-dim observations by key (flat float64 arrays), then camera images by key (uint8,
    /// `[height, width, 3]`) when the environment has cameras.
    fn observation<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let (low_dim, images) = self.with(py, |env| (env.observation(), env.images()), true)?;
        let images = images.map_err(pipeline_error)?;
        let out = PyDict::new(py);
        for (key, value) in low_dim {
            out.set_item(key, PyArray1::from_vec(py, value))?;
        }
        for (key, stream) in images {
            let shape = stream.shape.to_vec();
            match stream.pixels {
                Pixels::Rgb(p) => out.set_item(key, PyArray1::from_vec(py, p).reshape(shape)?)?,
                Pixels::Depth(p) => out.set_item(key, PyArray1::from_vec(py, p).reshape(shape)?)?,
            }
        }
        Ok(out)
    }

    fn is_success(&self, py: Python<'_>) -> PyResult<bool> {
        self.with(py, |env| env.is_success(), false)
    }

    fn subtask_signals(&self, py: Python<'_>) -> PyResult<std::collections::BTreeMap<String, i64>> {
        self.with(py, |env| env.subtask_signals(), false)
    }

    fn state<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray1<f64>>> {
        Ok(PyArray1::from_vec(py, self.with(py, |env| env.state(), false)?))
    }

    fn model_xml(&self, py: Python<'_>) -> PyResult<String> {
        self.with(py, |env| env.model_xml(), false)
    }

    fn object_instance(&self, py: Python<'_>) -> PyResult<Option<String>> {
        self.with(py, |env| env.object_instance(), false)
    }
}
