//! CPU twin of `shaders/bilateral_filter.wgsl`: KinectFusion's edge-preserving bilateral
//! filter on the depth of the camera-frame vertex map (Newcombe et al. 2011, section 3.2:
//! noise is smoothed for the normals and ICP while depth discontinuities stay sharp).
//!
//! For each valid pixel `(u, v)` with depth `z`, the filtered depth is the weighted mean of
//! the valid depths `z_n` in the `(2 radius_px + 1)²` window around it (clipped at the image
//! border), with weight
//! `exp(-d_px² / (2 sigma_space_px²)) * exp(-(z_n - z)² / (2 sigma_depth_m²))`, evaluated as
//! one `exp` of the summed exponents (`d_px` is the pixel distance of the neighbour). The
//! pixel itself has weight 1, so the sum of weights is at least 1 and the mean stays inside
//! the window's depth range. The output is the vertex re-built from the filtered depth with
//! [`super::back_project`] (the function `depth_to_vertex` made the input with); invalid
//! pixels (w = 0) stay invalid and never contribute.
//!
//! What it is not: it does not fill holes, and it filters the maps ICP and the normals use,
//! not the raw depth (the caller keeps `depth_to_vertex`'s unfiltered map).
//!
//! `sigma_depth_m` is one constant for every depth, not the sensor's `~z²` noise model:
//! MEASUREMENT_PLACEHOLDER

use super::{back_project, is_valid, valid_entry, INVALID};
use crate::layout::BilateralParams;

/// The filtered vertex of pixel `(u, v)`, or [`INVALID`] where its vertex is invalid (the
/// rules of the module header). Mirrors `filtered_at` in bilateral_filter.wgsl.
pub fn filtered_at(params: &BilateralParams, vertex_map: &[[f32; 4]], u: u32, v: u32) -> [f32; 4] {
    let w = params.width as usize;
    let load = |u: u32, v: u32| vertex_map[v as usize * w + u as usize];
    let c = load(u, v);
    if !is_valid(c) {
        return INVALID;
    }
    let r = params.radius_px;
    let u_lo = if u < r { 0 } else { u - r };
    let v_lo = if v < r { 0 } else { v - r };
    let u_hi = (u + r).min(params.width - 1);
    let v_hi = (v + r).min(params.height - 1);
    let k_space = 1.0 / (2.0 * params.sigma_space_px * params.sigma_space_px);
    let k_depth = 1.0 / (2.0 * params.sigma_depth_m * params.sigma_depth_m);
    let mut sum_w = 0.0f32;
    let mut sum_wz = 0.0f32;
    for nv in v_lo..=v_hi {
        for nu in u_lo..=u_hi {
            let n = load(nu, nv);
            if is_valid(n) {
                let du = nu as f32 - u as f32;
                let dv = nv as f32 - v as f32;
                let dz = n[2] - c[2];
                let w = (-((du * du + dv * dv) * k_space) - dz * dz * k_depth).exp();
                sum_w += w;
                sum_wz += w * n[2];
            }
        }
    }
    let cam = [params.fx, params.fy, params.cx, params.cy];
    valid_entry(back_project(cam, [u, v], sum_wz / sum_w))
}

/// Bindings (as in the shader header):
/// - 0 `params`: `BilateralParams`
/// - 1 `vertex_map`: width x height, camera frame, metres, w = 1 / 0 (`depth_to_vertex`)
/// - 2 `filtered_vertex` (out): width x height, camera frame, metres, w = 1 / 0
pub fn bilateral_filter(
    params: &BilateralParams,
    vertex_map: &[[f32; 4]],
    filtered_vertex: &mut [[f32; 4]],
) {
    let (w, h) = (params.width as usize, params.height as usize);
    assert_eq!(vertex_map.len(), w * h, "vertex_map has the wrong size");
    assert_eq!(
        filtered_vertex.len(),
        w * h,
        "filtered_vertex has the wrong size"
    );
    // One shader thread per pixel (u, v).
    for v in 0..params.height {
        for u in 0..params.width {
            filtered_vertex[v as usize * w + u as usize] = filtered_at(params, vertex_map, u, v);
        }
    }
}
