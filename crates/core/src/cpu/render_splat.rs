//! CPU twin of `shaders/render_splat.wgsl`: splats every surfel as a small disc into an
//! index map with a depth test, for pictures of the map (not for tracking).
//!
//! Each surfel covers the pixels whose centres lie within `r` pixels of its projection,
//! `r = splat_radius_m * max(|fx|, |fy|) / z` clamped to `[min_radius_px, max_radius_px]`.
//! Every covered pixel keeps the maximum key `(!bits(z_cam) as u64) << 32 | index`: the
//! nearest surfel (by its centre depth) wins, ties go to the larger index, 0 means empty.
//! This is the key of `project_model`, so the GPU's 64-bit `atomicMax` picks the same one,
//! and so do its two 32-bit passes (render_splat_portable: a
//! [`KeyPass`](super::key_writer::KeyPass) per pass).

use super::binding::twin;
use super::key_writer::{KeyMap, KeyWriter};
use super::{depth_key, transform_dir, transform_point, xyz};
use crate::layout::render::RenderParams;

/// Projections farther than this from the image (pixels) are skipped before any
/// float-to-int conversion; it also rejects NaN and infinite positions.
pub const MAX_PROJECTED_PX: f32 = 1.0e7;

/// Pixel radius of a splat at camera depth `z` (metres, > 0). Mirrors `splat_radius_px`.
#[inline]
pub fn splat_radius_px(params: &RenderParams, z: f32) -> f32 {
    let f = params.camera.fx.abs().max(params.camera.fy.abs());
    (params.splat_radius_m * f / z).clamp(params.min_radius_px, params.max_radius_px)
}

twin! {
    /// Splats every surfel into `index_map`: the parameters are the shader's bindings in
    /// `@binding` order, named as there (see the declarations in `shaders/render_splat.wgsl`
    /// for shapes, units and frames); `index_map` is the 64-bit kernel's keys or a pass of
    /// the portable variant's words, as its binding gives it (`cpu::key_writer::KeyMap`).
    pub fn render_splat(
        params: &RenderParams,
        positions: &[[f32; 4]],
        normals: &[[f32; 4]],
        index_map: KeyMap<'_>,
    ) {
        assert_eq!(
            index_map.pixels(),
            params.camera.width as usize * params.camera.height as usize,
            "index_map has the wrong size"
        );
        let (w, h) = (params.camera.width, params.camera.height);
        // Every surfel on every thread: the keys go up through the atomic key writer.
        super::invocations::par_for_each_invocation(params.surfel_count as usize, |i| {
            let p = transform_point(&params.t_world_to_cam, xyz(positions[i]));
            // Written as a negated comparison so that a NaN depth is skipped too.
            if !(p.z > params.near_m && p.z <= params.far_m) {
                return;
            }
            if params.cull_backfaces == 1 {
                let n = transform_dir(&params.t_world_to_cam, xyz(normals[i]));
                if n.dot(p) > 0.0 {
                    return;
                }
            }
            let u = params.camera.fx * p.x / p.z + params.camera.cx;
            let v = params.camera.fy * p.y / p.z + params.camera.cy;
            if !(u.abs() < MAX_PROJECTED_PX && v.abs() < MAX_PROJECTED_PX) {
                return;
            }
            let r = splat_radius_px(params, p.z);
            let u0 = (u - r).ceil().max(0.0);
            let u1 = (u + r).floor().min((w - 1) as f32);
            let v0 = (v - r).ceil().max(0.0);
            let v1 = (v + r).floor().min((h - 1) as f32);
            if u0 > u1 || v0 > v1 {
                return;
            }
            let depth_word = depth_key(p.z);
            for py in v0 as u32..=v1 as u32 {
                let dv = py as f32 - v;
                for px in u0 as u32..=u1 as u32 {
                    let du = px as f32 - u;
                    if du * du + dv * dv <= r * r {
                        index_map.keep_nearer((py * w + px) as usize, depth_word, i as u32);
                    }
                }
            }
        });
    }
}
