//! CPU twin of `shaders/fuse_select_portable.wgsl`: [`fuse_select`](super::fuse_select)
//! (whose header states the gates and the choice) without 64-bit integers, one pass of
//! two. Both maps hold fuse_select's 64-bit keys as `(low, high)` u32 words; pass 0
//! (`key_pass` 0) over every chunk, then pass 1 over every chunk, leave each pair equal to
//! fuse_select's key ([`keep_nearer`]).

use super::{
    block_visible, candidate_off_ray, chunk_blocks, decode_corner, depth_key, is_valid,
    keep_nearer, normal_of, project_to_texel, transform_dir, transform_point, xyz,
};
use crate::layout::{FuseParams, MapChunk, BLOCK_SURFELS};

/// Arguments: the shader's bindings in `@binding` order, named as there; see the
/// declarations in `shaders/fuse_select_portable.wgsl` for shapes, units and frames;
/// `key_pass` is the kernel's `override KEY_PASS`.
#[allow(clippy::too_many_arguments)] // the shader's nine bindings, in order, and the pass
pub fn fuse_select_portable(
    params: &FuseParams,
    normal_depth: &[[f32; 4]],
    chunk: &MapChunk,
    block_bounds: &[[u32; 4]],
    position_weight: &[[f32; 4]],
    normal_frame: &[[u32; 4]],
    color: &[[f32; 4]],
    assoc: &mut [u32],
    index_map: &mut [u32],
    key_pass: u32,
) {
    let cam = [params.fx, params.fy, params.cx, params.cy];
    let (blocks, span_end) = chunk_blocks(chunk, params.surfel_count);
    let map = Chunk {
        position_weight,
        normal_frame,
        color,
    };
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
            select_for_surfel(
                params,
                normal_depth,
                &map,
                assoc,
                index_map,
                i,
                i - chunk.base,
                cam,
                key_pass,
            );
        }
    }
}

/// The chunk's three arrays (the shader's bindings 4..6).
struct Chunk<'a> {
    position_weight: &'a [[f32; 4]],
    normal_frame: &'a [[u32; 4]],
    color: &'a [[f32; 4]],
}

/// Pass `key_pass` for surfel `i` (map-wide index; `slot` in the chunk's arrays) at the
/// pixel it projects to: of its index-map key and of its association key (if the surfel
/// passes its gates), as fuse_select's `select_for_surfel`.
#[allow(clippy::too_many_arguments)] // the shader's function plus the bindings it uses
fn select_for_surfel(
    params: &FuseParams,
    normal_depth: &[[f32; 4]],
    map: &Chunk,
    assoc: &mut [u32],
    index_map: &mut [u32],
    i: u32,
    slot: u32,
    cam: [f32; 4],
    key_pass: u32,
) {
    let slot = slot as usize;
    let p_cam = transform_point(&params.t_world_to_cam, xyz(map.position_weight[slot]));
    let Some(texel) = project_to_texel(cam, params.width, params.height, p_cam) else {
        return;
    };
    let pix = (texel[1] * params.width + texel[0]) as usize;
    keep_nearer(index_map, pix, depth_key(p_cam.z), i, key_pass);
    let nd = normal_depth[pix];
    if !is_valid(nd) {
        return;
    }
    let n_cam = transform_dir(&params.t_world_to_cam, normal_of(map.normal_frame[slot]));
    let Some(off_ray) = candidate_off_ray(
        cam,
        texel,
        nd,
        p_cam,
        n_cam,
        map.color[slot][3],
        params.dist_threshold_m,
        params.cos_normal_threshold,
    ) else {
        return;
    };
    keep_nearer(assoc, pix, depth_key(off_ray), i, key_pass);
}
