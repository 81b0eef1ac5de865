//! CPU twin of `shaders/fuse_merge.wgsl`: merges the new frame into the surfels it sees
//! with projective association (the assignment).
//!
//! For every surfel (world frame): move it into the tracked camera and project it. Filter
//! pass 1: it lands inside the image with `z > 0` on a pixel with a valid `normal_depth`
//! texel (a valid normal implies a valid vertex). Filter pass 2: the frame's point at that
//! pixel (rebuilt with `back_project`), moved to the world, is closer than
//! `dist_m`, and the angle between the normals is below the threshold
//! (`cos > cos_normal_threshold`); the pixel is then marked in `assoc` so `fuse_add` does
//! not add it again. Several surfels may merge with one pixel (as in the assignment).
//! Best-candidate association merges from the pixels instead (`fuse_merge_chosen`).
//!
//! Merged surfels take [`merged_surfel`]'s confidence-weighted averages `(w x + c x_new) /
//! (w + c)` of position, colour, normal (renormalised) and radius, weight `w + c` and
//! `last_frame = frame_id`, where `c = pixel_confidence(...)` (1 with
//! `confidence_sigma = 0`: the assignment's counts) and the new radius is `surfel_radius`
//! of the measurement.
//!
//! Called once per map chunk, walking its blocks and skipping those the camera cannot see
//! ([`block_visible`]); a merge that moves a surfel out of its block's box grows the box
//! (the shader does it with `atomicMin`/`atomicMax` on the ordered encoding).

use super::binding::twin;
use glam::Vec3;

use super::{
    back_project, block_visible, chunk_blocks, is_valid, merged_surfel, normal_of,
    pixel_confidence, project_to_texel, surfel_radius, transform_dir, transform_point, xyz,
};
use crate::layout::{f32_from_ordered, ordered_from_f32, FuseParams, MapChunk, BLOCK_SURFELS};

twin! {
    /// Merges the frame into the chunk's visible surfels (projective association): the
    /// parameters are the shader's bindings in `@binding` order, named as there (see the
    /// declarations in `shaders/fuse_merge.wgsl` for shapes, units and frames).
    pub fn fuse_merge(
        params: &FuseParams,
        normal_depth: &[[f32; 4]],
        color_map: &[[f32; 4]],
        chunk: &MapChunk,
        block_boxes: &mut [u32],
        position_weight: &mut [[f32; 4]],
        normal_frame: &mut [[u32; 4]],
        color: &mut [[f32; 4]],
        assoc: &mut [u32],
    ) {
        let cam = super::camera_intrinsics(&params.camera);
        let (blocks, span_end) = chunk_blocks(chunk, params.surfel_count);
        let mut map = ChunkMut {
            position_weight,
            normal_frame,
            color,
        };
        for b in 0..blocks {
            let block = (chunk.base / BLOCK_SURFELS + b) as usize;
            let word = |k: usize| f32_from_ordered(block_boxes[8 * block + k]);
            let lo = Vec3::new(word(0), word(1), word(2));
            let hi = Vec3::new(word(4), word(5), word(6));
            if !block_visible(
                &params.t_world_to_cam,
                cam,
                params.camera.width,
                params.camera.height,
                lo,
                hi,
            ) {
                continue;
            }
            // The box grown by the merged surfels.
            let mut grown_lo = lo;
            let mut grown_hi = hi;
            let end = (chunk.base + (b + 1) * BLOCK_SURFELS).min(span_end);
            for i in chunk.base + b * BLOCK_SURFELS..end {
                if let Some(moved) = merge_surfel(
                    params,
                    normal_depth,
                    color_map,
                    &mut map,
                    assoc,
                    i - chunk.base,
                    cam,
                ) {
                    grown_lo = grown_lo.min(moved);
                    grown_hi = grown_hi.max(moved);
                }
            }
            for k in 0..3 {
                if grown_lo[k] < lo[k] {
                    let w = &mut block_boxes[8 * block + k];
                    *w = (*w).min(ordered_from_f32(grown_lo[k]));
                }
                if grown_hi[k] > hi[k] {
                    let w = &mut block_boxes[8 * block + 4 + k];
                    *w = (*w).max(ordered_from_f32(grown_hi[k]));
                }
            }
        }
    }
}

/// The chunk's three arrays (the shader's bindings 5..7).
struct ChunkMut<'a> {
    position_weight: &'a mut [[f32; 4]],
    normal_frame: &'a mut [[u32; 4]],
    color: &'a mut [[f32; 4]],
}

/// Merges surfel `slot` of the chunk with its pixel when the filters pass: its new world-frame position, or `None` if unmerged (the shader returns
/// w = 1 / w = 0).
#[allow(clippy::too_many_arguments)]
fn merge_surfel(
    params: &FuseParams,
    normal_depth: &[[f32; 4]],
    color_map: &[[f32; 4]],
    map: &mut ChunkMut,
    assoc: &mut [u32],
    slot: u32,
    cam: [f32; 4],
) -> Option<Vec3> {
    let surfel = slot as usize;
    let pw = map.position_weight[surfel];
    let p_world = xyz(pw);
    let p_cam = transform_point(&params.t_world_to_cam, p_world);
    let texel = project_to_texel(cam, params.camera.width, params.camera.height, p_cam)?;
    let pix = (texel[1] * params.camera.width + texel[0]) as usize;
    // Valid normal (w = depth > 0) implies a valid vertex.
    let nd = normal_depth[pix];
    if !is_valid(nd) {
        return None;
    }
    let q_cam = back_project(cam, texel, nd[3]);
    let q_world = transform_point(&params.t_cam_to_world, q_cam);
    let nq_world = transform_dir(&params.t_cam_to_world, xyz(nd));
    let n_old = normal_of(map.normal_frame[surfel]);
    if super::arith::length(q_world - p_world) >= params.dist_m
        || n_old.dot(nq_world) <= params.cos_normal_threshold
    {
        return None;
    }
    let wq = pixel_confidence(cam, texel, params.confidence_sigma);
    let cq = xyz(color_map[pix]);
    let r_q = surfel_radius(params.camera.fx, q_cam, xyz(nd));
    let m = merged_surfel(pw, n_old, map.color[surfel], q_world, nq_world, cq, wq, r_q);
    map.position_weight[surfel] = m.position_weight;
    let n = m.normal;
    map.normal_frame[surfel] = [n.x.to_bits(), n.y.to_bits(), n.z.to_bits(), params.frame_id];
    map.color[surfel] = m.color;
    // The key's low word (its (low, high) words, as the shader sees them) maxed with 1: the
    // key reads 1, with no 64-bit integers.
    assoc[2 * pix] = assoc[2 * pix].max(1);
    Some(xyz(m.position_weight))
}
