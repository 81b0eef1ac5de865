//! CPU twin of `shaders/icp_reduce.wgsl`: projective data association, both filters, the
//! weighted point-to-plane row and the reduction to the 29-float normal-equation system.
//!
//! Source: the predicted model map (world frame), one point per pixel, moved into the
//! new camera with the current estimate `T_world_to_cam`: `p' = T p`. Filter 1: `p'`
//! projects inside the image with `z > 0`, onto a pixel whose `normal_depth` texel is valid
//! (a valid normal implies a valid target vertex, depth > 0). Filter 2:
//! `|p' - q| < dist_m` and, when the angle gate is on
//! (`cos_normal_threshold >= -1`), the model normal moved into the camera, `R n_p`, and
//! the frame normal `n_q` have a cosine above `cos_normal_threshold`. Target `q`, `n_q`:
//! the new frame's vertex (rebuilt from the texel's depth with `back_project`) and normal,
//! camera frame. Linearising `T <- exp(x) T` with `x = (alpha, beta, gamma, tx, ty, tz)`
//! gives the residual `r = A x + b` with `A = [(p' x n_q)ᵀ, n_qᵀ]` and
//! `b = n_qᵀ (p' - q)`; the least-squares increment solves `AᵀA x = -Aᵀb` (see
//! `crate::slam::solve`).
//!
//! Weights (robust profile; both off in the assignment's): a Huber weight on `b`
//! ([`super::huber_weight`]) times a depth-noise weight of the target depth ([`noise_weight`]).
//! The row is scaled by `sqrt(w)`, so the system stays 29 floats: AᵀWA, AᵀWb, the inlier
//! count and the weighted squared residuals. With both off `w` is exactly 1 and the row
//! is the unweighted one bit for bit.
//!
//! The reduction's element is the CPU's own: where the shader writes one f32 partial
//! system per workgroup, the twin runs as one workgroup whose sums are f64 (every row in
//! pixel order, `cpu::system_grid`) and its `partials` binding is one system of f64
//! entries, which `cpu::icp_reduce_final` gives back unchanged: the CPU backend's systems
//! are f64 sums, as they were before the one call shape (`docs/extending.md`, "The
//! reductions' f64 system"; `tests/it/bindings.rs`'s `CPU_F64` allows exactly this).

use super::binding::twin;
use super::{
    back_project, huber_weight, is_valid, project_to_texel, transform_dir, transform_point, xyz,
};
use crate::layout::IcpParams;

/// Axial depth noise of a Kinect-like sensor, after Nguyen, Izadi and Lovell (2012):
/// `sigma(z) = NOISE_SIGMA_0_M + NOISE_SIGMA_QUAD (z - NOISE_Z_0_M)^2`, metres.
pub const NOISE_SIGMA_0_M: f32 = 0.0012;
pub const NOISE_SIGMA_QUAD: f32 = 0.0019;
pub const NOISE_Z_0_M: f32 = 0.4;

/// Row weight of the depth noise at `z` (metres): `(sigma(0.4 m) / sigma(z))^2`, 1 at
/// 0.4 m and less beyond. Mirrors `noise_weight` in icp_reduce.wgsl.
#[inline]
pub fn noise_weight(z: f32) -> f32 {
    let dz = z - NOISE_Z_0_M;
    let sigma = NOISE_SIGMA_0_M + NOISE_SIGMA_QUAD * dz * dz;
    let r = NOISE_SIGMA_0_M / sigma;
    r * r
}

/// The weighted Jacobian row `A` and residual `b` of source pixel `src_texel` (both scaled
/// by `sqrt(weight)`), or `None` when a filter rejects it. Mirrors `icp_row` in
/// icp_reduce.wgsl.
#[inline]
pub fn icp_row(
    params: &IcpParams,
    src_texel: [u32; 2],
    pred_vertex: &[[f32; 4]],
    pred_normal: &[[f32; 4]],
    normal_depth: &[[f32; 4]],
) -> Option<([f32; 6], f32)> {
    let src = src_texel[1] as usize * params.camera.width as usize + src_texel[0] as usize;
    let src_world = pred_vertex[src];
    if !is_valid(src_world) {
        return None;
    }
    let cam = super::camera_intrinsics(&params.camera);
    let p = transform_point(&params.t_world_to_cam, xyz(src_world));
    let target_texel = project_to_texel(cam, params.camera.width, params.camera.height, p)?;
    // Valid normal (w = depth > 0) implies a valid vertex.
    let nd = normal_depth
        [target_texel[1] as usize * params.camera.width as usize + target_texel[0] as usize];
    if !is_valid(nd) {
        return None;
    }
    let q = back_project(cam, target_texel, nd[3]);
    let n = xyz(nd);
    let d = p - q;
    if super::arith::length(d) >= params.dist_m {
        return None;
    }
    // The angle gate reads the source normal only when it is on.
    if params.cos_normal_threshold >= -1.0 {
        let src_normal_world = pred_normal[src];
        let n_p = transform_dir(&params.t_world_to_cam, xyz(src_normal_world));
        if !is_valid(src_normal_world) || n_p.dot(n) <= params.cos_normal_threshold {
            return None;
        }
    }
    let b = n.dot(d);
    let mut w = huber_weight(b, params.huber_m);
    if params.noise_weighting != 0 {
        w *= noise_weight(q.z);
    }
    Some(super::entries::scaled_row(p, n, b, super::arith::sqrt(w)))
}

