//! CPU twin of `shaders/project_model.wgsl` (both variants): splats every surfel of one
//! map chunk into an index map with a depth test, one key per pixel, skipping blocks the
//! camera cannot see ([`visible_surfels`]).
//!
//! Key = [`pack_depth_index`](super::pack_depth_index)`(z_cam, surfel)` with the map-wide
//! surfel index; the pixel keeps the maximum key, i.e. the nearest surfel, ties broken by
//! the larger index. 0 means no surfel. The GPU does the same with one `atomicMax` on `u64`
//! (`index_map` a [`KeyMap`] of `u64` keys here) or in two 32-bit passes
//! (project_model_portable: a [`KeyMap`] bound as one pass of the words, every chunk of
//! pass 0 before pass 1), so both backends pick the same surfel whatever the chunking.

use super::binding::twin;
use super::key_writer::{KeyMap, KeyWriter};
use super::{depth_key, project_to_pixel, transform_point, visible_surfels, xyz};
use crate::layout::{MapChunk, ProjectParams};

twin! {
    /// Splats the chunk's visible surfels into the index map: the parameters are the shader's
    /// bindings in `@binding` order, named as there (see the declarations in
    /// `shaders/project_model.wgsl` for shapes, units and frames). The key maps are
    /// [`KeyMap`]s, which carry the key variant (and the portable kernel's `override
    /// KEY_PASS`).
    pub fn project_model(
        params: &ProjectParams,
        chunk: &MapChunk,
        block_boxes: &[[u32; 4]],
        position_weight: &[[f32; 4]],
        index_map: KeyMap<'_>,
    ) {
        let cam = super::camera_intrinsics(&params.camera);
        assert_eq!(
            index_map.pixels(),
            (params.camera.width * params.camera.height) as usize
        );
        visible_surfels(params, chunk, block_boxes, |i, slot| {
            let p = transform_point(&params.t_world_to_cam, xyz(position_weight[slot as usize]));
            if let Some(pix) = project_to_pixel(cam, params.camera.width, params.camera.height, p) {
                index_map.keep_nearer(pix, depth_key(p.z), i);
            }
        });
    }
}
