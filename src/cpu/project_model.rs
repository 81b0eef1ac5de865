//! CPU twin of `shaders/project_model.wgsl`: splats every surfel into an index map with a
//! depth test, one packed 64-bit key per pixel.
//!
//! Key = `(!bits(z_cam) as u64) << 32 | surfel_index`; the pixel keeps the maximum key,
//! i.e. the nearest surfel (for positive floats the bit pattern grows with the value, so its
//! complement shrinks), ties broken by the larger index. 0 means no surfel. The GPU does the
//! same with one `atomicMax` on `u64`, so both backends pick the same surfel.

use super::{project_to_pixel, transform_point, xyz};
use crate::layout::ProjectParams;

/// Packs a camera depth (metres, > 0) and a surfel index into an index-map key.
#[inline]
pub fn pack_depth_index(z_cam: f32, surfel: u32) -> u64 {
    ((!z_cam.to_bits()) as u64) << 32 | surfel as u64
}

/// Bindings: 0 `params`, 1 `positions` (world, surfel_count used), 2 `index_map`
/// (in/out, width x height, cleared to 0 by the caller).
pub fn project_model(params: &ProjectParams, positions: &[[f32; 4]], index_map: &mut [u64]) {
    let cam = [params.fx, params.fy, params.cx, params.cy];
    assert_eq!(index_map.len(), (params.width * params.height) as usize);
    for (i, p_world) in positions
        .iter()
        .enumerate()
        .take(params.surfel_count as usize)
    {
        let p = transform_point(&params.t_world_to_cam, xyz(*p_world));
        if let Some(pix) = project_to_pixel(cam, params.width, params.height, p) {
            let key = pack_depth_index(p.z, i as u32);
            index_map[pix] = index_map[pix].max(key);
        }
    }
}
