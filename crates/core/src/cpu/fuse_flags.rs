//! CPU twin of `shaders/fuse_flags.wgsl`: one flag per pixel, 1 where the pixel becomes a
//! new surfel (a valid measurement no surfel merged with or covers), stored at the pixel's
//! `append_index`. With `prefix_sum` over the flags it gives `fuse_add` each new surfel's
//! slot in append order (`layout::APPEND_TILE_PX`), on both backends, so the GPU map has
//! the CPU map's order and two runs write the same bytes.
//!
//! Best-candidate association also asks the neighbours: `fuse_select` lets a pixel choose
//! only among the surfels whose centres project into it, and the projected map has holes
//! (surfels lie about a pixel apart, not on the pixel grid), so a pixel that chose nothing
//! is still covered when a surfel that one of its 8 neighbours merged into (`merged`, after
//! the merge) passes this pixel's gates ([`candidate_off_ray`]). Without this, revisits
//! grow the map. It replaces a 3x3 window per surfel in `fuse_select`, at the cost of
//! the image instead of the map.

use super::binding::twin;
use super::invocations::Storage;
use super::{
    append_index, candidate_off_ray, fuse_depth_gate, is_valid, pixel_grid, transform_dir,
    transform_point, xyz,
};
use crate::layout::{FuseParams, ASSOCIATION_BEST_CANDIDATE};

twin! {
    /// Which pixels become new surfels, one flag per append slot: the parameters are the
    /// shader's bindings in `@binding` order, named as there (see the declarations in
    /// `shaders/fuse_flags.wgsl` for shapes, units and frames).
    pub fn fuse_flags(
        params: &FuseParams,
        normal_depth: &[[f32; 4]],
        assoc: &[u64],
        merged: &[[f32; 4]],
        flags: &mut [u32],
    ) {
        // The shader's entry, pixel_grid.wgsl: every pixel once, in parallel.
        let flags = Storage::new(flags);
        pixel_grid(params.camera.width, params.camera.height, |[u, v]| {
            let texel = [u, v];
            let pix = (v * params.camera.width + u) as usize;
            let nd = normal_depth[pix];
            // Valid normal (w = depth > 0) implies a valid vertex.
            let mut new_surfel = assoc[pix] == 0 && is_valid(nd);
            if new_surfel && params.association == ASSOCIATION_BEST_CANDIDATE {
                new_surfel = !neighbour_covers(params, merged, texel, nd);
            }
            flags.store(append_index(texel), new_surfel as u32);
        });
    }
}

/// Whether a surfel that one of the 8 neighbours of `texel` (measurement `nd`, valid)
/// merged into passes this pixel's gates (`fuse_select`'s filter 2).
fn neighbour_covers(
    params: &FuseParams,
    merged: &[[f32; 4]],
    texel: [u32; 2],
    nd: [f32; 4],
) -> bool {
    let cam = super::camera_intrinsics(&params.camera);
    for dv in -1..=1 {
        for du in -1..=1 {
            let u = texel[0] as i32 + du;
            let v = texel[1] as i32 + dv;
            if (du == 0 && dv == 0)
                || u < 0
                || v < 0
                || u >= params.camera.width as i32
                || v >= params.camera.height as i32
            {
                continue;
            }
            let pix = (v as u32 * params.camera.width + u as u32) as usize;
            let pw = merged[2 * pix];
            if !is_valid(pw) {
                continue;
            }
            let nr = merged[2 * pix + 1];
            let p_cam = transform_point(&params.t_world_to_cam, xyz(pw));
            let n_cam = transform_dir(&params.t_world_to_cam, xyz(nr));
            if candidate_off_ray(
                cam,
                texel,
                nd,
                p_cam,
                n_cam,
                nr[3],
                fuse_depth_gate(params, pw[3]),
                params.cos_normal_threshold,
            )
            .is_some()
            {
                return true;
            }
        }
    }
    false
}