pub use super::entries::accumulate;

twin! {
    /// The system of every pixel's row into `partials`, as one workgroup of the shader
    /// whose sums are f64: the CPU's `partials` is one partial system of f64 entries (the
    /// shader writes one f32 partial per workgroup; see `cpu::icp_reduce_final` for their
    /// sum, and `docs/extending.md` for why the CPU's element is wider). The parameters are
    /// the shader's bindings in `@binding` order, named as there (see the declarations in
    /// `shaders/icp_reduce.wgsl` for shapes, units and frames).
    pub fn icp_reduce(
        params: &IcpParams,
        pred_vertex: &[[f32; 4]],
        pred_normal: &[[f32; 4]],
        normal_depth: &[[f32; 4]],
        partials: &mut [f64],
    ) {
        let sys = super::system_grid(params.camera.width, params.camera.height, |texel| {
            icp_row(params, texel, pred_vertex, pred_normal, normal_depth)
        });
        super::entries::one_partial(partials).copy_from_slice(&sys);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::camera::Intrinsics;
    use crate::geometry::se3;
    use crate::layout::{gpu_mat4, Camera};
    use bytemuck::Zeroable;

    /// Central differences in f64 of an f32 residual: error ~ h^2 plus f32 rounding / h.
    const JACOBIAN_TOL: f64 = 2e-3;

    /// Gates and weights off: the assignment's filters.
    fn plain(params: IcpParams) -> IcpParams {
        IcpParams {
            cos_normal_threshold: -2.0,
            huber_m: 0.0,
            noise_weighting: 0,
            ..params
        }
    }

    /// The row of one source point `p` (world frame) with normal `n_p`, put at texel (0, 0)
    /// of an otherwise empty prediction.
    fn row_of(
        params: &IcpParams,
        p: [f32; 4],
        n_p: [f32; 4],
        nd: &[[f32; 4]],
    ) -> Option<([f32; 6], f32)> {
        let n = (params.camera.width * params.camera.height) as usize;
        let mut pv = vec![[0.0; 4]; n];
        let mut pn = vec![[0.0; 4]; n];
        pv[0] = p;
        pn[0] = n_p;
        icp_row(params, [0, 0], &pv, &pn, nd)
    }

    /// The analytic row matches finite differences of the exact residual
    /// `n_qᵀ (exp(x) p' - q)` around x = 0.
    #[test]
    fn jacobian_matches_finite_differences() {
        let n = glam::DVec3::new(0.2, 0.3, -0.9).normalize();
        let p = glam::DVec3::new(0.12, -0.18, 2.01);
        let z_q = 2.0f32;
        let params = IcpParams {
            t_world_to_cam: gpu_mat4(&glam::DMat4::IDENTITY),
            camera: Camera::new(&Intrinsics {
                width: 5,
                height: 5,
                fx: 10.0,
                fy: -10.0,
                cx: 2.0,
                cy: 2.0,
            }),
            dist_m: 0.5,
            ..Zeroable::zeroed()
        };
        let params = plain(params);
        // A target map where every pixel holds n at depth z_q; q is the vertex of the pixel
        // p lands on.
        let nd = vec![[n.x as f32, n.y as f32, n.z as f32, z_q]; 25];
        let cam = crate::cpu::camera_intrinsics(&params.camera);
        let p32 = glam::Vec3::new(p.x as f32, p.y as f32, p.z as f32);
        let texel = project_to_texel(cam, 5, 5, p32).expect("p projects into the image");
        let q = back_project(cam, texel, z_q).as_dvec3();
        let resid = |x: &[f64; 6]| -> f64 {
            let t = se3::exp(x);
            n.dot(t.transform_point3(p) - q)
        };
        let (a, b) = row_of(
            &params,
            [p.x as f32, p.y as f32, p.z as f32, 1.0],
            [0.0; 4],
            &nd,
        )
        .expect("the correspondence passes both filters");
        assert!((b as f64 - resid(&[0.0; 6])).abs() < 1e-6);
        let h = 1e-4;
        for k in 0..6 {
            let (mut xp, mut xm) = ([0.0; 6], [0.0; 6]);
            xp[k] = h;
            xm[k] = -h;
            let fd = (resid(&xp) - resid(&xm)) / (2.0 * h);
            assert!(
                (fd - a[k] as f64).abs() < JACOBIAN_TOL,
                "d r / d x[{k}]: analytic {} vs finite difference {fd}",
                a[k]
            );
        }
    }

    /// A 3x3 camera at the identity, f = 100 px, with distance gate `dist_m` and no
    /// angle gate or weights.
    fn params_3x3(dist_m: f32) -> IcpParams {
        plain(IcpParams {
            t_world_to_cam: gpu_mat4(&glam::DMat4::IDENTITY),
            camera: Camera::new(&Intrinsics {
                width: 3,
                height: 3,
                fx: 100.0,
                fy: 100.0,
                cx: 1.0,
                cy: 1.0,
            }),
            dist_m,
            ..Zeroable::zeroed()
        })
    }

    /// Filter 1 rejects points behind the camera or outside the image, filter 2 far ones.
    #[test]
    fn filters_reject() {
        let params = plain(params_3x3(0.07));
        // Normal (0, 0, -1) at depth 1 m everywhere: the centre pixel's vertex is (0, 0, 1).
        let nd = vec![[0.0, 0.0, -1.0, 1.0]; 9];
        let row = |p: [f32; 4]| row_of(&params, p, [0.0; 4], &nd);
        assert!(row([0.0, 0.0, 1.05, 1.0]).is_some());
        assert!(row([0.0, 0.0, -1.0, 1.0]).is_none(), "behind the camera");
        assert!(row([1.0, 0.0, 1.0, 1.0]).is_none(), "outside the image");
        assert!(row([0.0, 0.0, 1.08, 1.0]).is_none(), "farther than 0.07 m");
        assert!(row([0.0, 0.0, 1.0, 0.0]).is_none(), "invalid source");
        let mut holes = nd.clone();
        holes[4] = [0.0; 4];
        assert!(row_of(&params, [0.0, 0.0, 1.0, 1.0], [0.0; 4], &holes).is_none());
    }

    /// The angle gate rejects a model normal turned away from the frame normal and keeps
    /// an aligned one; the Huber and noise weights scale the row by sqrt(w).
    #[test]
    fn angle_gate_and_weights() {
        let params = IcpParams {
            cos_normal_threshold: 20f32.to_radians().cos(),
            ..params_3x3(0.1)
        };
        let nd = vec![[0.0, 0.0, -1.0, 1.0]; 9];
        let toward = [0.0, 0.0, -1.0, 1.0];
        let tilted = [
            0.0,
            30f32.to_radians().sin(),
            -30f32.to_radians().cos(),
            1.0,
        ];
        let p = [0.0, 0.0, 1.05, 1.0];
        let (a1, b1) = row_of(&params, p, toward, &nd).expect("aligned normals pass");
        assert!(row_of(&params, p, tilted, &nd).is_none(), "30 degrees > 20");
        assert!(
            row_of(&params, p, [0.0; 4], &nd).is_none(),
            "invalid model normal"
        );
        // Huber: |b| = 0.05 > delta = 0.01 gives w = 0.2; the row scales by sqrt(0.2).
        let huber = IcpParams {
            huber_m: 0.01,
            ..params
        };
        let (a2, b2) = row_of(&huber, p, toward, &nd).unwrap();
        let s = 0.2f32.sqrt();
        assert!((b2 - b1 * s).abs() < 1e-6, "{b2} vs {}", b1 * s);
        assert!((a2[5] - a1[5] * s).abs() < 1e-6);
        // Noise: 1 at 0.4 m, falling with depth; the row at 1 m depth is scaled by it.
        assert_eq!(noise_weight(NOISE_Z_0_M), 1.0);
        assert!(noise_weight(3.0) < noise_weight(1.0) && noise_weight(1.0) < 1.0);
        let noisy = IcpParams {
            noise_weighting: 1,
            ..params
        };
        let (_, b3) = row_of(&noisy, p, toward, &nd).unwrap();
        assert!((b3 - b1 * noise_weight(1.0).sqrt()).abs() < 1e-6);
    }
}
