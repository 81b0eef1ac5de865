//! CPU twin of `shaders/fuse_merge_chosen.wgsl`: the merge of best-candidate association,
//! driven by the pixels. Every pixel whose `fuse_select` key chose a surfel of this chunk
//! merges its measurement into that surfel ([`merged_surfel`], `last_frame = frame_id`).
//! A surfel keys only the pixel its centre projects to, so each surfel has at most one
//! writer: the same merges as walking the surfels and asking their pixel whether it chose
//! them, at the cost of the image instead of the map. A merge that moves a surfel out of its
//! block's box grows the box.

use super::binding::twin;
use super::invocations::Storage;
use super::{
    back_project, merged_surfel, normal_of, pixel_confidence, pixel_grid, surfel_radius,
    transform_dir, transform_point, xyz,
};
use crate::layout::{ordered_from_f32, FuseParams, MapChunk, BLOCK_SURFELS};

twin! {
    /// Merges each pixel's chosen surfel of the chunk with its measurement: the parameters are
    /// the shader's bindings in `@binding` order, named as there (see the declarations in
    /// `shaders/fuse_merge_chosen.wgsl` for shapes, units and frames).
    pub fn fuse_merge_chosen(
        params: &FuseParams,
        normal_depth: &[[f32; 4]],
        color_map: &[[f32; 4]],
        chunk: &MapChunk,
        block_boxes: &mut [u32],
        position_weight: &mut [[f32; 4]],
        normal_frame: &mut [[u32; 4]],
        color: &mut [[f32; 4]],
        assoc: &[u64],
        merged: &mut [[f32; 4]],
    ) {
        let (position_weight, color) = (Storage::new(position_weight), Storage::new(color));
        let (normal_frame, merged) = (Storage::new(normal_frame), Storage::new(merged));
        let block_boxes = Storage::new(block_boxes);
        // The shader's grid-stride loop: every pixel once, in parallel (each surfel has at most
        // one writer, and the boxes grow through atomic min / max).
        pixel_grid(params.camera.width, params.camera.height, |[u, v]| {
            let pix = (v * params.camera.width + u) as usize;
            let key = assoc[pix];
            if key == 0 {
                return;
            }
            // The index minus chunk.base wraps to a huge value below the chunk.
            let slot = (key as u32).wrapping_sub(chunk.base);
            if slot >= chunk.slots {
                return;
            }
            let s = slot as usize;
            let texel = [u, v];
            let cam = super::camera_intrinsics(&params.camera);
            let pw = position_weight.load(s);
            // fuse_select chose only on a valid pixel (a valid normal implies a valid
            // vertex).
            let nd = normal_depth[pix];
            let q_cam = back_project(cam, texel, nd[3]);
            let q_world = transform_point(&params.t_cam_to_world, q_cam);
            let nq_world = transform_dir(&params.t_cam_to_world, xyz(nd));
            let n_old = normal_of(normal_frame.load(s));
            let wq = pixel_confidence(cam, texel, params.confidence_sigma);
            let cq = xyz(color_map[pix]);
            let r_q = surfel_radius(params.camera.fx, q_cam, xyz(nd));
            let m = merged_surfel(pw, n_old, color.load(s), q_world, nq_world, cq, wq, r_q);
            position_weight.store(s, m.position_weight);
            let n = m.normal;
            normal_frame.store(
                s,
                [n.x.to_bits(), n.y.to_bits(), n.z.to_bits(), params.frame_id],
            );
            color.store(s, m.color);
            merged.store(2 * pix, m.position_weight);
            merged.store(2 * pix + 1, [n.x, n.y, n.z, m.color[3]]);
            // Grow the block's box if the surfel moved out of it.
            let block = (key as u32 / BLOCK_SURFELS) as usize;
            for k in 0..3 {
                let e = ordered_from_f32(m.position_weight[k]);
                // atomicMin / atomicMax: order-independent, so the pixels run on any thread.
                block_boxes.fetch_min(8 * block + k, e);
                block_boxes.fetch_max(8 * block + 4 + k, e);
            }
        });
    }
}
