//! CPU twin of `shaders/fuse_add.wgsl`: appends every valid pixel that no surfel merged
//! with (projective association) or covers (best-candidate association: `fuse_select`
//! found a surfel for it) as a new surfel: world frame, weight `pixel_confidence` (1 for
//! the assignment), radius `surfel_radius`.
//!
//! The GPU appends with an atomic counter, so its order differs from this pixel order;
//! compare maps order-independently. Never writes at or past `params.capacity`: the counter
//! still counts, and the host reports a count above capacity as a capacity error.

use super::{
    back_project, is_valid, pixel_confidence, surfel_radius, surfel_texel, transform_dir,
    transform_point, xyz,
};
use crate::layout::FuseParams;

/// Bindings (as in the shader header; map arrays in the packing of `map::SurfelMap`, each
/// holding at least `capacity` entries):
/// - 0 `params`: `FuseParams` (`t_cam_to_world`, `frame_id`, `capacity`)
/// - 1 `normal_depth`: width x height, camera-frame normal with the vertex's depth in w,
///   zero where invalid (see `vertex_to_normal`)
/// - 2 `color_map`: width x height, RGB 0..255
/// - 3 `assoc`: one key per pixel, non-zero where a surfel merged with (projective) or was
///   chosen by (best candidate) the pixel
/// - 4 `counter` (in/out): surfels in the map (in: before, out: after)
/// - 5 `position_weight` (out): xyz world frame, w = confidence
/// - 6 `normal_frame` (out): normal bits, w = last frame
/// - 7 `color` (out): RGB 0..255, a = radius (metres)
#[allow(clippy::too_many_arguments)]
pub fn fuse_add(
    params: &FuseParams,
    normal_depth: &[[f32; 4]],
    color_map: &[[f32; 4]],
    assoc: &[u64],
    counter: &mut u32,
    position_weight: &mut [[f32; 4]],
    normal_frame: &mut [[u32; 4]],
    color: &mut [[f32; 4]],
) {
    let cam = [params.fx, params.fy, params.cx, params.cy];
    for v in 0..params.height {
        for u in 0..params.width {
            let pix = (v * params.width + u) as usize;
            if assoc[pix] != 0 {
                continue;
            }
            // Valid normal (w = depth > 0) implies a valid vertex.
            let nd = normal_depth[pix];
            if !is_valid(nd) {
                continue;
            }
            let i = *counter;
            *counter += 1;
            if i >= params.capacity {
                continue;
            }
            let q_cam = back_project(cam, [u, v], nd[3]);
            let p = transform_point(&params.t_cam_to_world, q_cam);
            let n = transform_dir(&params.t_cam_to_world, xyz(nd));
            let w = pixel_confidence(cam, [u, v], params.confidence_sigma);
            let r = surfel_radius(params.fx, q_cam, xyz(nd));
            let surfel = surfel_texel(i);
            position_weight[surfel] = [p.x, p.y, p.z, w];
            normal_frame[surfel] = [n.x.to_bits(), n.y.to_bits(), n.z.to_bits(), params.frame_id];
            let c = color_map[pix];
            color[surfel] = [c[0], c[1], c[2], r];
        }
    }
}
