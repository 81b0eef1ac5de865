//! CPU twin of `shaders/compact_scatter.wgsl`: copies one surfel array of every kept surfel
//! `i` to slot `offsets[i]` of the output map array, so the survivors end up at the front
//! in their current order (stream compaction). Called once per surfel array, as the kernel is
//! dispatched.

use super::binding::twin;
use super::chunk_blocks;
use crate::layout::{CompactParams, MapChunk};

twin! {
    /// Copies the chunk's kept surfels' `surfel_array` to their slots of `out_surfel_array`:
    /// the parameters are the shader's bindings in `@binding` order, named as there (see the
    /// declarations in `shaders/compact_scatter.wgsl` for shapes, units and frames). The arrays
    /// are read as `[u32; 4]` bits, as the kernel reads them.
    pub fn compact_scatter(
        params: &CompactParams,
        flags: &[u32],
        offsets: &[u32],
        chunk: &MapChunk,
        surfel_array: &[[u32; 4]],
        out_chunk: &MapChunk,
        out_surfel_array: &mut [[u32; 4]],
    ) {
        let (_, end) = chunk_blocks(chunk, params.surfel_count);
        for i in chunk.base..end {
            // offsets[i] - out_chunk.base wraps to a huge value below the output chunk.
            let dst = offsets[i as usize].wrapping_sub(out_chunk.base);
            if flags[i as usize] == 0 || dst >= out_chunk.slots {
                continue;
            }
            let src = (i - chunk.base) as usize;
            let dst = dst as usize;
            out_surfel_array[dst] = surfel_array[src];
        }
    }
}
