//! CPU twin of `shaders/render_splat_portable.wgsl`: [`render_splat`](super::render_splat)
//! without 64-bit integers, one pass of two. The map holds render_splat's 64-bit keys as
//! `(low, high)` u32 words; pass 0 (`key_pass` 0) then pass 1 leave each pair equal to
//! render_splat's key ([`keep_nearer`]).

use super::render_splat::{splat_radius_px, MAX_PROJECTED_PX};
use super::{depth_key, keep_nearer, transform_dir, transform_point, xyz};
use crate::render::layout::RenderParams;

/// Arguments: the shader's bindings in `@binding` order, named as there; see the
/// declarations in `shaders/render_splat_portable.wgsl` for shapes, units and frames;
/// `key_pass` is the kernel's `override KEY_PASS`.
pub fn render_splat_portable(
    params: &RenderParams,
    positions: &[[f32; 4]],
    normals: &[[f32; 4]],
    index_map: &mut [u32],
    key_pass: u32,
) {
    assert_eq!(
        index_map.len(),
        2 * params.width as usize * params.height as usize,
        "index_map has the wrong size"
    );
    let (w, h) = (params.width, params.height);
    for i in 0..params.surfel_count as usize {
        let p = transform_point(&params.t_world_to_cam, xyz(positions[i]));
        // Written as a negated comparison so that a NaN depth is skipped too.
        if !(p.z > params.near_m && p.z <= params.far_m) {
            continue;
        }
        if params.cull_backfaces == 1 {
            let n = transform_dir(&params.t_world_to_cam, xyz(normals[i]));
            if n.dot(p) > 0.0 {
                continue;
            }
        }
        let u = params.fx * p.x / p.z + params.cx;
        let v = params.fy * p.y / p.z + params.cy;
        if !(u.abs() < MAX_PROJECTED_PX && v.abs() < MAX_PROJECTED_PX) {
            continue;
        }
        let r = splat_radius_px(params, p.z);
        let u0 = (u - r).ceil().max(0.0);
        let u1 = (u + r).floor().min((w - 1) as f32);
        let v0 = (v - r).ceil().max(0.0);
        let v1 = (v + r).floor().min((h - 1) as f32);
        if u0 > u1 || v0 > v1 {
            continue;
        }
        let depth_word = depth_key(p.z);
        for py in v0 as u32..=v1 as u32 {
            let dv = py as f32 - v;
            for px in u0 as u32..=u1 as u32 {
                let du = px as f32 - u;
                if du * du + dv * dv <= r * r {
                    let pix = (py * w + px) as usize;
                    keep_nearer(index_map, pix, depth_word, i as u32, key_pass);
                }
            }
        }
    }
}
