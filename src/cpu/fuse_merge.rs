//! CPU twin of `shaders/fuse_merge.wgsl`: merges the new frame into the surfels it sees.
//!
//! For every surfel (world frame): move it into the tracked camera and project it. Filter
//! pass 1: it lands inside the image with `z > 0` on a pixel with a valid vertex and
//! normal. Filter pass 2: the frame's point at that pixel, moved to the world, is closer
//! than `dist_threshold_m`, and the angle between the normals is below the threshold
//! (`cos > cos_normal_threshold`). Associated surfels take the weighted average
//! `(w x + 1 x_new) / (w + 1)` of position, colour and normal (normal renormalised), weight
//! `w + 1` and `last_frame = frame_id`; the pixel is marked in `assoc` so `fuse_add` does
//! not add it again. Several surfels may merge with one pixel (as in the assignment).

use super::{is_valid, project_to_pixel, transform_dir, transform_point, xyz};
use crate::layout::FuseParams;

/// Bindings: 0 `params`, 1 `vertex_map` and 2 `normal_map` (camera frame), 3 `color_map`,
/// 4 `positions`, 5 `normals`, 6 `colors`, 7 `weights`, 8 `last_frame` (the map, in/out),
/// 9 `assoc` (out, one flag per pixel, cleared to 0 by the caller).
#[allow(clippy::too_many_arguments)]
pub fn fuse_merge(
    params: &FuseParams,
    vertex_map: &[[f32; 4]],
    normal_map: &[[f32; 4]],
    color_map: &[[f32; 4]],
    positions: &mut [[f32; 4]],
    normals: &mut [[f32; 4]],
    colors: &mut [[f32; 4]],
    weights: &mut [f32],
    last_frame: &mut [u32],
    assoc: &mut [u32],
) {
    let cam = [params.fx, params.fy, params.cx, params.cy];
    for i in 0..params.surfel_count as usize {
        let p_world = xyz(positions[i]);
        let p_cam = transform_point(&params.t_world_to_cam, p_world);
        let Some(pix) = project_to_pixel(cam, params.width, params.height, p_cam) else {
            continue;
        };
        if !is_valid(vertex_map[pix]) || !is_valid(normal_map[pix]) {
            continue;
        }
        let q_world = transform_point(&params.t_cam_to_world, xyz(vertex_map[pix]));
        let nq_world = transform_dir(&params.t_cam_to_world, xyz(normal_map[pix]));
        let n_old = xyz(normals[i]);
        if (q_world - p_world).length() >= params.dist_threshold_m
            || n_old.dot(nq_world) <= params.cos_normal_threshold
        {
            continue;
        }
        let w = weights[i];
        let inv = 1.0 / (w + 1.0);
        let p = (p_world * w + q_world) * inv;
        let n = ((n_old * w + nq_world) * inv).normalize_or_zero();
        let c = colors[i];
        let cq = color_map[pix];
        positions[i] = [p.x, p.y, p.z, 1.0];
        normals[i] = [n.x, n.y, n.z, 0.0];
        colors[i] = [
            (c[0] * w + cq[0]) * inv,
            (c[1] * w + cq[1]) * inv,
            (c[2] * w + cq[2]) * inv,
            255.0,
        ];
        weights[i] = w + 1.0;
        last_frame[i] = params.frame_id;
        assoc[pix] = 1;
    }
}
