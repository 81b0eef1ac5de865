//! The streaming tracker (`wgslam.Slam`): the library's frame loop (`slam::pipeline::Slam`)
//! fed one frame at a time from arrays, for live sensors. Each frame goes through exactly
//! the call `wgslam run` makes for it (`Slam::process` with the frame's number, raw depth,
//! packed colour and, when given, its known pose), so a stream over a sequence's frames
//! gives `wgslam run`'s trajectory bit for bit.

use std::collections::HashMap;
use std::sync::Mutex;

use glam::DMat4;
use numpy::{PyArray2, PyReadonlyArray2, PyReadonlyArray3, PyUntypedArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use wgslam::cli::embed;
use wgslam::geometry::camera::Intrinsics;
use wgslam::layout::pack_rgba8;
use wgslam::slam::backend::Inspect;
use wgslam::slam::params::resolution::{self, DownsampleFrom};
use wgslam::slam::pipeline::{Slam, TrackStatus};
use wgslam::AnyBackend;

use crate::{
    backend_choice, map_dict, params_toml, pose_array, pose_from_array, pose_source, py_err,
    trajectory_arrays, TrajectoryArrays,
};

/// The tracker and what it has been given so far.
struct State {
    slam: Slam<AnyBackend>,
    /// The next frame's number when `track` is not given one.
    next_frame: u32,
    /// Every fused frame's stamp by frame number (for loop closure's poses).
    stamps: HashMap<u32, f64>,
    /// The tracked frames' `(stamp, camera-to-world)` in order, as tracked.
    tracked: Vec<(f64, DMat4)>,
}

impl State {
    /// The trajectory as `wgslam run` writes it: loop closure's poses when it runs, else the
    /// tracked frames' own.
    fn trajectory(&self) -> Vec<(f64, DMat4)> {
        match self.slam.loop_closure() {
            Some(lc) => lc
                .poses()
                .iter()
                .filter_map(|p| Some((*self.stamps.get(&p.frame)?, p.estimate)))
                .collect(),
            None => self.tracked.clone(),
        }
    }
}

/// One frame's depth as it arrived: raw units or metres.
enum Depth {
    Raw(Vec<u16>),
    Metres(Vec<f32>),
}

/// A frame's story in words: `(status, detail)`. The status is `tracked` (ICP from the last
/// pose), `given` (a known pose, or the first frame), `relocalised`, `lost` or `empty` (no
/// depth); the detail the pipeline's own (ICP's ending, why it was lost).
fn status_words(s: &TrackStatus) -> (&'static str, String) {
    match s {
        TrackStatus::Given => ("given", String::new()),
        TrackStatus::Converged => ("tracked", "converged".into()),
        TrackStatus::MaxIterations => ("tracked", "at the finest level's iteration budget".into()),
        TrackStatus::Stopped(why) => ("tracked", format!("stopped early: {why}")),
        TrackStatus::Relocalised { keyframe_frame } => (
            "relocalised",
            format!("from the keyframe of frame {keyframe_frame}"),
        ),
        TrackStatus::Lost(why) => ("lost", why.clone()),
        TrackStatus::EmptyDepth => ("empty", "no valid depth".into()),
    }
}

/// The streaming tracker behind `wgslam.Slam`.
#[pyclass(module = "wgslam._native", name = "Slam")]
pub struct Stream {
    state: Mutex<State>,
    /// The frames' size, `(width, height)` pixels.
    size: (usize, usize),
    /// The input's downsampling and where it came from (the parameters, or the backend's
    /// default when they set none).
    downsample: (u32, DownsampleFrom),
}

impl Stream {
    /// The state, or an error when an earlier call panicked while holding it.
    fn state(&self) -> PyResult<std::sync::MutexGuard<'_, State>> {
        self.state
            .lock()
            .map_err(|_| crate::Error::new_err("the tracker failed earlier and cannot go on"))
    }
}

