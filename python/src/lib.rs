//! `wgslam._native`: the pyo3 extension module under the Python package `wgslam`
//! (python/wgslam, which checks arrays and gives the documented API; docs/python.md).
//!
//! What is here: whole runs (`run`, the library's `run_observed` on a sequence resolved
//! as `wgslam run` resolves it), a sequence's frames as arrays (module `sequence`), the streaming
//! tracker (module `stream`), and the command line's entry point (`main`). Frames are processed
//! with the interpreter's lock released (`Python::detach`), so Python threads run meanwhile.
//! Errors are `wgslam.Error` with the command line's message (what it prints after
//! `error: `). Not here: shape and dtype checks with their messages (the Python package's,
//! one place); this side only refuses what would be out of bounds.

use std::ffi::OsString;
use std::path::PathBuf;

use glam::DMat4;
use numpy::ndarray::{Array1, Array2, Array3};
use numpy::{IntoPyArray, PyArray1, PyArray2, PyArray3, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::exceptions::{PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use wgslam::cli::embed;
use wgslam::dataset::{RawFrame, Sequence};
use wgslam::io::outputs::OutputSet;
use wgslam::layout::map::SurfelMap;
use wgslam::slam::params::{resolution, PoseSource};
use wgslam::tools::run::{self as run_job, Decode, FrameObserver, FrameOutcome, RunResult};
use wgslam::BackendChoice;

mod sequence;
mod stream;

pyo3::create_exception!(
    _native,
    Error,
    PyRuntimeError,
    "A run failed: the message is the command line's (what `wgslam` prints after `error: `)."
);

/// The library's error as `wgslam.Error` with the command line's message.
pub(crate) fn py_err(e: wgslam::Error) -> PyErr {
    Error::new_err(e.to_string())
}

/// A backend by its command-line name (`auto`, `cpu`, `gpu`).
pub(crate) fn backend_choice(name: &str) -> PyResult<BackendChoice> {
    match name {
        "auto" => Ok(BackendChoice::Auto),
        "cpu" => Ok(BackendChoice::Cpu),
        "gpu" => Ok(BackendChoice::Gpu),
        other => Err(PyValueError::new_err(format!(
            "backend {other:?}: want \"auto\", \"cpu\" or \"gpu\""
        ))),
    }
}

/// A pose source by its command-line name (`track`, `gt`).
pub(crate) fn pose_source(name: &str) -> PyResult<PoseSource> {
    match name {
        "track" => Ok(PoseSource::Track),
        "gt" => Ok(PoseSource::GroundTruth),
        other => Err(PyValueError::new_err(format!(
            "poses {other:?}: want \"track\" or \"gt\""
        ))),
    }
}

/// A parameter file's TOML text from the `params` dict's JSON text (`{}` for none): the
/// same keys and sections as `--params FILE.toml` (docs/params-file.md).
pub(crate) fn params_toml(params_json: &str) -> PyResult<String> {
    let table: toml::Table = serde_json::from_str(params_json).map_err(|e| {
        PyValueError::new_err(format!(
            "params: not a parameter table (string keys; numbers, strings, booleans, lists \
             and tables as values): {e}"
        ))
    })?;
    toml::to_string(&table)
        .map_err(|e| PyValueError::new_err(format!("params: cannot write as TOML: {e}")))
}

/// A pose (a rigid 4x4 matrix) as a row-major `(4, 4)` float64 array.
pub(crate) fn pose_array<'py>(py: Python<'py>, m: &DMat4) -> Bound<'py, PyArray2<f64>> {
    let rows = m.transpose().to_cols_array();
    Array2::from_shape_vec((4, 4), rows.to_vec())
        .expect("16 values make a 4x4")
        .into_pyarray(py)
}

/// A row-major `(4, 4)` array as a pose matrix.
pub(crate) fn pose_from_array(a: &PyReadonlyArray2<f64>) -> PyResult<DMat4> {
    if a.shape() != [4, 4] {
        return Err(PyValueError::new_err(format!(
            "a pose must be a (4, 4) array, got shape {:?}",
            a.shape()
        )));
    }
    let v: Vec<f64> = a.as_array().iter().copied().collect();
    if let Some(x) = v.iter().find(|x| !x.is_finite()) {
        return Err(PyValueError::new_err(format!(
            "pose holds {x}: a camera-to-world pose must be 16 finite numbers"
        )));
    }
    // The checks a pose file gets (a rigid motion, bottom row 0 0 0 1, translation in
    // range), naming the keyword where they would name the file.
    wgslam::dataset::pose_from_row_major(std::path::Path::new("pose"), &v)
        .map_err(|e| PyValueError::new_err(e.to_string()))?
        .ok_or_else(|| PyValueError::new_err("pose is not finite"))
}

