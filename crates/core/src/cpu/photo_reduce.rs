//! CPU twin of `shaders/photo_reduce.wgsl`: the photometric term of RGB-D tracking (Kerl,
//! Sturm and Cremers 2013; ElasticFusion's `RGBDOdometry`), frame to model: one
//! intensity-residual row per model pixel, reduced to a 29-float system of the same layout
//! as `icp_reduce`'s, which the host adds to the geometric one with a weight
//! (`crate::slam::tracker`).
//!
//! Runs at one pyramid level: its frame maps (depth, intensity pyramid level) and
//! intrinsics. Source: the level-0 predicted model map (world frame) and its predicted
//! intensity (`predict_model`'s `pred_intensity`, 0..1, [`INTENSITY_NONE`] where no
//! surfel), at pixel `(step u, step v)` for each pixel `(u, v)` of the level
//! (`photo_source_step = 2^level`: the points `pyramid_model` gives the level), moved
//! into the new camera with the current estimate: `p' = T p`. It projects to the
//! sub-pixel position `x = π(p')` (pixel centres at integers). Gates: the four texels
//! around `x` are inside the image; the frame's depth at the texel nearest `x` is valid
//! and within `photo_depth_gate_m` of `p'.z` (occluded points are skipped); the frame
//! intensity gradient at `x` is at least `photo_gradient_min` per pixel. The frame
//! intensity `I` is the bilinear interpolant of those four texels at `x`, and `∇I` its
//! exact gradient there, both from the one intensity patch (`intensity_pyramid`) at the
//! texel left of and above `x` (central differences over the 4x4 neighbourhood measured
//! worse on noisy ICL-NUIM and SUN3D, `docs/rgbd-tracking.md`). Residual `r = I(x) - I_model` (intensity units,
//! 0..1); linearising `T <- exp(ξ) T` as the geometric term does
//! (`ξ = (alpha, beta, gamma, tx, ty, tz)`): `r(ξ) ≈ r + J ξ` with
//! `J = [(p' x g)ᵀ, gᵀ]`, `g = (dπ/dp')ᵀ ∇I = (fx Ix / z, fy Iy / z,
//! -(fx Ix x + fy Iy y) / z²)` (units: intensity per metre). A Huber weight on `r`
//! (`photo_huber`) scales the row by `sqrt(w)`.
//!
//! As `cpu::icp_reduce`'s, the twin's `partials` is one partial system of f64 sums (the
//! shader's one workgroup, its sums wider than the shader's f32; see its notes).

use super::arith;
use super::binding::twin;
use super::{huber_weight, is_valid, transform_point, xyz};
use crate::layout::IcpParams;

/// `pred_intensity` where the pixel has no surfel (intensities are 0..1).
pub const INTENSITY_NONE: f32 = -1.0;

/// Huber threshold on the intensity residual (0..1 units): 0.1, a tenth of the range (25
/// grey levels). Below it a residual is sensor noise and small misalignment; above it,
/// mostly a wrong association (a colour edge offset by a camera not registered to depth,
/// a specularity, exposure change), which the weight `0.1 / |r|` damps.
pub const PHOTO_HUBER: f32 = 0.1;

/// Least frame intensity gradient (0..1 units per pixel) of a used pixel: 0.005, about 1.3
/// grey levels per pixel, above the 8-bit quantisation (0.5 grey level per pixel in a
/// central difference of one step) so that flat texture, whose gradient is noise, adds
/// nothing.
pub const PHOTO_GRADIENT_MIN: f32 = 0.005;

/// The bilinear interpolant of the four texel intensities `i = [i00, i10, i01, i11]`
/// around a point at fractions `(tx, ty)`, and its exact gradient there (intensity per
/// pixel): `[I, Ix, Iy]`. The gradient is the derivative of the very function the residual
/// samples, so the Gauss-Newton row is its true linearisation. Mirrors `bilinear` in
/// photo_reduce.wgsl.
#[inline]
fn bilinear(i: [f32; 4], tx: f32, ty: f32) -> [f32; 3] {
    let [i00, i10, i01, i11] = i;
    let top = i00 + tx * (i10 - i00);
    let bottom = i01 + tx * (i11 - i01);
    let left = i00 + ty * (i01 - i00);
    let right = i10 + ty * (i11 - i10);
    [top + ty * (bottom - top), right - left, bottom - top]
}

