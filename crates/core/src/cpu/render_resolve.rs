//! CPU twin of `shaders/render_resolve.wgsl`: shades each pixel of a `render_splat` index
//! map from its winning surfel (colour, normal, weight or depth), background where empty.
//!
//! Output pixels are RGBA8 packed into one `u32` (`r | g << 8 | b << 16 | 255 << 24`), the
//! layout of `layout::pack_rgba8`. No lighting: the normal view shows the shape.
//!
//! Gap filling (`params.fill_gap_px > 0`): an empty pixel with covered pixels at most
//! `fill_gap_px` away on both sides of it (above and below, or left and right) whose depths
//! agree within [`GAP_DEPTH_TOLERANCE`] shows the nearer of the two. This closes the
//! stripes between rows of surfels on surfaces the input camera saw at a grazing angle,
//! while silhouettes (covered on one side only) and depth jumps stay as they are. Keys are
//! read from the index map only, so the shader and this twin fill the same pixels.

use super::binding::twin;
use super::invocations::{par_for_each_invocation, Storage};
use glam::Vec3;

use crate::layout::render::{RenderParams, VIEW_COLOR, VIEW_DEPTH, VIEW_NORMALS, VIEW_WEIGHT};

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

/// Relative depth difference (`|z_a - z_b| / min(z_a, z_b)`) up to which the two covered
/// pixels around a gap are taken as one surface. Rows of one surface a few pixels apart
/// differ by well under 5 % even at a grazing angle (a floor 2.5 m away, rows 5 cm apart:
/// 2 %); a foreground object in front of a wall is usually more than 5 % nearer.
/// Mirrors `GAP_DEPTH_TOLERANCE` in render_resolve.wgsl.
pub const GAP_DEPTH_TOLERANCE: f32 = 0.05;

/// Camera depth (metres) of a non-zero key. Mirrors `key_depth`.
#[inline]
pub fn key_depth(key: u64) -> f32 {
    f32::from_bits(!((key >> 32) as u32))
}

/// The first non-zero key at most `params.fill_gap_px` pixels from `(x, y)` in the direction
/// `(dx, dy)`, or 0. Mirrors `nearest_covered`.
#[inline]
pub fn nearest_covered(
    params: &RenderParams,
    index_map: &[u64],
    x: i32,
    y: i32,
    dx: i32,
    dy: i32,
) -> u64 {
    for s in 1..=params.fill_gap_px as i32 {
        let (qx, qy) = (x + dx * s, y + dy * s);
        if qx < 0 || qy < 0 || qx >= params.camera.width as i32 || qy >= params.camera.height as i32
        {
            break;
        }
        let key = index_map[qy as usize * params.camera.width as usize + qx as usize];
        if key != 0 {
            return key;
        }
    }
    0
}

/// Of the keys on opposite sides of an empty pixel: the nearer (the larger key) when both
/// are covered and their depths agree, else 0. Mirrors `bridge`.
#[inline]
pub fn bridge(a: u64, b: u64) -> u64 {
    if a == 0 || b == 0 {
        return 0;
    }
    let (za, zb) = (key_depth(a), key_depth(b));
    if (za - zb).abs() > GAP_DEPTH_TOLERANCE * za.min(zb) {
        return 0;
    }
    a.max(b)
}

/// The key an empty pixel `pix` shows after gap filling (0: stays empty). Mirrors
/// `fill_gap`.
#[inline]
pub fn fill_gap(params: &RenderParams, index_map: &[u64], pix: usize) -> u64 {
    let x = (pix % params.camera.width as usize) as i32;
    let y = (pix / params.camera.width as usize) as i32;
    let near = |dx, dy| nearest_covered(params, index_map, x, y, dx, dy);
    let vertical = bridge(near(0, -1), near(0, 1));
    let horizontal = bridge(near(-1, 0), near(1, 0));
    vertical.max(horizontal)
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

twin! {
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
        let n = params.camera.width as usize * params.camera.height as usize;
        assert_eq!(index_map.len(), n, "index_map has the wrong size");
        assert_eq!(out_rgba.len(), n, "out_rgba has the wrong size");
        // Every pixel on every thread, each writing its own.
        let out_rgba = Storage::new(out_rgba);
        par_for_each_invocation(n, |pix| {
            let mut key = index_map[pix];
            if key == 0 {
                key = fill_gap(params, index_map, pix);
            }
            if key == 0 {
                out_rgba.store(pix, params.background);
                return;
            }
            let index = (key & 0xffff_ffff) as usize;
            let z = key_depth(key);
            out_rgba.store(pix, pack_rgb(shade(params, index, z, normals, colors, weights)));
        });
    }
}