/// A trajectory as arrays: stamps `(N,)` float64 and poses `(N, 4, 4)` float64.
pub(crate) type TrajectoryArrays<'py> = (Bound<'py, PyArray1<f64>>, Bound<'py, PyArray3<f64>>);

/// A frame's images as arrays: depth `(H, W)` uint16 raw units, RGB `(H, W, 3)` uint8.
pub(crate) type FrameArrays<'py> = (Bound<'py, PyArray2<u16>>, Bound<'py, PyArray3<u8>>);

/// A trajectory as `(stamps (N,) float64, poses (N, 4, 4) float64 camera-to-world)`.
pub(crate) fn trajectory_arrays<'py>(
    py: Python<'py>,
    traj: &[(f64, DMat4)],
) -> TrajectoryArrays<'py> {
    let stamps: Array1<f64> = traj.iter().map(|(t, _)| *t).collect();
    let poses: Vec<f64> = traj
        .iter()
        .flat_map(|(_, m)| m.transpose().to_cols_array())
        .collect();
    let poses = Array3::from_shape_vec((traj.len(), 4, 4), poses).expect("16 per pose");
    (stamps.into_pyarray(py), poses.into_pyarray(py))
}

/// The map as a dict of arrays, one row per surfel: `positions` (N, 3) float32 metres and
/// `normals` (N, 3) float32 unit vectors, world frame; `colors` (N, 3) uint8 RGB (rounded
/// as in map.ply); `weights` (N,) float32; `radii` (N,) float32 metres; `last_frames` (N,)
/// uint32 (the frame that last added or merged the surfel).
pub(crate) fn map_dict<'py>(py: Python<'py>, map: &SurfelMap) -> PyResult<Bound<'py, PyDict>> {
    let n = map.len();
    let rows3 = |f: &dyn Fn(usize) -> [f32; 3]| {
        let flat: Vec<f32> = (0..n).flat_map(f).collect();
        Array2::from_shape_vec((n, 3), flat).expect("3 per surfel")
    };
    let colors: Vec<u8> = (0..n)
        .flat_map(|i| map.color(i).map(|c| c.round().clamp(0.0, 255.0) as u8))
        .collect();
    let d = PyDict::new(py);
    d.set_item("positions", rows3(&|i| map.position(i)).into_pyarray(py))?;
    d.set_item("normals", rows3(&|i| map.normal(i)).into_pyarray(py))?;
    let colors = Array2::from_shape_vec((n, 3), colors).expect("3 per surfel");
    d.set_item("colors", colors.into_pyarray(py))?;
    let per = |f: &dyn Fn(usize) -> f32| (0..n).map(f).collect::<Array1<f32>>();
    d.set_item("weights", per(&|i| map.weight(i)).into_pyarray(py))?;
    d.set_item("radii", per(&|i| map.radius(i)).into_pyarray(py))?;
    let last: Array1<u32> = (0..n).map(|i| map.last_frame(i)).collect();
    d.set_item("last_frames", last.into_pyarray(py))?;
    Ok(d)
}

/// Calls the progress callback after each frame (frames done, frames in all), and stops the
/// run when the callback raises or a signal's Python handler does (Ctrl-C): the exception
/// is kept for [`run`] to raise.
struct Progress {
    callback: Option<Py<PyAny>>,
    total: usize,
    done: usize,
    raised: Option<PyErr>,
}

impl FrameObserver for Progress {
    fn wants_map(&mut self, _index: usize) -> bool {
        false
    }

    fn frame(
        &mut self,
        _raw: &RawFrame,
        outcome: &FrameOutcome,
        _map: Option<&SurfelMap>,
    ) -> wgslam::Result<()> {
        self.done += 1;
        let (done, total) = (self.done, self.total);
        let called = Python::attach(|py| -> PyResult<()> {
            py.check_signals()?;
            match &self.callback {
                Some(cb) => cb.call1(py, (done, total)).map(|_| ()),
                None => Ok(()),
            }
        });
        called.map_err(|e| {
            self.raised = Some(e);
            wgslam::Error::Interrupted(format!(
                "stopped after frame {} by the progress callback or a signal",
                outcome.index
            ))
        })
    }
}

/// A finished whole run: the library's result and the sequence it ran on (for `write`).
#[pyclass(module = "wgslam._native", frozen)]
struct Run {
    result: RunResult,
    sequence: Sequence,
}

