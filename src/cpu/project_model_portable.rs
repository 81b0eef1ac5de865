//! CPU twin of `shaders/project_model_portable.wgsl`: project_model without 64-bit
//! integers, one pass of two. The map holds [`project_model`](super::project_model)'s
//! 64-bit keys as `(low, high)` u32 words (low = map-wide surfel index, high =
//! [`depth_key`]); pass 0 (`key_pass` 0) over every chunk, then pass 1 over every chunk,
//! leave each pair equal to project_model's key ([`keep_nearer`]).

use super::{
    block_visible, chunk_blocks, decode_corner, depth_key, keep_nearer, project_to_pixel,
    transform_point, xyz,
};
use crate::layout::{MapChunk, ProjectParams, BLOCK_SURFELS};

/// Arguments: the shader's bindings in `@binding` order, named as there; see the
/// declarations in `shaders/project_model_portable.wgsl` for shapes, units and frames;
/// `key_pass` is the kernel's `override KEY_PASS`.
pub fn project_model_portable(
    params: &ProjectParams,
    chunk: &MapChunk,
    block_bounds: &[[u32; 4]],
    position_weight: &[[f32; 4]],
    index_map: &mut [u32],
    key_pass: u32,
) {
    let cam = [params.fx, params.fy, params.cx, params.cy];
    assert_eq!(index_map.len(), 2 * (params.width * params.height) as usize);
    let (blocks, span_end) = chunk_blocks(chunk, params.surfel_count);
    for b in 0..blocks {
        let block = (chunk.base / BLOCK_SURFELS + b) as usize;
        let lo = decode_corner(block_bounds[2 * block]);
        let hi = decode_corner(block_bounds[2 * block + 1]);
        if !block_visible(
            &params.t_world_to_cam,
            cam,
            params.width,
            params.height,
            lo,
            hi,
        ) {
            continue;
        }
        let end = (chunk.base + (b + 1) * BLOCK_SURFELS).min(span_end);
        for i in chunk.base + b * BLOCK_SURFELS..end {
            let p = transform_point(
                &params.t_world_to_cam,
                xyz(position_weight[(i - chunk.base) as usize]),
            );
            if let Some(pix) = project_to_pixel(cam, params.width, params.height, p) {
                keep_nearer(index_map, pix, depth_key(p.z), i, key_pass);
            }
        }
    }
}
