//! Replica as NICE-SLAM ships it (`Replica/room0/...`): `results/frameNNNNNN.jpg`,
//! `results/depthNNNNNN.png` (16-bit, 6553.5 per metre), `traj.txt` (one 4x4
//! camera-to-world matrix per frame, 16 numbers a line, row-major, in frame order) and
//! `cam_params.json` (`{"camera": {"w", "h", "fx", "fy", "cx", "cy", "scale"}}`) beside the
//! sequence folder (NICE-SLAM keeps one for all scenes in `Replica/`) or inside it.
//! A frame's stamp is its number.

use std::path::{Path, PathBuf};

use serde::Deserialize;

use super::matrix_file::{parse_numbers, pose_from_row_major};
use super::numbered::{self, Pattern};
use super::{FrameConventions, FrameRecord, Listing};
use crate::geometry::camera::Intrinsics;
use crate::{Error, Result};

/// `results/depthNNNNNN.png`.
pub const DEPTH: Pattern = Pattern::new("depth", ".png");
/// `results/frameNNNNNN.jpg`.
pub const COLOR: Pattern = Pattern::new("frame", ".jpg");
/// NICE-SLAM's depth scale for Replica (65535 / 10 m), when `cam_params.json` has none.
pub const DEPTH_SCALE: f32 = 6553.5;
/// The intrinsics file's name.
pub const CAM_PARAMS: &str = "cam_params.json";

#[derive(Debug, Deserialize)]
struct CamParamsFile {
    camera: CamParams,
}

#[derive(Debug, Deserialize)]
struct CamParams {
    w: u32,
    h: u32,
    fx: f32,
    fy: f32,
    cx: f32,
    cy: f32,
    scale: Option<f32>,
}

/// Reads `cam_params.json`: intrinsics and the depth scale, if it gives one.
fn read_cam_params(path: &Path) -> Result<(Intrinsics, Option<f32>)> {
    let text = super::source::read_string(path, crate::io::input::InputKind::Settings)?;
    let c: CamParamsFile = serde_json::from_str(&text).map_err(|e| {
        Error::format(
            path,
            format!("expected {{\"camera\": {{w, h, fx, fy, cx, cy[, scale]}}}}: {e}"),
        )
    })?;
    let c = c.camera;
    let floats = [c.fx, c.fy, c.cx, c.cy];
    let finite = floats.iter().all(|v| v.is_finite());
    if !finite || c.fx == 0.0 || c.fy == 0.0 || c.w == 0 || c.h == 0 {
        return Err(Error::format(
            path,
            "w/h must be positive and fx, fy finite and non-zero",
        ));
    }
    super::checks::pinhole_in_bounds(floats, &path.display().to_string())?;
    Ok((Intrinsics::from_floats(floats, (c.w, c.h)), c.scale))
}

/// Reads `traj.txt`: one pose per data line, 16 numbers each; an error naming
/// `traj.txt:line` for another count.
fn read_traj(path: &Path) -> Result<Vec<Option<glam::DMat4>>> {
    let text = super::source::read_string(path, crate::io::input::InputKind::List)?;
    let mut out = Vec::new();
    for (lineno, line) in crate::io::text::data_lines(&text) {
        let v = parse_numbers(path, line)?;
        let pose = pose_from_row_major(path, &v).map_err(|e| match e {
            Error::Format { what, .. } => Error::parse(path, lineno, what),
            other => other,
        })?;
        out.push(pose);
    }
    Ok(out)
}

/// Lists the frames of `root` with their poses from `traj.txt` and reads the intrinsics.
pub fn list(root: &Path) -> Result<Listing> {
    let results = root.join("results");
    let depth = numbered::list(&results, DEPTH)?;
    let color = numbered::list(&results, COLOR)?;
    let pairs = numbered::pair(&depth, &color, DEPTH, COLOR)?;
    let mut notes = Vec::new();

    let traj_path = root.join("traj.txt");
    let traj = if super::source::present(&traj_path) {
        let t = read_traj(&traj_path)?;
        if t.len() != pairs.len() {
            return Err(Error::format(
                &traj_path,
                format!(
                    "has {} poses but results/ has {} frames (one line per frame, in frame \
                     order)",
                    t.len(),
                    pairs.len()
                ),
            ));
        }
        t
    } else {
        notes.push(format!("no {}: no ground truth", traj_path.display()));
        vec![None; pairs.len()]
    };
    let frames: Vec<FrameRecord> = pairs
        .into_iter()
        .zip(traj)
        .map(|((n, rgb_path, depth_path), gt)| FrameRecord {
            timestamp: n as f64,
            rgb_path,
            depth_path,
            gt_cam_to_world: gt,
        })
        .collect();
    let first = frames
        .first()
        .ok_or_else(|| Error::format(&results, "no frames"))?;
    let size = super::frame::image_size(&first.depth_path)?;

    let candidates: Vec<PathBuf> = [
        Some(root.join(CAM_PARAMS)),
        root.parent().map(|p| p.join(CAM_PARAMS)),
    ]
    .into_iter()
    .flatten()
    .collect();
    let (intrinsics, depth_scale) = match candidates.iter().find(|p| super::source::present(p)) {
        Some(p) => {
            let (k, scale) = read_cam_params(p)?;
            (Some(k), scale)
        }
        None => (None, None),
    };
    Ok(Listing {
        frames,
        gt_file: None,
        intrinsics,
        no_intrinsics: format!(
            "no {CAM_PARAMS} in {} or beside it: Replica's intrinsics are needed (NICE-SLAM's \
             are 600,600,599.5,339.5)",
            root.display()
        ),
        image_size: Some(size),
        depth_scale: Some(depth_scale.unwrap_or(DEPTH_SCALE)),
        conventions: FrameConventions::default(),
        notes,
    })
}
