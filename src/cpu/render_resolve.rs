//! CPU twin of `shaders/render_resolve.wgsl`: shades each pixel of a `render_splat` index
//! map from its winning surfel (colour, normal, weight or depth), background where empty.
//!
//! Output pixels are RGBA8 packed into one `u32` (`r | g << 8 | b << 16 | 255 << 24`), the
//! layout of `layout::pack_rgba8`. No lighting: the normal view shows the shape.

use glam::Vec3;

use crate::render::layout::{RenderParams, VIEW_COLOR, VIEW_DEPTH, VIEW_NORMALS, VIEW_WEIGHT};

/// Dark blue, teal and yellow stops of the weight and depth ramps (RGB in 0..1, close to
/// the ends and middle of viridis). Mirrors `RAMP_*` in render_resolve.wgsl.
pub const RAMP_LOW: [f32; 3] = [0.267, 0.005, 0.329];
pub const RAMP_MID: [f32; 3] = [0.128, 0.567, 0.551];
pub const RAMP_HIGH: [f32; 3] = [0.993, 0.906, 0.144];

/// Colour (RGB in 0..1) of `t` in 0..1 on the two-segment ramp. Mirrors `ramp`.
#[inline]
pub fn ramp(t: f32) -> Vec3 {
    let t = t.clamp(0.0, 1.0);
    let (lo, hi, s) = if t < 0.5 {
        (RAMP_LOW, RAMP_MID, t * 2.0)
    } else {
        (RAMP_MID, RAMP_HIGH, t * 2.0 - 1.0)
    };
    Vec3::from(lo).lerp(Vec3::from(hi), s)
}

/// Packs RGB in 0..255 (clamped, rounded half up) with alpha 255. Mirrors `pack_rgb`.
#[inline]
pub fn pack_rgb(c: Vec3) -> u32 {
    let q = |x: f32| (x.clamp(0.0, 255.0) + 0.5) as u32;
    q(c.x) | q(c.y) << 8 | q(c.z) << 16 | 255 << 24
}

/// The colour of surfel `index` seen at camera depth `z` (metres). Mirrors `shade`.
#[inline]
pub fn shade(
    params: &RenderParams,
    index: usize,
    z: f32,
    normals: &[[f32; 4]],
    colors: &[[f32; 4]],
    weights: &[f32],
) -> Vec3 {
    match params.view {
        VIEW_COLOR => Vec3::new(colors[index][0], colors[index][1], colors[index][2]),
        VIEW_NORMALS => {
            let n = Vec3::new(normals[index][0], normals[index][1], normals[index][2]);
            (n + 1.0) * 127.5
        }
        VIEW_WEIGHT => ramp(weights[index] / params.weight_max) * 255.0,
        VIEW_DEPTH => {
            // Near is bright, far is dark.
            ramp(1.0 - (z - params.near_m) / (params.far_m - params.near_m)) * 255.0
        }
        _ => Vec3::ZERO,
    }
}

/// Arguments: the shader's bindings in `@binding` order, named as there; see the
/// declarations in `shaders/render_resolve.wgsl` for shapes, units and frames.
pub fn render_resolve(
    params: &RenderParams,
    index_map: &[u64],
    normals: &[[f32; 4]],
    colors: &[[f32; 4]],
    weights: &[f32],
    out_rgba: &mut [u32],
) {
    let n = params.width as usize * params.height as usize;
    assert_eq!(index_map.len(), n, "index_map has the wrong size");
    assert_eq!(out_rgba.len(), n, "out_rgba has the wrong size");
    for pix in 0..n {
        let key = index_map[pix];
        if key == 0 {
            out_rgba[pix] = params.background;
            continue;
        }
        let index = (key & 0xffff_ffff) as usize;
        let z = f32::from_bits(!((key >> 32) as u32));
        out_rgba[pix] = pack_rgb(shade(params, index, z, normals, colors, weights));
    }
}
