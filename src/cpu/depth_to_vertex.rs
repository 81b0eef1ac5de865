//! CPU twin of `shaders/depth_to_vertex.wgsl`: raw 16-bit depth and RGB8 to a camera-frame
//! vertex map (metres) and a colour map, downsampled by keeping every `stride`-th pixel.
//!
//! Output pixel `(u, v)` reads raw pixel `(stride u, stride v)`; `params.fx..cy` are the
//! downsampled intrinsics, so unprojecting `(u, v)` with them equals unprojecting the raw
//! pixel with the raw intrinsics. Invalid depth (0 or outside the depth range) gives the
//! invalid entry `[0; 4]`.

use super::{valid_entry, INVALID};
use crate::layout::PreprocessParams;
use glam::Vec3;

/// Bindings: 0 `params`, 1 `raw_depth` (u16, raw_width x raw_height), 2 `raw_rgba`
/// (packed RGBA8), 3 `vertex_map` (out, width x height, camera frame, metres),
/// 4 `color_map` (out, RGB 0..255).
pub fn depth_to_vertex(
    params: &PreprocessParams,
    raw_depth: &[u16],
    raw_rgba: &[u32],
    vertex_map: &mut [[f32; 4]],
    color_map: &mut [[f32; 4]],
) {
    let (w, h) = (params.width as usize, params.height as usize);
    assert_eq!(vertex_map.len(), w * h, "vertex_map has the wrong size");
    assert_eq!(color_map.len(), w * h, "color_map has the wrong size");
    assert_eq!(
        raw_depth.len(),
        (params.raw_width * params.raw_height) as usize
    );
    for pix in 0..w * h {
        let (u, v) = ((pix % w) as u32, (pix / w) as u32);
        let raw = (v * params.stride * params.raw_width + u * params.stride) as usize;
        let z = raw_depth[raw] as f32 / params.depth_scale;
        let c = raw_rgba[raw];
        color_map[pix] = [
            (c & 255) as f32,
            ((c >> 8) & 255) as f32,
            ((c >> 16) & 255) as f32,
            255.0,
        ];
        if z <= 0.0 || z < params.min_depth_m || z > params.max_depth_m {
            vertex_map[pix] = INVALID;
            continue;
        }
        let x = (u as f32 - params.cx) * z / params.fx;
        let y = (v as f32 - params.cy) * z / params.fy;
        vertex_map[pix] = valid_entry(Vec3::new(x, y, z));
    }
}
