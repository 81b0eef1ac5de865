//! CPU twin of `shaders/block_bounds.wgsl`: recomputes the world-frame box of each block of
//! one map chunk from block `params.block_from` on, the boxes the map-walking kernels cull
//! with ([`super::block_visible`]).
//!
//! A block is [`BLOCK_SURFELS`] consecutive map slots; its box is entries `2b` (min corner)
//! and `2b + 1` (max corner) of `block_bounds`, each coordinate [`ordered_from_f32`]
//! encoded so that `fuse_merge` can grow it with integer atomics.

use super::{chunk_blocks, xyz};
use crate::layout::{ordered_from_f32, BoundsParams, MapChunk, BLOCK_SURFELS};

/// Arguments: the shader's bindings in `@binding` order, named as there; see the
/// declarations in `shaders/block_bounds.wgsl` for shapes, units and frames.
pub fn block_bounds(
    params: &BoundsParams,
    chunk: &MapChunk,
    position_weight: &[[f32; 4]],
    block_bounds: &mut [[u32; 4]],
) {
    let (blocks, span_end) = chunk_blocks(chunk, params.surfel_count);
    let first = chunk.base / BLOCK_SURFELS;
    let start = params.block_from.max(first) - first;
    for b in start..blocks {
        let end = (chunk.base + (b + 1) * BLOCK_SURFELS).min(span_end);
        let mut lo = xyz(position_weight[(b * BLOCK_SURFELS) as usize]);
        let mut hi = lo;
        for i in chunk.base + b * BLOCK_SURFELS + 1..end {
            let p = xyz(position_weight[(i - chunk.base) as usize]);
            lo = lo.min(p);
            hi = hi.max(p);
        }
        let block = (first + b) as usize;
        let enc = |v: glam::Vec3| {
            [
                ordered_from_f32(v.x),
                ordered_from_f32(v.y),
                ordered_from_f32(v.z),
                0,
            ]
        };
        block_bounds[2 * block] = enc(lo);
        block_bounds[2 * block + 1] = enc(hi);
    }
}

/// Every block's box of a whole map (one chunk): what the backends hold after a refresh,
/// for tests that call a culling twin on a map directly.
pub fn whole_map_bounds(position_weight: &[[f32; 4]]) -> Vec<[u32; 4]> {
    let n = position_weight.len();
    let mut bounds = vec![[0; 4]; 2 * n.div_ceil(BLOCK_SURFELS as usize)];
    block_bounds(
        &BoundsParams::stale(n, 0),
        &MapChunk::whole(n),
        position_weight,
        &mut bounds,
    );
    bounds
}
