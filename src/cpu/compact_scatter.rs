//! CPU twin of `shaders/compact_scatter.wgsl`: copies every kept surfel `i` to slot
//! `offsets[i]` of the output map arrays, so the survivors end up at the front in their
//! current order (stream compaction).

use super::chunk_blocks;
use crate::layout::{CompactParams, MapChunk};

/// Bindings (as in the shader header; map arrays in the packing of `map::SurfelMap`, the
/// outputs holding at least as many entries as kept surfels):
/// - 0 `params`: `CompactParams` (`surfel_count`)
/// - 1 `flags`: 1 keep / 0 remove (`compact_flags`)
/// - 2 `offsets`: exclusive prefix sum of `flags` (`prefix_sum`)
/// - 3 `chunk`, 4 `position_weight`, 5 `normal_frame`, 6 `color`: one chunk of the map
/// - 7 `out_chunk`, 8 `out_position_weight`, 9 `out_normal_frame`, 10 `out_color` (out):
///   one chunk of the compacted map; only surfels whose new slot it holds are written
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
