//! CPU twin of `shaders/pyramid_depth.wgsl`: the next coarser level of the frame's ICP
//! pyramid, an edge-aware average of the finer level's depth (the pyramid step of
//! KinectFusion, Newcombe et al. 2011, section 3.5).
//!
//! Sampling convention: coarse pixel `(u, v)` samples finer pixel `(2u, 2v)`, the
//! convention of `depth_to_vertex`'s stride and of [`crate::geometry::camera::Intrinsics::downsampled`]:
//! the coarse intrinsics are the finer ones halved (`fx' = fx / 2`, `cx' = cx / 2`), so
//! back-projecting `(u, v)` with them at a depth equals back-projecting `(2u, 2v)` with the
//! finer ones, and the coarse size is the finer size halved, rounded up.
//!
//! Rule: invalid where the sampled pixel `(2u, 2v)` is invalid (no hole filling); else the
//! plain mean of the valid depths `z_n` in the `(2 radius_px + 1)²` window around it
//! (clipped at the border) with `|z_n - z| <= max_depth_diff_m + max_depth_diff_per_m2 z²`,
//! `z` the sampled pixel's depth (which always passes, so the mean has at least one term).
//! The gate keeps the mean on the sampled pixel's side of a depth edge, so edges stay sharp
//! at every level; inside the gate the window halves the noise's standard deviation per
//! level as an unweighted mean of up to 9 (radius 1) depths does. The output is the vertex
//! re-built from the mean depth with [`super::back_project`] at the coarse intrinsics.
//! The window is symmetric about the sampled pixel, so on a plane facing the camera the
//! mean stays at the sampled pixel's depth and the sampling convention holds.

use super::binding::twin;
use super::invocations::Storage;
use super::{back_project, is_valid, pixel_grid, valid_entry, INVALID};
use crate::layout::PyramidParams;

/// The coarse vertex of pixel `(u, v)`, or [`INVALID`] (the rules of the module header).
/// Mirrors `coarse_at` in pyramid_depth.wgsl.
pub fn coarse_at(params: &PyramidParams, fine_vertex: &[[f32; 4]], u: u32, v: u32) -> [f32; 4] {
    let fw = params.fine_width as usize;
    let load = |u: u32, v: u32| fine_vertex[v as usize * fw + u as usize];
    let fu = 2 * u;
    let fv = 2 * v;
    let c = load(fu, fv);
    if !is_valid(c) {
        return INVALID;
    }
    let r = params.radius_px;
    // The shader's `select(fu - r, 0u, fu < r)`.
    let u_lo = fu.saturating_sub(r);
    let v_lo = fv.saturating_sub(r);
    let u_hi = (fu + r).min(params.fine_width - 1);
    let v_hi = (fv + r).min(params.fine_height - 1);
    let gate = params.max_depth_diff_m + params.max_depth_diff_per_m2 * c[2] * c[2];
    let mut sum_z = 0.0f32;
    let mut count = 0.0f32;
    for nv in v_lo..=v_hi {
        for nu in u_lo..=u_hi {
            let n = load(nu, nv);
            if is_valid(n) && (n[2] - c[2]).abs() <= gate {
                sum_z += n[2];
                count += 1.0;
            }
        }
    }
    let cam = super::camera_intrinsics(&params.camera);
    valid_entry(back_project(cam, [u, v], sum_z / count))
}

