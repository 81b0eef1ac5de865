//! CPU twin of `shaders/fuse_add_portable.wgsl`: [`fuse_add`](super::fuse_add) without
//! 64-bit integers, one pass of two. Pass 0 (`key_pass` 0) writes the new surfels and, with
//! best-candidate association, raises the high (depth) word of each new surfel's pixel in
//! fuse_select_portable's index map of `(low, high)` u32 words; pass 1 sets the pixel's
//! index word where the new surfel's depth word won ([`keep_nearer`]). New surfels' indices
//! exceed every index already in the map, so each pair then equals fuse_add's 64-bit key.
//! Called once per map chunk and pass, every chunk of pass 0 before pass 1.

use super::{
    append_index, back_project, depth_key, keep_nearer, pixel_confidence, surfel_radius,
    transform_dir, transform_point, xyz,
};
use crate::layout::{FuseParams, MapChunk, ASSOCIATION_BEST_CANDIDATE};

/// Arguments: the shader's bindings in `@binding` order, named as there; see the
/// declarations in `shaders/fuse_add_portable.wgsl` for shapes, units and frames;
/// `key_pass` is the kernel's `override KEY_PASS`.
#[allow(clippy::too_many_arguments)]
pub fn fuse_add_portable(
    params: &FuseParams,
    normal_depth: &[[f32; 4]],
    color_map: &[[f32; 4]],
    flags: &[u32],
    offsets: &[u32],
    chunk: &MapChunk,
    position_weight: &mut [[f32; 4]],
    normal_frame: &mut [[u32; 4]],
    color: &mut [[f32; 4]],
    index_map: &mut [u32],
    key_pass: u32,
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
            if key_pass == 0 {
                let surfel = slot as usize;
                position_weight[surfel] = [p.x, p.y, p.z, w];
                normal_frame[surfel] =
                    [n.x.to_bits(), n.y.to_bits(), n.z.to_bits(), params.frame_id];
                let c = color_map[pix];
                color[surfel] = [c[0], c[1], c[2], r];
            }
            if params.association == ASSOCIATION_BEST_CANDIDATE {
                keep_nearer(index_map, pix, depth_key(q_cam.z), i, key_pass);
            }
        }
    }
}
