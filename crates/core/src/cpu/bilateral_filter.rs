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
//! What it is not: it does not fill holes, and it does not replace the raw depth: the
//! caller keeps `depth_to_vertex`'s unfiltered map, and by default (the robust profile's
//! `bilateral.filter_points` off) level 0's points, which ICP and fusion rebuild from
//! `normal_depth`, keep the raw depth while the normals and the coarser pyramid levels
//! come from this filter's output (see `cpu::vertex_to_normal` for why and the
//! measurements). The table below was measured with the filtered points (before
//! 2026-11-26, when fusion and ICP took the filtered depth).
//!
//! The range sigma grows with depth, `sigma_depth_m + sigma_depth_per_m2 * z²` at the
//! pixel's own depth `z`, because a structured-light sensor's depth noise does (disparity
//! noise: `sigma_z ~ z²`; on the noisy ICL-NUIM set the disparity step is `z² / 351 m`, 11 mm
//! at 2 m and 46 mm at 4 m). Measured on `icl_living_room_kt2_noisy` frames 1..200 at
//! 320x240, CPU backend, ATE after alignment (off: 204 mm; the clean set: 0.326 mm off):
//!
//! | window | range sigma | noisy ATE | clean ATE |
//! |---|---|---|---|
//! | 7x7, sigma 2.25 px (KinectFusion at 320x240) | 30 mm | 184 mm | 1.71 mm |
//! | 7x7, sigma 2.25 px | 50 mm | 132 mm | |
//! | 7x7, sigma 2.25 px | 10 mm | | 0.372 mm |
//! | 7x7, sigma 2.25 px | 0.005 z² | 38.7 mm | |
//! | 7x7, sigma 2.25 px | 0.01 z² | 14.2 mm | 1.95 mm |
//! | 7x7, sigma 2.25 px | 0.015 z², 0.02 z² | 14.1 mm, 14.1 mm | |
//! | 5x5, sigma 1.5 px | 0.01 z² | | 0.969 mm |
//! | 5x5, sigma 1 px | 0.01 z² | 53.1 mm | 0.543 mm |
//! | 3x3, sigma 1 px | 30 mm | 178 mm | 0.261 mm |
//! | 3x3, sigma 1 px (the default) | 0.01 z² | 75.5 mm | 0.279 mm |
//! | 3x3, sigma 1 px | 0.02 z² | 70.8 mm | |
//!
//! A depth-proportional-to-z² sigma beats every constant one on the noisy set at any window
//! (a constant sigma small enough to keep near edges sharp cannot average across the far
//! disparity steps), and 0.01/m is where the gain levels off. The window is a compromise:
//! larger windows track the noisy set better but bias the clean one (windows clipped at the
//! image border and at depth edges are one-sided, so slanted and curved surfaces move with
//! the view), and the clean set must stay within 0.5 mm; 3x3 is the largest that does. The
//! defaults (in `slam::params::BilateralSettings`) are therefore 3x3, sigma 1 px,
//! `sigma_depth = 0.01 z²`. The filter alone does not make noisy tracking good (fusion keeps
//! the noise in the map).

use super::binding::twin;
use super::invocations::Storage;
use super::{back_project, is_valid, pixel_grid, valid_entry, INVALID};
use crate::layout::BilateralParams;

/// The filtered vertex of pixel `(u, v)`, or [`INVALID`] where its vertex is invalid (the
/// rules of the module header). Mirrors `filtered_at` in bilateral_filter.wgsl.
pub fn filtered_at(params: &BilateralParams, vertex_map: &[[f32; 4]], u: u32, v: u32) -> [f32; 4] {
    let w = params.camera.width as usize;
    let load = |u: u32, v: u32| vertex_map[v as usize * w + u as usize];
    let c = load(u, v);
    if !is_valid(c) {
        return INVALID;
    }
    let r = params.radius_px;
    // The shader's `select(u - r, 0u, u < r)`.
    let u_lo = u.saturating_sub(r);
    let v_lo = v.saturating_sub(r);
    let u_hi = (u + r).min(params.camera.width - 1);
    let v_hi = (v + r).min(params.camera.height - 1);
    let k_space = 1.0 / (2.0 * params.sigma_space_px * params.sigma_space_px);
    let sigma_depth = params.sigma_depth_m + params.sigma_depth_per_m2 * c[2] * c[2];
    let k_depth = 1.0 / (2.0 * sigma_depth * sigma_depth);
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
    let cam = super::camera_intrinsics(&params.camera);
    valid_entry(back_project(cam, [u, v], sum_wz / sum_w))
}

twin! {
    /// `vertex_map` filtered into `filtered_vertex`; shapes, units and frames as declared in
    /// `shaders/bilateral_filter.wgsl`, whose bindings the parameters are, in order.
    pub fn bilateral_filter(
        params: &BilateralParams,
        vertex_map: &[[f32; 4]],
        filtered_vertex: &mut [[f32; 4]],
    ) {
        let w = params.camera.width as usize;
        let pixels = w * params.camera.height as usize;
        assert_eq!(vertex_map.len(), pixels, "vertex_map has the wrong size");
        assert_eq!(filtered_vertex.len(), pixels, "filtered_vertex has the wrong size");
        // The shader's entry, pixel_grid.wgsl: every pixel once, in parallel.
        let filtered_vertex = Storage::new(filtered_vertex);
        pixel_grid(params.camera.width, params.camera.height, |[u, v]| {
            filtered_vertex.store(
                v as usize * w + u as usize,
                filtered_at(params, vertex_map, u, v),
            );
        });
    }
}
