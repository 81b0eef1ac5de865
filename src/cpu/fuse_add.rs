//! CPU twin of `shaders/fuse_add.wgsl`: appends every valid pixel that no surfel merged
//! with as a new surfel (world frame, weight 1).
//!
//! The GPU appends with an atomic counter, so its order differs from this pixel order;
//! compare maps order-independently. Never writes at or past `params.capacity`: the counter
//! still counts, and the host reports a count above capacity as a capacity error.

use super::{is_valid, transform_dir, transform_point, xyz};
use crate::layout::FuseParams;

/// Bindings: 0 `params`, 1 `vertex_map`, 2 `normal_map`, 3 `color_map`, 4 `assoc`,
/// 5 `counter` (surfels in the map; in/out), 6 `positions`, 7 `normals`, 8 `colors`,
/// 9 `weights`, 10 `last_frame`. Map arrays must hold `capacity` entries.
#[allow(clippy::too_many_arguments)]
pub fn fuse_add(
    params: &FuseParams,
    vertex_map: &[[f32; 4]],
    normal_map: &[[f32; 4]],
    color_map: &[[f32; 4]],
    assoc: &[u32],
    counter: &mut u32,
    positions: &mut [[f32; 4]],
    normals: &mut [[f32; 4]],
    colors: &mut [[f32; 4]],
    weights: &mut [f32],
    last_frame: &mut [u32],
) {
    let n = (params.width * params.height) as usize;
    for pix in 0..n {
        if assoc[pix] != 0 || !is_valid(vertex_map[pix]) || !is_valid(normal_map[pix]) {
            continue;
        }
        let i = *counter;
        *counter += 1;
        if i >= params.capacity {
            continue;
        }
        let i = i as usize;
        let p = transform_point(&params.t_cam_to_world, xyz(vertex_map[pix]));
        let nn = transform_dir(&params.t_cam_to_world, xyz(normal_map[pix]));
        positions[i] = [p.x, p.y, p.z, 1.0];
        normals[i] = [nn.x, nn.y, nn.z, 0.0];
        colors[i] = color_map[pix];
        weights[i] = 1.0;
        last_frame[i] = params.frame_id;
    }
}
