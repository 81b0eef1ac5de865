//! CPU twin of `shaders/block_bounds.wgsl`: recomputes the world-frame box of each block of
//! one map chunk from block `params.block_from` on, the boxes the map-walking kernels cull
//! with ([`super::block_visible`]).
//!
//! A block is [`BLOCK_SURFELS`] consecutive map slots; its box is entries `2b` (min corner)
//! and `2b + 1` (max corner) of `block_boxes`, each coordinate [`ordered_from_f32`]
//! encoded so that `fuse_merge` can grow it with integer atomics. In the shader's shape:
//! per block, [`WORKGROUP_SIZE`] strided boxes halved pairwise (min and max are exact, so
//! the box is the serial one).

use super::binding::{twin, Binding};
use super::{chunk_blocks, xyz};
use crate::layout::{ordered_from_f32, BoundsParams, MapChunk, BLOCK_SURFELS};

/// Threads per block's workgroup (`WORKGROUP_SIZE` in block_bounds.wgsl), a power of two.
pub const WORKGROUP_SIZE: u32 = 64;

twin! {
    /// The boxes of the chunk's blocks from `params.block_from` on: the parameters are the
    /// shader's bindings in `@binding` order, named as there (see the declarations in
    /// `shaders/block_bounds.wgsl` for shapes, units and frames).
    pub fn block_bounds(
        params: &BoundsParams,
        chunk: &MapChunk,
        position_weight: &[[f32; 4]],
        block_boxes: &mut [[u32; 4]],
    ) {
        let (blocks, span_end) = chunk_blocks(chunk, params.surfel_count);
        let first = chunk.base / BLOCK_SURFELS;
        let start = params.block_from.max(first) - first;
        for b in start..blocks {
            let begin = chunk.base + b * BLOCK_SURFELS;
            let end = (begin + BLOCK_SURFELS).min(span_end);
            let start_box = xyz(position_weight[(b * BLOCK_SURFELS) as usize]);
            let mut lo_box = [start_box; WORKGROUP_SIZE as usize];
            let mut hi_box = lo_box;
            for t in 0..WORKGROUP_SIZE {
                let (lo, hi) = (&mut lo_box[t as usize], &mut hi_box[t as usize]);
                for i in (begin + t..end).step_by(WORKGROUP_SIZE as usize) {
                    let p = xyz(position_weight[(i - chunk.base) as usize]);
                    *lo = lo.min(p);
                    *hi = hi.max(p);
                }
            }
            let mut s = WORKGROUP_SIZE as usize / 2;
            while s > 0 {
                for t in 0..s {
                    lo_box[t] = lo_box[t].min(lo_box[t + s]);
                    hi_box[t] = hi_box[t].max(hi_box[t + s]);
                }
                s /= 2;
            }
            let (lo, hi) = (lo_box[0], hi_box[0]);
            let block = (first + b) as usize;
            let enc = |v: glam::Vec3| {
                [
                    ordered_from_f32(v.x),
                    ordered_from_f32(v.y),
                    ordered_from_f32(v.z),
                    0,
                ]
            };
            block_boxes[2 * block] = enc(lo);
            block_boxes[2 * block + 1] = enc(hi);
        }
    }
}

/// Every block's box of a whole map (one chunk): what the backends hold after a refresh,
/// for tests that call a culling twin on a map directly.
pub fn whole_map_bounds(position_weight: &[[f32; 4]]) -> Vec<[u32; 4]> {
    let n = position_weight.len();
    let mut bounds = vec![[0; 4]; 2 * n.div_ceil(BLOCK_SURFELS as usize)];
    block_bounds(&mut [
        Binding::of(&BoundsParams::stale(n, 0)),
        Binding::of(&MapChunk::whole(n)),
        Binding::read(position_weight),
        Binding::write(&mut bounds),
    ]);
    bounds
}
