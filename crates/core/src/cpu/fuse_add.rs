//! CPU twin of `shaders/fuse_add.wgsl`: appends every pixel `fuse_flags` flagged (a valid
//! measurement no surfel merged with or covers) as a new surfel at slot `surfel_count +
//! offsets[append_index(pixel)]` (`prefix_sum` of the flags: append order on both
//! backends, see `layout::APPEND_TILE_PX`): world frame,
//! weight `pixel_confidence` (1 for the assignment), radius `surfel_radius`. Never writes
//! at or past `params.capacity` (the host grows the map first so that every pixel fits).
//! Called once per map chunk: each call writes the new surfels whose slots the chunk holds.
//!
//! Both key variants, as the [`KeyMap`] `index_map` is bound: with `u64` keys one pass
//! does it all; with a pass of the words (fuse_add_portable, every chunk of pass 0 before
//! pass 1) pass 0 writes the new surfels and raises the depth words, pass 1 sets the index
//! words. New surfels' indices exceed every index already in the map, so each pair then
//! equals the 64-bit key.

use super::binding::twin;
use super::invocations::Storage;
use super::key_writer::{KeyMap, KeyWriter};
use super::{
    append_index, back_project, depth_key, pixel_confidence, pixel_grid, surfel_radius,
    transform_dir, transform_point, xyz,
};
use crate::layout::{FuseParams, MapChunk, ASSOCIATION_BEST_CANDIDATE};

twin! {
    /// Appends the flagged pixels whose slots the chunk holds as new surfels: the parameters
    /// are the shader's bindings in `@binding` order, named as there (see the declarations in
    /// `shaders/fuse_add.wgsl` for shapes, units and frames). The key maps are [`KeyMap`]s,
    /// which carry the key variant (and the portable kernel's `override KEY_PASS`).
    pub fn fuse_add(
        params: &FuseParams,
        normal_depth: &[[f32; 4]],
        color_map: &[[f32; 4]],
        flags: &[u32],
        offsets: &[u32],
        chunk: &MapChunk,
        position_weight: &mut [[f32; 4]],
        normal_frame: &mut [[u32; 4]],
        color: &mut [[f32; 4]],
        index_map: KeyMap<'_>,
    ) {
        let cam = super::camera_intrinsics(&params.camera);
        // Each flagged pixel writes its own slot (the prefix sum keeps them apart).
        let (position_weight, normal_frame) = (Storage::new(position_weight), Storage::new(normal_frame));
        let color = Storage::new(color);
        pixel_grid(params.camera.width, params.camera.height, |[u, v]| {
            let pix = (v * params.camera.width + u) as usize;
            let a = append_index([u, v]);
            if flags[a] == 0 {
                return;
            }
            let nd = normal_depth[pix];
            let i = params.surfel_count + offsets[a];
            // i - chunk.base wraps to a huge value below the chunk: one test for both ends.
            let slot = i.wrapping_sub(chunk.base);
            if i >= params.capacity || slot >= chunk.slots {
                return;
            }
            let q_cam = back_project(cam, [u, v], nd[3]);
            let p = transform_point(&params.t_cam_to_world, q_cam);
            let n = transform_dir(&params.t_cam_to_world, xyz(nd));
            let w = pixel_confidence(cam, [u, v], params.confidence_sigma);
            let r = surfel_radius(params.camera.fx, q_cam, xyz(nd));
            if index_map.first_pass() {
                let surfel = slot as usize;
                position_weight.store(surfel, [p.x, p.y, p.z, w]);
                let bits = n.to_array().map(f32::to_bits);
                normal_frame.store(surfel, [bits[0], bits[1], bits[2], params.frame_id]);
                let c = color_map[pix];
                color.store(surfel, [c[0], c[1], c[2], r]);
            }
            if params.association == ASSOCIATION_BEST_CANDIDATE {
                index_map.keep_nearer(pix, depth_key(q_cam.z), i);
            }
        });
    }
}
