//! CPU twin of `shaders/fuse_flags.wgsl`: one flag per pixel, 1 where the pixel becomes a
//! new surfel (a valid measurement no surfel merged with or covers), stored at the pixel's
//! `append_index`. With `prefix_sum` over the flags it gives `fuse_add` each new surfel's
//! slot in append order (`layout::APPEND_TILE_PX`), on both backends, so the GPU map has
//! the CPU map's order and two runs write the same bytes.

use super::{append_index, is_valid};
use crate::layout::FuseParams;

/// Bindings (as in the shader header):
/// - 0 `params`: `FuseParams` (width, height)
/// - 1 `normal_depth`: width x height, camera-frame normal with the depth in w, zero
///   where invalid
/// - 2 `assoc`: one key per pixel, non-zero where a surfel merged with or was chosen by the
///   pixel
/// - 3 `flags` (out): 1 new surfel / 0 not, `layout::append_slots(width, height)` entries
///   indexed by `append_index` (the holes, no pixel's, are never written: they stay 0)
pub fn fuse_flags(
    params: &FuseParams,
    normal_depth: &[[f32; 4]],
    assoc: &[u64],
    flags: &mut [u32],
) {
    // The shader's grid-stride loop as one thread whose stride is 1 x 1: every pixel once,
    // row by row.
    for v in 0..params.height {
        for u in 0..params.width {
            let pix = (v * params.width + u) as usize;
            // Valid normal (w = depth > 0) implies a valid vertex.
            let new_surfel = assoc[pix] == 0 && is_valid(normal_depth[pix]);
            flags[append_index([u, v])] = new_surfel as u32;
        }
    }
}
