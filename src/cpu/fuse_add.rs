//! CPU twin of `shaders/fuse_add.wgsl`: appends every pixel `fuse_flags` flagged (a valid
//! measurement no surfel merged with or covers) as a new surfel at slot `surfel_count +
//! offsets[append_index(pixel)]` (`prefix_sum` of the flags: append order on both
//! backends, see `layout::APPEND_TILE_PX`): world frame,
//! weight `pixel_confidence` (1 for the assignment), radius `surfel_radius`. Never writes
//! at or past `params.capacity` (the host grows the map first so that every pixel fits).
//! Called once per map chunk: each call writes the new surfels whose slots the chunk holds.

use super::{
    append_index, back_project, pack_depth_index, pixel_confidence, surfel_radius, transform_dir,
    transform_point, xyz,
};
use crate::layout::{FuseParams, MapChunk, ASSOCIATION_BEST_CANDIDATE};

/// Bindings (as in the shader header; map arrays in the packing of `map::SurfelMap`, the
/// chunk's `slots` entries each):
/// - 0 `params`: `FuseParams` (`t_cam_to_world`, `surfel_count`, `frame_id`, `capacity`)
/// - 1 `normal_depth`: width x height, camera-frame normal with the vertex's depth in w,
///   zero where invalid (see `vertex_to_normal`)
/// - 2 `color_map`: width x height, RGB 0..255
/// - 3 `flags`: 1 where the pixel becomes a new surfel (`fuse_flags`), at the pixel's
///   `append_index`
/// - 4 `offsets`: exclusive prefix sum of `flags` (`prefix_sum`)
/// - 5 `chunk`: the chunk's first map-wide index and slots
/// - 6 `position_weight` (out): xyz world frame, w = confidence
/// - 7 `normal_frame` (out): normal bits, w = last frame
/// - 8 `color` (out): RGB 0..255, a = radius (metres)
/// - 9 `index_map` (in/out): with best-candidate association, the index map `fuse_select`
///   began; each new surfel competes for its own pixel with `pack_depth_index(z_cam,
///   map-wide index)`, as `project_model`'s key (left alone otherwise)
#[allow(clippy::too_many_arguments)]
pub fn fuse_add(
    params: &FuseParams,
    normal_depth: &[[f32; 4]],
    color_map: &[[f32; 4]],
    flags: &[u32],
    offsets: &[u32],
    chunk: &MapChunk,
    position_weight: &mut [[f32; 4]],
    normal_frame: &mut [[u32; 4]],
    color: &mut [[f32; 4]],
    index_map: &mut [u64],
) {
    let cam = [params.fx, params.fy, params.cx, params.cy];
    for v in 0..params.height {
        for u in 0..params.width {
            let pix = (v * params.width + u) as usize;
            let a = append_index([u, v]);
            if flags[a] == 0 {
                continue;
            }
            let nd = normal_depth[pix];
            let i = params.surfel_count + offsets[a];
            // i - chunk.base wraps to a huge value below the chunk: one test for both ends.
            let slot = i.wrapping_sub(chunk.base);
            if i >= params.capacity || slot >= chunk.slots {
                continue;
            }
            let q_cam = back_project(cam, [u, v], nd[3]);
            let p = transform_point(&params.t_cam_to_world, q_cam);
            let n = transform_dir(&params.t_cam_to_world, xyz(nd));
            let w = pixel_confidence(cam, [u, v], params.confidence_sigma);
            let r = surfel_radius(params.fx, q_cam, xyz(nd));
            let surfel = slot as usize;
            position_weight[surfel] = [p.x, p.y, p.z, w];
            normal_frame[surfel] = [n.x.to_bits(), n.y.to_bits(), n.z.to_bits(), params.frame_id];
            let c = color_map[pix];
            color[surfel] = [c[0], c[1], c[2], r];
            if params.association == ASSOCIATION_BEST_CANDIDATE {
                index_map[pix] = index_map[pix].max(pack_depth_index(q_cam.z, i));
            }
        }
    }
}