#[pymethods]
impl Stream {
    /// A tracker for frames from a camera `(width, height, fx, fy, cx, cy)` (pixels) whose
    /// raw depth holds `depth_scale` units per metre, with a parameter table's settings.
    #[new]
    #[pyo3(signature = (intrinsics, depth_scale, backend, poses, params_json))]
    fn new(
        py: Python<'_>,
        intrinsics: (u32, u32, f32, f32, f32, f32),
        depth_scale: f32,
        backend: &str,
        poses: &str,
        params_json: &str,
    ) -> PyResult<Self> {
        // (width, height, fx, fy, cx, cy), as `Sequence.intrinsics()` gives them.
        let k = Intrinsics {
            width: intrinsics.0,
            height: intrinsics.1,
            fx: intrinsics.2,
            fy: intrinsics.3,
            cx: intrinsics.4,
            cy: intrinsics.5,
        };
        let finite = [k.fx, k.fy, k.cx, k.cy].iter().all(|x| x.is_finite());
        if k.width == 0 || k.height == 0 || k.fx == 0.0 || k.fy == 0.0 || !finite {
            return Err(PyValueError::new_err(format!(
                "intrinsics {intrinsics:?}: want a non-empty image and finite fx, fy, cx, cy with \
                 fx, fy non-zero"
            )));
        }
        let choice = backend_choice(backend)?;
        // Validated once, by the parameter text's reading; the depth scale by its own check.
        let text = embed::params_from_toml(&params_toml(params_json)?, pose_source(poses)?)
            .map_err(py_err)?;
        let params = text
            .params
            .with_depth_scale(depth_scale)
            .map_err(|e| PyValueError::new_err(e.to_string()))?;
        let backend = py
            .detach(|| wgslam::open_backend_shared(choice))
            .map_err(py_err)?;
        // Unset, the resolution is the backend's default, as `wgslam run` chooses it.
        let (params, downsample_from) =
            resolution::for_backends(params, text.sets_downsample, &[backend.name()])
                .map_err(py_err)?;
        Ok(Stream {
            downsample: (params.input.downsample, downsample_from),
            state: Mutex::new(State {
                slam: Slam::new(backend, k, params),
                next_frame: 0,
                stamps: HashMap::new(),
                tracked: vec![],
            }),
            size: (k.width as usize, k.height as usize),
        })
    }