/// The weighted photometric row `J` and residual `r` of source pixel `src_texel` (both
/// scaled by `sqrt(weight)`), or `None` when a gate rejects it. Mirrors `photo_row` in
/// photo_reduce.wgsl.
#[inline]
pub fn photo_row(
    params: &IcpParams,
    src_texel: [u32; 2],
    level0_pred_vertex: &[[f32; 4]],
    pred_intensity: &[f32],
    normal_depth: &[[f32; 4]],
    intensity_patch: &[[f32; 4]],
) -> Option<([f32; 6], f32)> {
    let w = params.camera.width;
    let step = params.photo_source_step;
    let src = (step * src_texel[1] * params.photo_source_width + step * src_texel[0]) as usize;
    let src_world = level0_pred_vertex[src];
    let i_model = pred_intensity[src];
    if !is_valid(src_world) || i_model < 0.0 {
        return None;
    }
    let p = transform_point(&params.t_world_to_cam, xyz(src_world));
    if p.z <= 0.0 {
        return None;
    }
    let x = arith::div(params.camera.fx * p.x, p.z) + params.camera.cx;
    let y = arith::div(params.camera.fy * p.y, p.z) + params.camera.cy;
    // The four texels around (x, y) inside the image.
    if !(x >= 0.0 && y >= 0.0 && x < (w - 1) as f32 && y < (params.camera.height - 1) as f32) {
        return None;
    }
    // x, y >= 0: truncation is the floor.
    let (u0, v0) = (x as u32, y as u32);
    let (tx, ty) = (x - u0 as f32, y - v0 as f32);
    let near = [u0 + (tx >= 0.5) as u32, v0 + (ty >= 0.5) as u32];
    let nd = normal_depth[(near[1] * w + near[0]) as usize];
    if !is_valid(nd) || (nd[3] - p.z).abs() >= params.photo_depth_gate_m {
        return None;
    }
    let corners = intensity_patch[(v0 * w + u0) as usize];
    let [i_frame, gx, gy] = bilinear(corners, tx, ty);
    let g_min = params.photo_gradient_min;
    if gx * gx + gy * gy < g_min * g_min {
        return None;
    }
    let r = i_frame - i_model;
    let s = arith::sqrt(huber_weight(r, params.photo_huber));
    let fgx = params.camera.fx * gx;
    let fgy = params.camera.fy * gy;
    let g = glam::Vec3::new(
        arith::div(fgx, p.z),
        arith::div(fgy, p.z),
        -arith::div(arith::div(fgx * p.x + fgy * p.y, p.z), p.z),
    );
    Some(super::entries::scaled_row(p, g, r, s))
}

