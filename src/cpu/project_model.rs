//! CPU twin of `shaders/project_model.wgsl`: splats every surfel into an index map with a
//! depth test, one packed 64-bit key per pixel.
//!
//! Key = [`pack_depth_index`]`(z_cam, surfel)`; the pixel keeps the maximum key, i.e. the
//! nearest surfel, ties broken by the larger index. 0 means no surfel. The GPU does the
//! same with one `atomicMax` on `u64`, so both backends pick the same surfel.

use super::{pack_depth_index, project_to_pixel, surfel_texel, transform_point, xyz};
use crate::layout::ProjectParams;

/// Bindings (as in the shader header):
/// - 0 `params`: `ProjectParams` (`t_world_to_cam`, intrinsics, map size, `surfel_count`)
/// - 1 `position_weight`: surfel xyz (world frame, metres) + weight, `surfel_count` used
/// - 2 `index_map` (in/out): width x height keys, cleared to 0 by the caller
pub fn project_model(params: &ProjectParams, position_weight: &[[f32; 4]], index_map: &mut [u64]) {
    let cam = [params.fx, params.fy, params.cx, params.cy];
    assert_eq!(index_map.len(), (params.width * params.height) as usize);
    for i in 0..params.surfel_count {
        let p = transform_point(
            &params.t_world_to_cam,
            xyz(position_weight[surfel_texel(i)]),
        );
        if let Some(pix) = project_to_pixel(cam, params.width, params.height, p) {
            index_map[pix] = index_map[pix].max(pack_depth_index(p.z, i));
        }
    }
}