    /// Tracks and fuses one frame: `depth_raw` (H, W) uint16 or `depth_m` (H, W) float32
    /// (exactly one), `color` (H, W, 3) uint8 or `None` (black), `timestamp` (default: the
    /// frame number), `pose` a known camera-to-world (4, 4) (the first frame's, or every
    /// frame's with poses "gt"), `frame_id` the frame's number (default: the last plus one,
    /// from 0). Returns `(camera-to-world (4, 4), status, detail, report as JSON)`.
    #[pyo3(signature = (depth_raw, depth_m, color, timestamp, pose, frame_id))]
    #[allow(clippy::too_many_arguments)] // the frame's parts, each optional, as Python passes them
    fn track<'py>(
        &self,
        py: Python<'py>,
        depth_raw: Option<PyReadonlyArray2<'py, u16>>,
        depth_m: Option<PyReadonlyArray2<'py, f32>>,
        color: Option<PyReadonlyArray3<'py, u8>>,
        timestamp: Option<f64>,
        pose: Option<PyReadonlyArray2<'py, f64>>,
        frame_id: Option<u32>,
    ) -> PyResult<(Bound<'py, PyArray2<f64>>, &'static str, String, String)> {
        let (w, h) = self.size;
        let wrong = |what: &str, shape: &[usize], want: String| {
            PyValueError::new_err(format!("{what} has shape {shape:?}, expected {want}"))
        };
        let depth = match (depth_raw, depth_m) {
            (Some(d), None) if d.shape() == [h, w] => {
                Depth::Raw(d.as_array().iter().copied().collect())
            }
            (None, Some(d)) if d.shape() == [h, w] => {
                Depth::Metres(d.as_array().iter().copied().collect())
            }
            (Some(d), None) => return Err(wrong("depth", d.shape(), format!("[{h}, {w}]"))),
            (None, Some(d)) => return Err(wrong("depth", d.shape(), format!("[{h}, {w}]"))),
            _ => {
                return Err(PyValueError::new_err(
                    "give exactly one of depth_raw and depth_m",
                ))
            }
        };
        let rgba: Vec<u32> = match color {
            Some(c) if c.shape() == [h, w, 3] => {
                let a = c.as_array();
                (0..h)
                    .flat_map(|v| (0..w).map(move |u| (v, u)))
                    .map(|(v, u)| pack_rgba8([a[[v, u, 0]], a[[v, u, 1]], a[[v, u, 2]]]))
                    .collect()
            }
            Some(c) => return Err(wrong("color", c.shape(), format!("[{h}, {w}, 3]"))),
            None => vec![pack_rgba8([0, 0, 0]); w * h],
        };
        let pose = pose.as_ref().map(pose_from_array).transpose()?;
        if let Some(t) = timestamp.filter(|t| !t.is_finite()) {
            return Err(PyValueError::new_err(format!(
                "timestamp {t} must be a finite number (the frame's time, seconds)"
            )));
        }
        // The lock is taken with the interpreter's released: another thread's call waits for
        // it without holding the interpreter this call needs to return.
        let report = py.detach(|| -> PyResult<_> {
            let mut state = self.state()?;
            let id = frame_id.unwrap_or(state.next_frame);
            let raw = match depth {
                Depth::Raw(d) => d,
                Depth::Metres(m) => {
                    embed::raw_depth_from_metres(&m, state.slam.params.input.depth_scale)
                }
            };
            let report = state
                .slam
                .process(id, &raw, &rgba, pose.as_ref())
                .map_err(py_err)?;
            state.next_frame = id.saturating_add(1);
            if report.status.is_tracked() {
                let stamp = timestamp.unwrap_or(f64::from(id));
                state.stamps.insert(id, stamp);
                state.tracked.push((stamp, report.t_cam_to_world));
            }
            Ok(report)
        })?;
        let (status, detail) = status_words(&report.status);
        let json =
            serde_json::to_string(&report).map_err(|e| crate::Error::new_err(e.to_string()))?;
        Ok((pose_array(py, &report.t_cam_to_world), status, detail, json))
    }

    /// The input's downsampling: 1 tracks every pixel, 2 every second pixel in each
    /// direction.
    #[getter]
    fn downsample(&self) -> u32 {
        self.downsample.0
    }

    /// Where [`Stream::downsample`] came from, as `metrics.json`'s `downsample_from`
    /// writes it: `"set"` (the parameters), `"gpu-default"` or `"cpu-default"`.
    #[getter]
    fn downsample_from(&self) -> PyResult<String> {
        serde_json::to_value(self.downsample.1)
            .ok()
            .and_then(|v| v.as_str().map(str::to_owned))
            .ok_or_else(|| crate::Error::new_err("downsample_from has no name"))
    }

    /// The map now, as a dict of arrays (see `wgslam.RunResult.map`).
    fn map<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let map = py.detach(|| self.state()?.slam.backend.download_map().map_err(py_err))?;
        map_dict(py, &map)
    }

    /// The trajectory so far: `(stamps (N,), poses (N, 4, 4))`, camera to world, the tracked
    /// frames only, after loop closure when it runs.
    fn trajectory<'py>(&self, py: Python<'py>) -> PyResult<TrajectoryArrays<'py>> {
        let trajectory = py.detach(|| self.state().map(|s| s.trajectory()))?;
        Ok(trajectory_arrays(py, &trajectory))
    }
}