twin! {
    /// The system of every pixel's row into `partials`, as `icp_reduce` writes it: one
    /// partial system of f64 entries, the shader's one workgroup with f64 sums. The
    /// parameters are the shader's bindings in `@binding` order, named as there (see the
    /// declarations in `shaders/photo_reduce.wgsl` for shapes, units and frames).
    pub fn photo_reduce(
        params: &IcpParams,
        level0_pred_vertex: &[[f32; 4]],
        pred_intensity: &[f32],
        normal_depth: &[[f32; 4]],
        intensity_patch: &[[f32; 4]],
        partials: &mut [f64],
    ) {
        let sys = super::system_grid(params.camera.width, params.camera.height, |texel| {
            photo_row(
                params,
                texel,
                level0_pred_vertex,
                pred_intensity,
                normal_depth,
                intensity_patch,
            )
        });
        super::entries::one_partial(partials).copy_from_slice(&sys);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cpu::binding::Binding;
    use crate::geometry::camera::Intrinsics;
    use crate::geometry::se3;
    use crate::layout::{gpu_mat4, Camera};
    use bytemuck::Zeroable;

    /// Central differences (step `H`) of an f32 residual whose intensity (about 0.5) is
    /// rounded to 6e-8: that rounding over 2 H = 2e-3 is 6e-5 in a derivative of order 1,
    /// so 1e-3 leaves a margin of 15; the image is linear, so the bilinear sample and its
    /// gradient are exact and no curvature term enters.
    const JACOBIAN_TOL: f64 = 1e-3;
    const H: f64 = 1e-3;

    /// Intensity of the synthetic frame at texel (u, v): linear, 0.02 per pixel along u,
    /// -0.01 along v.
    fn ramp(u: u32, v: u32) -> f32 {
        0.3 + 0.02 * u as f32 - 0.01 * v as f32
    }

    /// A 32x24 frame with the [`ramp`] intensity (grey, so luma is exact; as intensity
    /// patches) and depth `z_m` everywhere, and its camera.
    fn frame(z_m: f32) -> (IcpParams, Vec<[f32; 4]>, Vec<[f32; 4]>) {
        let (w, h) = (32u32, 24u32);
        let params = IcpParams {
            t_world_to_cam: gpu_mat4(&glam::DMat4::IDENTITY),
            camera: Camera::new(&Intrinsics {
                width: w,
                height: h,
                fx: 40.0,
                fy: 42.0,
                cx: 15.5,
                cy: 11.5,
            }),
            photo_depth_gate_m: 0.3,
            photo_huber: 0.0,
            photo_gradient_min: PHOTO_GRADIENT_MIN,
            photo_source_step: 1,
            photo_source_width: w,
            ..Zeroable::zeroed()
        };
        let mut color = Vec::new();
        for v in 0..h {
            for u in 0..w {
                let g = 255.0 * ramp(u, v);
                color.push([g, g, g, 255.0]);
            }
        }
        let nd = vec![[0.0, 0.0, -1.0, z_m]; (w * h) as usize];
        (params, patches(w, h, &color), nd)
    }

    /// The level-0 intensity patches of a `w` x `h` colour map (`intensity_pyramid`).
    fn patches(w: u32, h: u32, color: &[[f32; 4]]) -> Vec<[f32; 4]> {
        let mut out = vec![[0.0f32; 4]; color.len()];
        let p = crate::layout::IntensityParams::levels(w, h, &[])[0];
        crate::cpu::intensity_pyramid::intensity_pyramid(&mut [
            Binding::of(&p),
            Binding::read(color),
            Binding::write(&mut out),
        ]);
        out
    }

    /// The row of one model point `p` (world frame) with intensity `i_model`, put at texel
    /// (0, 0) of an otherwise empty prediction.
    fn row_of(
        params: &IcpParams,
        p: glam::DVec3,
        i_model: f32,
        nd: &[[f32; 4]],
        color: &[[f32; 4]],
    ) -> Option<([f32; 6], f32)> {
        let n = nd.len();
        let mut pv = vec![[0.0; 4]; n];
        let mut pi = vec![INTENSITY_NONE; n];
        pv[0] = [p.x as f32, p.y as f32, p.z as f32, 1.0];
        pi[0] = i_model;
        photo_row(params, [0, 0], &pv, &pi, nd, color)
    }

    /// The analytic row matches finite differences of the residual the kernel itself
    /// computes, `I(π(exp(ξ) T p)) - I_model`, around ξ = 0, at a pose off the identity.
    #[test]
    fn jacobian_matches_finite_differences() {
        let (params, color, nd) = frame(2.0);
        let t = se3::exp(&[0.02, -0.03, 0.01, 0.05, -0.02, 0.03]);
        let p = t
            .inverse()
            .transform_point3(glam::DVec3::new(0.23, -0.17, 2.05));
        let at = |x: &[f64; 6]| {
            let params = IcpParams {
                t_world_to_cam: gpu_mat4(&(se3::exp(x) * t)),
                ..params
            };
            row_of(&params, p, 0.4, &nd, &color).expect("the point passes every gate")
        };
        let (a, r) = at(&[0.0; 6]);
        assert!(r.abs() > 0.01, "a residual to linearise: {r}");
        for k in 0..6 {
            let (mut xp, mut xm) = ([0.0; 6], [0.0; 6]);
            xp[k] = H;
            xm[k] = -H;
            let fd = (at(&xp).1 as f64 - at(&xm).1 as f64) / (2.0 * H);
            assert!(
                (fd - a[k] as f64).abs() < JACOBIAN_TOL,
                "d r / d xi[{k}]: analytic {} vs finite difference {fd}",
                a[k]
            );
        }
    }

    /// The gates: no model intensity, behind the camera, too near the border for the
    /// 4x4 taps, a frame depth beyond the gate (occlusion), a flat image; and the Huber
    /// weight scales the row by sqrt(w).
    #[test]
    fn gates_and_weight() {
        let (params, color, nd) = frame(2.0);
        let centre = glam::DVec3::new(0.0, 0.0, 2.0);
        let (a, r) = row_of(&params, centre, 0.4, &nd, &color).expect("centre passes");
        assert!(row_of(&params, centre, INTENSITY_NONE, &nd, &color).is_none());
        assert!(
            row_of(&params, -centre, 0.4, &nd, &color).is_none(),
            "behind"
        );
        // x = 40 * 0.78 / 2 + 15.5 = 31.1: no texel to the right.
        let edge = glam::DVec3::new(0.78, 0.0, 2.0);
        assert!(row_of(&params, edge, 0.4, &nd, &color).is_none(), "border");
        let far = glam::DVec3::new(0.0, 0.0, 2.5);
        assert!(row_of(&params, far, 0.4, &nd, &color).is_none(), "occluded");
        let flat = patches(32, 24, &vec![[100.0, 100.0, 100.0, 255.0]; color.len()]);
        assert!(row_of(&params, centre, 0.4, &nd, &flat).is_none(), "flat");
        let huber = IcpParams {
            photo_huber: 0.01,
            ..params
        };
        let (a2, r2) = row_of(&huber, centre, 0.4, &nd, &color).unwrap();
        let s = (0.01 / r.abs()).sqrt();
        assert!((r2 - r * s).abs() < 1e-6, "{r2} vs {}", r * s);
        assert!((a2[3] - a[3] * s).abs() < 1e-5);
    }
}
