//! CPU twin of `shaders/fuse_select.wgsl`: every pixel picks the one surfel it will fuse
//! with (the best-candidate association of the robust profile, Keller et al. 2013 Sec. 4.2,
//! ElasticFusion), before `fuse_merge_chosen` and `fuse_add`.
//!
//! For every surfel (world frame): move it and its normal into the tracked camera and
//! project it (filter 1: inside the image, `z > 0`). If its pixel has a valid measurement
//! `q` (camera frame, rebuilt with `back_project`), filter 2 ([`candidate_off_ray`]) has
//! three gates: the distance along the pixel's ray `|(p - q) . ray|` below the surfel's
//! depth gate ([`fuse_depth_gate`]: `dist_m` for a surfel seen once, narrowing
//! towards `dist_confident_m` as its weight grows), the distance off the ray `|(p - q) - ((p - q) . ray) ray| < radius` (the disc
//! covers the ray), and the normal angle (`cos > cos_normal_threshold`). Of the surfels
//! that pass, the pixel keeps the one nearest its ray (smallest off-ray distance; ties to
//! the larger index): `assoc[pix] = max(assoc[pix], pack_depth_index(off_ray, i))`, so the
//! choice does not depend on thread order. Both maps are [`KeyMap`]s: `u64` keys (the
//! 64-bit kernel) or a pass of the words each (fuse_select_portable, every chunk of pass 0
//! before pass 1), with the same keys in the end. As in
//! ElasticFusion's index map, a pixel only chooses among the surfels whose centres project
//! into it. `fuse_merge_chosen` then merges each chosen surfel with its pixel; `fuse_flags`
//! adds only the pixels that chose nothing and that no neighbour's merged surfel covers
//! (its header says why).
//!
//! Surfels that pass the gates but are not chosen are neither merged nor refreshed: a
//! second copy of a surface stops gaining confidence, `fuse_prune` retires it when it lies
//! on the merged one, and the removal of unstable surfels (`compact_flags`) takes it away.

use super::binding::twin;
use super::key_writer::{KeyMap, KeyWriter};
use super::{
    candidate_off_ray, depth_key, fuse_depth_gate, is_valid, normal_of, project_to_texel,
    transform_dir, transform_point, visible_surfels, xyz,
};
use crate::layout::{FuseParams, MapChunk};

twin! {
    /// Each pixel's choice among the chunk's visible surfels: the parameters are the shader's
    /// bindings in `@binding` order, named as there (see the declarations in
    /// `shaders/fuse_select.wgsl` for shapes, units and frames). The key maps are [`KeyMap`]s,
    /// which carry the key variant (and the portable kernel's `override KEY_PASS`).
    pub fn fuse_select(
        params: &FuseParams,
        normal_depth: &[[f32; 4]],
        chunk: &MapChunk,
        block_boxes: &[[u32; 4]],
        position_weight: &[[f32; 4]],
        normal_frame: &[[u32; 4]],
        color: &[[f32; 4]],
        assoc: KeyMap<'_>,
        index_map: KeyMap<'_>,
    ) {
        let cam = super::camera_intrinsics(&params.camera);
        let map = Chunk {
            position_weight,
            normal_frame,
            color,
        };
        visible_surfels(params, chunk, block_boxes, |i, slot| {
            select_for_surfel(params, normal_depth, &map, &assoc, &index_map, i, slot, cam);
        });
    }
}

/// The chunk's three arrays (the shader's bindings 4..6).
struct Chunk<'a> {
    position_weight: &'a [[f32; 4]],
    normal_frame: &'a [[u32; 4]],
    color: &'a [[f32; 4]],
}

/// The pixel surfel `i` (map-wide index; `slot` in the chunk's arrays) projects to keeps
/// the nearer of its index-map key and this surfel's, and the better of its association key
/// and this surfel's, if the surfel passes its gates.
#[allow(clippy::too_many_arguments)] // the shader's function plus the bindings it uses
fn select_for_surfel<A: KeyWriter + ?Sized, K: KeyWriter + ?Sized>(
    params: &FuseParams,
    normal_depth: &[[f32; 4]],
    map: &Chunk,
    assoc: &A,
    index_map: &K,
    i: u32,
    slot: u32,
    cam: [f32; 4],
) {
    let slot = slot as usize;
    let p_cam = transform_point(&params.t_world_to_cam, xyz(map.position_weight[slot]));
    let Some(texel) = project_to_texel(cam, params.camera.width, params.camera.height, p_cam)
    else {
        return;
    };
    let pix = (texel[1] * params.camera.width + texel[0]) as usize;
    index_map.keep_nearer(pix, depth_key(p_cam.z), i);
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
        fuse_depth_gate(params, map.position_weight[slot][3]),
        params.cos_normal_threshold,
    ) else {
        return;
    };
    assoc.keep_nearer(pix, depth_key(off_ray), i);
}
