//! CPU twin of `shaders/compact_scatter.wgsl`: copies every kept surfel `i` to slot
//! `offsets[i]` of the output map arrays, so the survivors end up at the front in their
//! current order (stream compaction).

use super::chunk_blocks;
use crate::layout::{CompactParams, MapChunk};

/// Arguments: the shader's bindings in `@binding` order, named as there; see the
/// declarations in `shaders/compact_scatter.wgsl` for shapes, units and frames.
#[allow(clippy::too_many_arguments)]
pub fn compact_scatter(
    params: &CompactParams,
    flags: &[u32],
    offsets: &[u32],
    chunk: &MapChunk,
    position_weight: &[[f32; 4]],
    normal_frame: &[[u32; 4]],
    color: &[[f32; 4]],
    out_chunk: &MapChunk,
    out_position_weight: &mut [[f32; 4]],
    out_normal_frame: &mut [[u32; 4]],
    out_color: &mut [[f32; 4]],
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
        out_position_weight[dst] = position_weight[src];
        out_normal_frame[dst] = normal_frame[src];
        out_color[dst] = color[src];
    }
}