twin! {
    /// A coarser level's vertex map from its finer level's (`fine_vertex`): the parameters
    /// are the shader's bindings in `@binding` order, named as there (see the declarations
    /// in `shaders/pyramid_depth.wgsl` for shapes, units and frames).
    pub fn pyramid_depth(
        params: &PyramidParams,
        fine_vertex: &[[f32; 4]],
        vertex_map: &mut [[f32; 4]],
    ) {
        let (w, h) = (params.camera.width as usize, params.camera.height as usize);
        assert_eq!(
            fine_vertex.len(),
            (params.fine_width * params.fine_height) as usize,
            "fine_vertex has the wrong size"
        );
        assert_eq!(vertex_map.len(), w * h, "vertex_map has the wrong size");
        assert!(
            2 * params.camera.width - 1 <= params.fine_width
                && 2 * params.camera.height - 1 <= params.fine_height,
            "a {w}x{h} level does not sample a {}x{} one",
            params.fine_width,
            params.fine_height
        );
        // The shader's entry, pixel_grid.wgsl: every pixel once, in parallel.
        let vertex_map = Storage::new(vertex_map);
        pixel_grid(params.camera.width, params.camera.height, |[u, v]| {
            vertex_map.store(
                v as usize * w + u as usize,
                coarse_at(params, fine_vertex, u, v),
            );
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cpu::binding::Binding;
    use crate::geometry::camera::Intrinsics;

    fn params(fine: Intrinsics, radius_px: u32, gate_m: f32) -> PyramidParams {
        PyramidParams::halving(&fine, radius_px, gate_m, 0.0)
    }

    /// A fronto-parallel plane keeps its depth, and each coarse vertex is the finer vertex
    /// it samples, bit for bit up to the halved intrinsics' rounding (the convention of the
    /// module header).
    #[test]
    fn a_plane_keeps_the_sampled_pixels() {
        let fine = Intrinsics {
            width: 9,
            height: 7,
            fx: 10.0,
            fy: -12.0,
            cx: 4.0,
            cy: 3.0,
        };
        let cam = fine.floats();
        let z = 2.0;
        let fine_map: Vec<[f32; 4]> = (0..fine.pixels())
            .map(|i| {
                let t = [(i % 9) as u32, (i / 9) as u32];
                valid_entry(back_project(cam, t, z))
            })
            .collect();
        let p = params(fine, 1, 0.05);
        assert_eq!((p.camera.width, p.camera.height), (5, 4));
        let mut out = vec![INVALID; 20];
        pyramid_depth(&mut [
            Binding::of(&p),
            Binding::read(&fine_map),
            Binding::write(&mut out),
        ]);
        for v in 0..4u32 {
            for u in 0..5u32 {
                let c = out[(v * 5 + u) as usize];
                let f = fine_map[(2 * v * 9 + 2 * u) as usize];
                for k in 0..3 {
                    assert!((c[k] - f[k]).abs() < 1e-6, "({u}, {v}): {c:?} vs {f:?}");
                }
                assert_eq!(c[3], 1.0);
            }
        }
    }

    /// Depths beyond the gate (the other side of an edge) and invalid pixels are left out;
    /// an invalid sampled pixel gives an invalid coarse pixel.
    #[test]
    fn the_gate_keeps_edges() {
        let fine = Intrinsics {
            width: 4,
            height: 4,
            fx: 10.0,
            fy: 10.0,
            cx: 2.0,
            cy: 2.0,
        };
        let cam = fine.floats();
        // Column 0-1: 1.0 m and 1.02 m alternating rows; column 2-3: 3 m (an edge).
        let mut fine_map = vec![INVALID; 16];
        for v in 0..4u32 {
            for u in 0..4u32 {
                let z = if u >= 2 {
                    3.0
                } else if v % 2 == 0 {
                    1.0
                } else {
                    1.02
                };
                fine_map[(v * 4 + u) as usize] = valid_entry(back_project(cam, [u, v], z));
            }
        }
        fine_map[5] = INVALID; // (1, 1)
        fine_map[10] = INVALID; // (2, 2): coarse (1, 1) samples it
        let p = params(fine, 1, 0.1);
        let mut out = vec![INVALID; 4];
        pyramid_depth(&mut [
            Binding::of(&p),
            Binding::read(&fine_map),
            Binding::write(&mut out),
        ]);
        // Coarse (0, 0) samples (0, 0) at 1.0 m: window (0..=1, 0..=1) minus the invalid
        // (1, 1): 1.0, 1.0, 1.02 -> mean 1.00667; the 3 m column is outside the window.
        assert!((out[0][2] - 3.02 / 3.0).abs() < 1e-6, "{:?}", out[0]);
        // Coarse (1, 0) samples (2, 0) at 3 m: the 1 m / 1.02 m pixel (1, 0..=1) is beyond
        // the gate, so the mean is 3 m.
        assert_eq!(out[1][2], 3.0);
        // Coarse (0, 1) samples (0, 2) at 1.0 m: rows 1..=3 of columns 0..=1 minus (1, 1).
        let expect = (1.02 + 1.0 + 1.0 + 1.02 + 1.02) / 5.0;
        assert!((out[2][2] - expect).abs() < 1e-6, "{:?}", out[2]);
        assert_eq!(out[3], INVALID);
    }
}
