//! The two-frame ICP experiment: align one frame's points to another's by the same
//! projective point-to-plane ICP the tracker uses, starting from identity.
//!
//! The source frame is fused into an empty map at the identity pose (so the "world" is the
//! source camera), then the target frame is tracked against it. The result maps source
//! camera coordinates into target camera coordinates (`t_source_to_target`); with ground
//! truth it is compared with `inv(T_target_cam_to_world) * T_source_cam_to_world`.
//!
//! The target may come before the source in the sequence: the pipeline numbers the two
//! frames 0 and 1, in the order they are fused (it takes frames in increasing order only).

use glam::DMat4;
use serde::Serialize;

use crate::dataset::Sequence;
use crate::slam::backend::{Backend, Inspect};
use crate::slam::params::{PoseSource, ValidParams};
use crate::slam::pipeline::{Slam, TrackStatus};
use crate::slam::solve::IcpIteration;
use crate::tools::run::packed_rgba;
use crate::{geometry::se3, Result};

/// Outcome of [`align_frames`].
#[derive(Debug, Clone, Serialize)]
pub struct TwoFrameResult {
    pub source: usize,
    pub target: usize,
    pub status: TrackStatus,
    pub iterations: Vec<IcpIteration>,
    /// Source camera to target camera (column-major 4x4).
    pub t_source_to_target: [[f64; 4]; 4],
    /// Rotation error against ground truth, degrees.
    pub rotation_error_deg: Option<f64>,
    /// Translation error against ground truth, metres.
    pub translation_error_m: Option<f64>,
    /// Ground-truth motion between the frames: rotation (deg) and translation (m).
    pub gt_motion: Option<(f64, f64)>,
    /// The source frame's vertex map (source camera frame, metres, `w = 0` invalid).
    #[serde(skip)]
    pub source_points: Vec<[f32; 4]>,
    /// The target frame's vertex map (target camera frame).
    #[serde(skip)]
    pub target_points: Vec<[f32; 4]>,
}

/// Aligns frame `target` to frame `source` (either may come first) with `params` (its
/// `poses` is ignored: tracked).
pub fn align_frames<B: Backend + Inspect>(
    backend: B,
    seq: &Sequence,
    source: usize,
    target: usize,
    params: ValidParams,
) -> Result<TwoFrameResult> {
    let mut slam = Slam::for_sequence(backend, seq, params.with_poses(PoseSource::Track))?;
    let mut source_points = Vec::new();
    for (fused, (i, gt)) in [(source, Some(&DMat4::IDENTITY)), (target, None)]
        .into_iter()
        .enumerate()
    {
        let frame = seq.load(i)?;
        if frame.valid_depth_pixels() == 0 {
            return Err(crate::Error::format(
                &seq.frames[i].depth_path,
                "depth image has no valid pixel",
            ));
        }
        let rgba = packed_rgba(&frame);
        let report = slam.process(fused as u32, &frame.depth, &rgba, gt)?;
        if source_points.is_empty() {
            source_points = slam.backend.download_frame()?.vertex;
        }
        if i == target || source == target {
            let target_points = slam.backend.download_frame()?.vertex;
            let t_source_to_target = se3::inverse_rigid(&report.t_cam_to_world);
            let gt_rel = match (
                seq.frames[source].gt_cam_to_world,
                seq.frames[target].gt_cam_to_world,
            ) {
                (Some(s), Some(t)) => Some(se3::inverse_rigid(&t) * s),
                _ => None,
            };
            let err = gt_rel.map(|g| se3::inverse_rigid(&g) * t_source_to_target);
            return Ok(TwoFrameResult {
                source,
                target,
                status: report.status,
                iterations: report.iterations,
                t_source_to_target: t_source_to_target.to_cols_array_2d(),
                rotation_error_deg: err.map(|e| se3::rotation_angle(&e).to_degrees()),
                translation_error_m: err.map(|e| se3::translation_norm(&e)),
                gt_motion: gt_rel.map(|g| {
                    (
                        se3::rotation_angle(&g).to_degrees(),
                        se3::translation_norm(&g),
                    )
                }),
                source_points,
                target_points,
            });
        }
    }
    unreachable!("the loop returns at the target frame")
}

/// Writes `result.json` and the before/after overlays (`icp_before.png`, `icp_after.png`:
/// source orange, target blue, seen from the target camera) into `out` (created when
/// missing). Returns the three paths in that order.
pub fn write_outputs(
    out: &std::path::Path,
    r: &TwoFrameResult,
    seq: &Sequence,
) -> Result<[std::path::PathBuf; 3]> {
    use crate::render::outputs::{write_icp_overlays, OverlayViewpoint};
    std::fs::create_dir_all(out).map_err(|e| crate::Error::write(out, e))?;
    let result = out.join("result.json");
    crate::tools::run::write_json(&result, r)?;
    let [before, after] = write_icp_overlays(
        out,
        &r.source_points,
        &r.target_points,
        &DMat4::IDENTITY,
        &DMat4::from_cols_array_2d(&r.t_source_to_target),
        OverlayViewpoint::Camera {
            fy_negative: seq.intrinsics.fy < 0.0,
        },
    )?;
    Ok([result, before, after])
}