#[pymethods]
impl Run {
    /// `trajectory.tum`'s poses: `(stamps (N,), poses (N, 4, 4))`, camera to world, after
    /// loop closure when it ran.
    fn trajectory<'py>(&self, py: Python<'py>) -> TrajectoryArrays<'py> {
        trajectory_arrays(py, &self.result.trajectory())
    }

    /// `trajectory_odometry.tum`'s poses: as tracked, before any loop closure.
    fn odometry<'py>(&self, py: Python<'py>) -> TrajectoryArrays<'py> {
        trajectory_arrays(py, &run_job::trajectory(&self.result.frames))
    }

    /// The map's arrays ([`map_dict`]).
    fn map<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        map_dict(py, &self.result.map)
    }

    /// `metrics.json`'s text.
    fn metrics_json(&self) -> PyResult<String> {
        serde_json::to_string(&self.result.metrics).map_err(|e| Error::new_err(e.to_string()))
    }

    /// `frames.json`'s text: one record per frame.
    fn frames_json(&self) -> PyResult<String> {
        serde_json::to_string(&self.result.frames).map_err(|e| Error::new_err(e.to_string()))
    }

    /// Writes the outputs `wgslam run --out OUT_DIR` writes, as a set (each file complete or
    /// not written; a folder of other files is refused, as by the command line).
    fn write(&self, py: Python<'_>, out_dir: PathBuf) -> PyResult<()> {
        py.detach(|| -> wgslam::Result<()> {
            let outputs = OutputSet::begin(&out_dir, &run_job::OUTPUT_FILES)?;
            run_job::write_files_and_pictures(outputs.dir(), &self.result, &self.sequence)?;
            outputs.commit()
        })
        .map_err(py_err)
    }
}

/// Runs dense SLAM over a sequence as `wgslam run DATASET --frames FRAMES --backend BACKEND
/// --poses POSES --params FILE` does (no files written): `params_json` the parameter
/// file's table as JSON, `progress` called with (done, total) after each frame.
#[pyfunction]
#[pyo3(signature = (dataset, frames, backend, poses, params_json, progress=None))]
fn run(
    py: Python<'_>,
    dataset: Option<PathBuf>,
    frames: Option<String>,
    backend: &str,
    poses: &str,
    params_json: &str,
    progress: Option<Py<PyAny>>,
) -> PyResult<Run> {
    let choice = backend_choice(backend)?;
    let poses = pose_source(poses)?;
    let text = params_toml(params_json)?;
    let setup = py
        .detach(|| embed::resolve_run(dataset.as_deref(), frames.as_deref(), &text, poses))
        .map_err(py_err)?;
    let mut observer = Progress {
        callback: progress,
        total: setup.frames.clone().count(),
        done: 0,
        raised: None,
    };
    let result = py.detach(|| {
        let backend = wgslam::open_backend_shared(choice)?;
        let (params, downsample_from) = resolution::for_backends(
            setup.params.clone(),
            setup.sets_downsample,
            &[backend.name()],
        )?;
        let mut result = run_job::run_observed(
            backend,
            &setup.sequence,
            setup.frames.clone(),
            params,
            Decode::ahead_on_every_core(),
            |_| {},
            Some(&mut observer),
        )?;
        result.metrics.downsample_from = Some(downsample_from);
        Ok::<_, wgslam::Error>(result)
    });
    match (result, observer.raised) {
        (Ok(result), _) => Ok(Run {
            result,
            sequence: setup.sequence,
        }),
        (Err(_), Some(raised)) => Err(raised),
        (Err(e), None) => Err(py_err(e)),
    }
}

/// The `wgslam` command: `args` as `sys.argv` (the program's name first); returns the exit
/// status. Runs with the interpreter's lock released.
#[pyfunction]
fn main(py: Python<'_>, args: Vec<OsString>) -> u8 {
    py.detach(|| embed::main(args))
}

/// The extension module `wgslam._native`.
/// GPU devices this process has opened: `wgslam.Slam`s and `wgslam.run`s share one, so
/// it does not grow with them (a diagnostic for tests).
#[pyfunction]
fn devices_opened() -> u64 {
    wgslam::gpu::GpuContext::devices_opened()
}

#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("Error", m.py().get_type::<Error>())?;
    m.add_class::<Run>()?;
    m.add_class::<sequence::SequenceFrames>()?;
    m.add_class::<stream::Stream>()?;
    m.add_function(wrap_pyfunction!(run, m)?)?;
    m.add_function(wrap_pyfunction!(sequence::open_sequence, m)?)?;
    m.add_function(wrap_pyfunction!(main, m)?)?;
    m.add_function(wrap_pyfunction!(devices_opened, m)?)?;
    Ok(())
}
