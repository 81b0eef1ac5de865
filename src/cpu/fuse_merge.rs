//! CPU twin of `shaders/fuse_merge.wgsl`: merges the new frame into the surfels it sees.
//!
//! For every surfel (world frame): move it into the tracked camera and project it. Filter
//! pass 1: it lands inside the image with `z > 0` on a pixel with a valid `normal_depth`
//! texel (a valid normal implies a valid vertex). Filter pass 2 depends on
//! `params.association`:
//! - [`ASSOCIATION_PROJECTIVE`] (the assignment): the frame's point at that pixel (rebuilt
//!   with `back_project`), moved to the world, is closer than `dist_threshold_m`, and the
//!   angle between the normals is below the threshold (`cos > cos_normal_threshold`); the
//!   pixel is then marked in `assoc` so `fuse_add` does not add it again. Several surfels
//!   may merge with one pixel (as in the assignment).
//! - [`ASSOCIATION_BEST_CANDIDATE`]: `fuse_select` already chose one surfel per pixel
//!   (gates included); the surfel merges only when its pixel chose it.
//!
//! Associated surfels take the confidence-weighted average `(w x + c x_new) / (w + c)` of
//! position, colour, normal (renormalised) and radius, weight `w + c` and
//! `last_frame = frame_id`, where `c = pixel_confidence(...)` (1 with
//! `confidence_sigma = 0`: the assignment's counts) and the new radius is `surfel_radius`
//! of the measurement.

use glam::Vec3;

use super::{
    back_project, is_valid, pixel_confidence, project_to_texel, surfel_radius, surfel_texel,
    transform_dir, transform_point, xyz,
};
use crate::layout::{FuseParams, ASSOCIATION_BEST_CANDIDATE, ASSOCIATION_PROJECTIVE};

/// `v / |v|`, or zero when `|v|` is zero. Mirrors `normalize_or_zero` in fuse_merge.wgsl.
#[inline]
fn normalize_or_zero(v: Vec3) -> Vec3 {
    v.normalize_or_zero()
}

/// The unit normal stored as bits in `normal_frame`'s xyz (`bitcast<vec3<f32>>`).
#[inline]
fn normal_of(nf: [u32; 4]) -> Vec3 {
    Vec3::new(
        f32::from_bits(nf[0]),
        f32::from_bits(nf[1]),
        f32::from_bits(nf[2]),
    )
}

/// Bindings (as in the shader header; map arrays in the packing of `map::SurfelMap`):
/// - 0 `params`: `FuseParams` (tracked poses, intrinsics, `surfel_count`, thresholds)
/// - 1 `normal_depth`: width x height, camera-frame normal with the vertex's depth in w,
///   zero where invalid (see `vertex_to_normal`)
/// - 2 `color_map`: width x height, RGB 0..255
/// - 3 `position_weight` (in/out): xyz world frame (metres), w = confidence
/// - 4 `normal_frame` (in/out): bits of the unit normal (world frame), w = last frame
/// - 5 `color` (in/out): RGB 0..255, a = radius (metres)
/// - 6 `assoc` (in/out): one key per pixel, cleared to 0 by the caller; projective
///   association marks merged pixels (max with 1), best-candidate association reads the
///   choice of `fuse_select` (the chosen surfel's index in the low 32 bits)
pub fn fuse_merge(
    params: &FuseParams,
    normal_depth: &[[f32; 4]],
    color_map: &[[f32; 4]],
    position_weight: &mut [[f32; 4]],
    normal_frame: &mut [[u32; 4]],
    color: &mut [[f32; 4]],
    assoc: &mut [u64],
) {
    let cam = [params.fx, params.fy, params.cx, params.cy];
    for i in 0..params.surfel_count {
        let surfel = surfel_texel(i);
        let pw = position_weight[surfel];
        let p_world = xyz(pw);
        let p_cam = transform_point(&params.t_world_to_cam, p_world);
        let Some(texel) = project_to_texel(cam, params.width, params.height, p_cam) else {
            continue;
        };
        let pix = (texel[1] * params.width + texel[0]) as usize;
        // Best candidate: only the pixel that chose this surfel (fuse_select tested the
        // gates, on a valid pixel), before any other load.
        if params.association == ASSOCIATION_BEST_CANDIDATE {
            let key = assoc[pix];
            if key == 0 || key as u32 != i {
                continue;
            }
        }
        // Valid normal (w = depth > 0) implies a valid vertex.
        let nd = normal_depth[pix];
        if !is_valid(nd) {
            continue;
        }
        let q_cam = back_project(cam, texel, nd[3]);
        let q_world = transform_point(&params.t_cam_to_world, q_cam);
        let nq_world = transform_dir(&params.t_cam_to_world, xyz(nd));
        let n_old = normal_of(normal_frame[surfel]);
        if params.association == ASSOCIATION_PROJECTIVE
            && ((q_world - p_world).length() >= params.dist_threshold_m
                || n_old.dot(nq_world) <= params.cos_normal_threshold)
        {
            continue;
        }
        let w = pw[3];
        let wq = pixel_confidence(cam, texel, params.confidence_sigma);
        let inv = 1.0 / (w + wq);
        let p = (p_world * w + q_world * wq) * inv;
        let n = normalize_or_zero((n_old * w + nq_world * wq) * inv);
        let c = color[surfel];
        let cq = color_map[pix];
        let r = (c[3] * w + surfel_radius(params.fx, q_cam, xyz(nd)) * wq) * inv;
        position_weight[surfel] = [p.x, p.y, p.z, w + wq];
        normal_frame[surfel] = [n.x.to_bits(), n.y.to_bits(), n.z.to_bits(), params.frame_id];
        let c = (xyz(c) * w + xyz(cq) * wq) * inv;
        color[surfel] = [c.x, c.y, c.z, r];
        if params.association == ASSOCIATION_PROJECTIVE {
            assoc[pix] = assoc[pix].max(1);
        }
    }
}
