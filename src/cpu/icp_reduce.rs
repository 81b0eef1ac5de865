//! CPU twin of `shaders/icp_reduce.wgsl`: projective data association, both filters, the
//! point-to-plane row and the reduction to the 29-float normal-equation system.
//!
//! Source: the predicted model map (world frame), one point per pixel, moved into the
//! new camera with the current estimate `T_world_to_cam`: `p' = T p`. Filter 1: `p'`
//! projects inside the image with `z > 0`, onto a pixel whose `normal_depth` texel is valid
//! (a valid normal implies a valid target vertex, depth > 0). Filter 2:
//! `|p' - q| < dist_threshold_m`. Target `q`, `n_q`: the new frame's vertex (rebuilt from
//! the texel's depth with `back_project`) and normal, camera frame. Linearising
//! `T <- exp(x) T` with `x = (alpha, beta, gamma, tx, ty, tz)` gives the residual
//! `r = A x + b` with `A = [(p' x n_q)ᵀ, n_qᵀ]` and `b = n_qᵀ (p' - q)`; the least-squares
//! increment solves `AᵀA x = -Aᵀb` (see `crate::slam::solve`).

use super::{back_project, is_valid, project_to_texel, transform_point, xyz};
use crate::layout::{
    IcpParams, ICP_ATB_OFFSET, ICP_COUNT_INDEX, ICP_RESIDUAL_INDEX, ICP_SYSTEM_LEN,
};

/// One correspondence's Jacobian row `A` and residual `b`, or `None` when a filter rejects
/// it. Mirrors `icp_row` in icp_reduce.wgsl.
#[inline]
pub fn icp_row(
    params: &IcpParams,
    src_world: [f32; 4],
    normal_depth: &[[f32; 4]],
) -> Option<([f32; 6], f32)> {
    if !is_valid(src_world) {
        return None;
    }
    let cam = [params.fx, params.fy, params.cx, params.cy];
    let p = transform_point(&params.t_world_to_cam, xyz(src_world));
    let target_texel = project_to_texel(cam, params.width, params.height, p)?;
    // Valid normal (w = depth > 0) implies a valid vertex.
    let nd =
        normal_depth[target_texel[1] as usize * params.width as usize + target_texel[0] as usize];
    if !is_valid(nd) {
        return None;
    }
    let q = back_project(cam, target_texel, nd[3]);
    let n = xyz(nd);
    let d = p - q;
    if d.length() >= params.dist_threshold_m {
        return None;
    }
    let pxn = p.cross(n);
    Some(([pxn.x, pxn.y, pxn.z, n.x, n.y, n.z], n.dot(d)))
}

/// Adds one row to a 29-entry system: 21 of AᵀA (upper triangle, row-major), 6 of Aᵀb,
/// the count and the squared residual. Mirrors `accumulate` in icp_reduce.wgsl.
#[inline]
pub fn accumulate(sys: &mut [f64; ICP_SYSTEM_LEN], a: &[f32; 6], b: f32) {
    let mut k = 0;
    for r in 0..6 {
        for c in r..6 {
            sys[k] += a[r] as f64 * a[c] as f64;
            k += 1;
        }
    }
    for r in 0..6 {
        sys[ICP_ATB_OFFSET + r] += a[r] as f64 * b as f64;
    }
    sys[ICP_COUNT_INDEX] += 1.0;
    sys[ICP_RESIDUAL_INDEX] += b as f64 * b as f64;
}

/// Bindings (as in the shader header):
/// - 0 `params`: `IcpParams` (current `t_world_to_cam`, intrinsics, `dist_threshold_m`)
/// - 1 `pred_vertex`: source, width x height, WORLD frame, w = 1 / 0
/// - 2 `normal_depth`: target normals (camera frame) with the target vertex's depth in w,
///   zero where invalid (see `vertex_to_normal`)
/// - 3 `partials`: returned instead of written: the summed system (the GPU writes one f32
///   partial per workgroup; the host sums them in f64)
pub fn icp_reduce(
    params: &IcpParams,
    pred_vertex: &[[f32; 4]],
    normal_depth: &[[f32; 4]],
) -> [f64; ICP_SYSTEM_LEN] {
    let mut sys = [0.0f64; ICP_SYSTEM_LEN];
    for src in pred_vertex {
        if let Some((a, b)) = icp_row(params, *src, normal_depth) {
            accumulate(&mut sys, &a, b);
        }
    }
    sys
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::se3;
    use crate::layout::gpu_mat4;

    /// Central differences in f64 of an f32 residual: error ~ h^2 plus f32 rounding / h.
    const JACOBIAN_TOL: f64 = 2e-3;

    /// The analytic row matches finite differences of the exact residual
    /// `n_qᵀ (exp(x) p' - q)` around x = 0.
    #[test]
    fn jacobian_matches_finite_differences() {
        let n = glam::DVec3::new(0.2, 0.3, -0.9).normalize();
        let p = glam::DVec3::new(0.12, -0.18, 2.01);
        let z_q = 2.0f32;
        let params = IcpParams {
            t_world_to_cam: gpu_mat4(&glam::DMat4::IDENTITY),
            fx: 10.0,
            fy: -10.0,
            cx: 2.0,
            cy: 2.0,
            width: 5,
            height: 5,
            dist_threshold_m: 0.5,
            _pad: 0,
        };
        // A target map where every pixel holds n at depth z_q; q is the vertex of the pixel
        // p lands on.
        let nd = vec![[n.x as f32, n.y as f32, n.z as f32, z_q]; 25];
        let cam = [params.fx, params.fy, params.cx, params.cy];
        let p32 = glam::Vec3::new(p.x as f32, p.y as f32, p.z as f32);
        let texel = project_to_texel(cam, 5, 5, p32).expect("p projects into the image");
        let q = back_project(cam, texel, z_q).as_dvec3();
        let resid = |x: &[f64; 6]| -> f64 {
            let t = se3::exp(x);
            n.dot(t.transform_point3(p) - q)
        };
        let (a, b) = icp_row(&params, [p.x as f32, p.y as f32, p.z as f32, 1.0], &nd)
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

    /// Filter 1 rejects points behind the camera or outside the image, filter 2 far ones.
    #[test]
    fn filters_reject() {
        let params = IcpParams {
            t_world_to_cam: gpu_mat4(&glam::DMat4::IDENTITY),
            fx: 100.0,
            fy: 100.0,
            cx: 1.0,
            cy: 1.0,
            width: 3,
            height: 3,
            dist_threshold_m: 0.07,
            _pad: 0,
        };
        // Normal (0, 0, -1) at depth 1 m everywhere: the centre pixel's vertex is (0, 0, 1).
        let nd = vec![[0.0, 0.0, -1.0, 1.0]; 9];
        let row = |p: [f32; 4]| icp_row(&params, p, &nd);
        assert!(row([0.0, 0.0, 1.05, 1.0]).is_some());
        assert!(row([0.0, 0.0, -1.0, 1.0]).is_none(), "behind the camera");
        assert!(row([1.0, 0.0, 1.0, 1.0]).is_none(), "outside the image");
        assert!(row([0.0, 0.0, 1.08, 1.0]).is_none(), "farther than 0.07 m");
        assert!(row([0.0, 0.0, 1.0, 0.0]).is_none(), "invalid source");
        let mut holes = nd.clone();
        holes[4] = [0.0; 4];
        assert!(icp_row(&params, [0.0, 0.0, 1.0, 1.0], &holes).is_none());
    }
}
