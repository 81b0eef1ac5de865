//! CPU twin of `shaders/compact_flags.wgsl`: one keep flag per surfel, the removal rule for
//! unstable surfels (Keller et al. 2013). A surfel with weight below `stable_weight` whose
//! `last_frame` is more than `max_age_frames` frames before `frame_id` is removed (flag 0);
//! every other surfel is kept (flag 1).

use super::binding::twin;
use super::chunk_blocks;
use crate::layout::{CompactParams, MapChunk};

/// True when the surfel stays: it is stable (`weight >= stable_weight`) or was seen within
/// the last `max_age_frames` frames. Mirrors `keep_surfel` in compact_flags.wgsl.
#[inline]
pub fn keep_surfel(params: &CompactParams, weight: f32, last_frame: u32, frame_id: u32) -> bool {
    let unstable = weight < params.stable_weight;
    let old = last_frame < frame_id && frame_id - last_frame > params.max_age_frames;
    !(unstable && old)
}

twin! {
    /// One keep flag per surfel of the chunk: the parameters are the shader's bindings in
    /// `@binding` order, named as there (see the declarations in `shaders/compact_flags.wgsl`
    /// for shapes, units and frames).
    pub fn compact_flags(
        params: &CompactParams,
        chunk: &MapChunk,
        position_weight: &[[f32; 4]],
        normal_frame: &[[u32; 4]],
        flags: &mut [u32],
    ) {
        let (_, end) = chunk_blocks(chunk, params.surfel_count);
        for i in chunk.base..end {
            let surfel = (i - chunk.base) as usize;
            let weight = position_weight[surfel][3];
            let last_frame = normal_frame[surfel][3];
            flags[i as usize] = keep_surfel(params, weight, last_frame, params.frame_id) as u32;
        }
    }
}
