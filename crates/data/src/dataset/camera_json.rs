//! `camera.json`, the camera a dataset folder may carry (it wins over the layout's own
//! files): intrinsics in pixels, an optional depth scale and an optional lens; and the note
//! a run prints when a lens is removed from its frames.

use std::path::Path;

use serde::Deserialize;

use super::source;
use crate::geometry::camera::Distortion;
use crate::{Error, Result};

/// `camera.json` in a dataset directory: intrinsics in pixels, optional depth scale,
/// optional lens distortion `[k1, k2, p1, p2, k3]` (see [`Distortion`]).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct CameraJson {
    pub(crate) width: u32,
    pub(crate) height: u32,
    pub(crate) fx: f32,
    pub(crate) fy: f32,
    pub(crate) cx: f32,
    pub(crate) cy: f32,
    pub(crate) depth_scale: Option<f32>,
    pub(crate) distortion: Option<[f64; 5]>,
}

pub(crate) fn read(path: &Path) -> Result<Option<CameraJson>> {
    if !source::present(path) {
        return Ok(None);
    }
    let text = source::read_string(path, crate::io::input::InputKind::Settings)?;
    parse(path, &text).map(Some)
}

/// `camera.json`'s text, checked; `path` names it in errors.
fn parse(path: &Path, text: &str) -> Result<CameraJson> {
    let cam: CameraJson = serde_json::from_str(text).map_err(|e| {
        Error::format(
            path,
            format!(
                "expected {{width, height, fx, fy, cx, cy[, depth_scale][, distortion: \
                 [k1, k2, p1, p2, k3]]}}: {e}"
            ),
        )
    })?;
    let finite = [cam.fx, cam.fy, cam.cx, cam.cy]
        .iter()
        .all(|v| v.is_finite());
    if !finite || cam.fx == 0.0 || cam.fy == 0.0 || cam.width == 0 || cam.height == 0 {
        return Err(Error::format(
            path,
            "width/height must be positive and fx, fy finite and non-zero",
        ));
    }
    if let Some(c) = cam.distortion {
        Distortion::from_coefficients(c).map_err(|why| Error::format(path, why))?;
    }
    Ok(cam)
}

/// The note that says a lens is removed from the frames, and where it came from.
pub(crate) fn lens_note(lens: &Distortion, from: &str) -> String {
    let [k1, k2, p1, p2, k3] = lens.coefficients();
    format!(
        "lens distortion k1 {k1}, k2 {k2}, p1 {p1}, p2 {p2}, k3 {k3} (from {from}) is removed \
         from every frame as it is decoded: the frames are the pinhole camera's"
    )
}
