//! CPU twin of `shaders/compact_scatter.wgsl`: copies every kept surfel `i` to slot
//! `offsets[i]` of the output map arrays, so the survivors end up at the front in their
//! current order (stream compaction).

use super::surfel_texel;
use crate::layout::CompactParams;

/// Bindings (as in the shader header; map arrays in the packing of `map::SurfelMap`, the
/// outputs holding at least as many entries as kept surfels):
/// - 0 `params`: `CompactParams` (`surfel_count`)
/// - 1 `flags`: 1 keep / 0 remove (`compact_flags`)
/// - 2 `offsets`: exclusive prefix sum of `flags` (`prefix_sum`)
/// - 3 `position_weight`, 4 `normal_frame`, 5 `color`: the map
/// - 6 `out_position_weight`, 7 `out_normal_frame`, 8 `out_color` (out): the compacted map
#[allow(clippy::too_many_arguments)]
pub fn compact_scatter(
    params: &CompactParams,
    flags: &[u32],
    offsets: &[u32],
    position_weight: &[[f32; 4]],
    normal_frame: &[[u32; 4]],
    color: &[[f32; 4]],
    out_position_weight: &mut [[f32; 4]],
    out_normal_frame: &mut [[u32; 4]],
    out_color: &mut [[f32; 4]],
) {
    for i in 0..params.surfel_count {
        if flags[i as usize] == 0 {
            continue;
        }
        let src = surfel_texel(i);
        let dst = surfel_texel(offsets[i as usize]);
        out_position_weight[dst] = position_weight[src];
        out_normal_frame[dst] = normal_frame[src];
        out_color[dst] = color[src];
    }
}
