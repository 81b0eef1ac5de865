//! CPU twin of `shaders/fuse_prune.wgsl`: duplicate removal of best-candidate fusion
//! (robust profile), after `fuse_merge_chosen`. A surfel this frame did not refresh
//! retires (weight 0, last frame 0, which the unstable-surfel removal drops at its next run
//! after frame `max_age_frames`) when the pixel it projects to chose another surfel that
//! this frame refreshed, lies within `prune_radius_scale` times the larger of their radii,
//! faces the same way ([`PRUNE_COS_NORMAL`]) and is at least as confident: a layered copy
//! of the surface the chosen surfel now stands for (Keller et al. 2013 merge such surfels).
//! Without it, noisy depth leaves copies that different pixels keep refreshing, and the
//! camera sees a denser map on every revisit (see `ROBUST_PRUNE_RADIUS_SCALE`). Called once
//! per map chunk; a chosen surfel in another chunk is left alone.

use super::{
    block_visible, chunk_blocks, decode_corner, normal_of, project_to_texel, transform_point, xyz,
};
use crate::layout::{FuseParams, MapChunk, BLOCK_SURFELS};

/// Cosine of the largest angle between the normals of a pruned surfel and the chosen one:
/// 45 degrees (Keller et al. 2013's merge of similar surfels). Mirrors `PRUNE_COS_NORMAL`
/// in the shader.
pub const PRUNE_COS_NORMAL: f32 = std::f32::consts::FRAC_1_SQRT_2;

/// Bindings (as in the shader header; map arrays in the packing of `map::SurfelMap`):
/// - 0 `params`: `FuseParams` (tracked pose, intrinsics, `surfel_count`, `frame_id`,
///   `prune_radius_scale`)
/// - 1 `chunk`: the chunk's first map-wide index and slots
/// - 2 `block_bounds`: per block, min (`2b`) and max (`2b + 1`) corner, ordered-encoded
/// - 3 `position_weight` (in/out): the chunk's surfels, xyz world frame (metres), w =
///   confidence
/// - 4 `normal_frame` (in/out): bits of the unit normal (world frame), w = last frame
/// - 5 `color`: RGB 0..255, a = radius (metres)
/// - 6 `assoc`: `fuse_select`'s key per pixel (low 32 bits: the chosen map-wide index; 0 =
///   no choice)
#[allow(clippy::too_many_arguments)] // the shader's seven bindings, in order
pub fn fuse_prune(
    params: &FuseParams,
    chunk: &MapChunk,
    block_bounds: &[[u32; 4]],
    position_weight: &mut [[f32; 4]],
    normal_frame: &mut [[u32; 4]],
    color: &[[f32; 4]],
    assoc: &[u64],
) {
    let cam = [params.fx, params.fy, params.cx, params.cy];
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
            prune_surfel(
                params,
                chunk,
                position_weight,
                normal_frame,
                color,
                assoc,
                i,
                (i - chunk.base) as usize,
                cam,
            );
        }
    }
}

/// Retires surfel `i` (map-wide index; `slot` in the chunk's arrays) if it duplicates the
/// surfel its pixel chose.
#[allow(clippy::too_many_arguments)]
fn prune_surfel(
    params: &FuseParams,
    chunk: &MapChunk,
    position_weight: &mut [[f32; 4]],
    normal_frame: &mut [[u32; 4]],
    color: &[[f32; 4]],
    assoc: &[u64],
    i: u32,
    slot: usize,
    cam: [f32; 4],
) {
    let nf = normal_frame[slot];
    if nf[3] == params.frame_id {
        return;
    }
    let pw = position_weight[slot];
    let Some(centre) = project_to_texel(
        cam,
        params.width,
        params.height,
        transform_point(&params.t_world_to_cam, xyz(pw)),
    ) else {
        return;
    };
    let key = assoc[(centre[1] * params.width + centre[0]) as usize];
    let chosen = key as u32;
    // chosen - chunk.base wraps to a huge value below the chunk: one test for both ends.
    let t = chosen.wrapping_sub(chunk.base);
    if key >> 32 == 0 || chosen == i || t >= chunk.slots {
        return;
    }
    let t = t as usize;
    let nf_t = normal_frame[t];
    if nf_t[3] != params.frame_id {
        return;
    }
    let pw_t = position_weight[t];
    let reach = params.prune_radius_scale * color[slot][3].max(color[t][3]);
    if xyz(pw).distance(xyz(pw_t)) < reach
        && normal_of(nf).dot(normal_of(nf_t)) > PRUNE_COS_NORMAL
        && pw[3] <= pw_t[3]
    {
        position_weight[slot] = [pw[0], pw[1], pw[2], 0.0];
        normal_frame[slot] = [nf[0], nf[1], nf[2], 0];
    }
}
