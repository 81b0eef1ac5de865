//! A dataset's frames as numpy arrays (`wgslam.open_sequence`): the readers of `wgslam run`
//! (every layout it reads, the same decoding), for feeding `wgslam.Slam` frame by frame or
//! looking at the images. Not a run: nothing is tracked here.

use std::path::PathBuf;

use numpy::ndarray::{Array2, Array3};
use numpy::{IntoPyArray, PyArray2};
use pyo3::exceptions::PyIndexError;
use pyo3::prelude::*;

use wgslam::cli::embed;
use wgslam::dataset::Sequence;

use crate::{params_toml, pose_array, py_err, FrameArrays};

/// An opened sequence: its camera, depth scale, stamps, ground truth and images.
#[pyclass(module = "wgslam._native", name = "Sequence", frozen)]
pub struct SequenceFrames {
    sequence: Sequence,
    /// The frames `wgslam run` runs without `--frames`: from the first with ground truth.
    default_first: usize,
}

impl SequenceFrames {
    /// Frame `i`'s record, or an `IndexError` naming the sequence's length.
    fn record(&self, i: usize) -> PyResult<&wgslam::dataset::FrameRecord> {
        self.sequence.frames.get(i).ok_or_else(|| {
            PyIndexError::new_err(format!(
                "frame {i}: the sequence has {} frames",
                self.sequence.len()
            ))
        })
    }
}

#[pymethods]
impl SequenceFrames {
    fn __len__(&self) -> usize {
        self.sequence.len()
    }

    /// The depth images' camera: `(width, height, fx, fy, cx, cy)`, pixels.
    fn intrinsics(&self) -> (u32, u32, f32, f32, f32, f32) {
        let k = self.sequence.intrinsics;
        (k.width, k.height, k.fx, k.fy, k.cx, k.cy)
    }

    /// Raw depth units per metre.
    fn depth_scale(&self) -> f32 {
        self.sequence.depth_scale
    }

    /// The first frame `wgslam run` runs without `--frames` (the first with ground truth).
    fn default_first_frame(&self) -> usize {
        self.default_first
    }

    /// Frame `i`'s stamp (seconds, or the frame number where the layout has no clock).
    fn timestamp(&self, i: usize) -> PyResult<f64> {
        Ok(self.record(i)?.timestamp)
    }

    /// Frame `i`'s ground-truth camera-to-world pose, `(4, 4)` float64, or `None`.
    fn ground_truth<'py>(
        &self,
        py: Python<'py>,
        i: usize,
    ) -> PyResult<Option<Bound<'py, PyArray2<f64>>>> {
        Ok(self
            .record(i)?
            .gt_cam_to_world
            .as_ref()
            .map(|m| pose_array(py, m)))
    }

    /// Frame `i`'s images as decoded for a run: `(depth (H, W) uint16 raw units, rgb (H, W,
    /// 3) uint8)`, row-major, colour resampled onto the depth image where the layout's
    /// colour camera differs.
    fn frame<'py>(&self, py: Python<'py>, i: usize) -> PyResult<FrameArrays<'py>> {
        self.record(i)?;
        let raw = py.detach(|| self.sequence.load(i)).map_err(py_err)?;
        let (h, w) = (raw.height as usize, raw.width as usize);
        let depth = Array2::from_shape_vec((h, w), raw.depth).expect("decoded as W x H");
        let rgb: Vec<u8> = raw.rgb.into_iter().flatten().collect();
        let rgb = Array3::from_shape_vec((h, w, 3), rgb).expect("decoded as W x H");
        Ok((depth.into_pyarray(py), rgb.into_pyarray(py)))
    }
}

/// Opens `dataset` (`None`: the bundled frames) as `wgslam run` does, with the dataset keys
/// of `params_json` (`camera`, `intrinsics`, `depth-scale`, `gt`, `max-time-diff`).
#[pyfunction]
#[pyo3(signature = (dataset, params_json))]
pub fn open_sequence(
    py: Python<'_>,
    dataset: Option<PathBuf>,
    params_json: &str,
) -> PyResult<SequenceFrames> {
    let text = params_toml(params_json)?;
    let sequence = py
        .detach(|| embed::open_sequence(dataset.as_deref(), &text))
        .map_err(py_err)?;
    Ok(SequenceFrames {
        default_first: sequence.default_first_frame(),
        sequence,
    })
}
