//! CPU twin of `shaders/icp_candidates.wgsl`: how many source pixels pass ICP's filter 1
//! at a pose (the predicted point moved into the camera projects inside the image onto a
//! texel with a valid normal), the denominator of the tracking-health inlier fraction
//! (`slam::health`). The same test as the first half of `icp_row` (`cpu::icp_reduce`).

use super::binding::twin;
use super::invocations::par_sum_rows;
use super::{is_valid, project_to_texel, transform_point, xyz};
use crate::layout::IcpParams;

/// Whether source pixel `src_texel` passes filter 1. Mirrors `is_candidate` in
/// icp_candidates.wgsl.
pub fn is_candidate(
    p: &IcpParams,
    src_texel: [u32; 2],
    pred_vertex: &[[f32; 4]],
    normal_depth: &[[f32; 4]],
) -> bool {
    let src_world = pred_vertex[(src_texel[1] * p.camera.width + src_texel[0]) as usize];
    if !is_valid(src_world) {
        return false;
    }
    let cam = super::camera_intrinsics(&p.camera);
    let q = transform_point(&p.t_world_to_cam, xyz(src_world));
    match project_to_texel(cam, p.camera.width, p.camera.height, q) {
        Some(t) => is_valid(normal_depth[(t[1] * p.camera.width + t[0]) as usize]),
        None => false,
    }
}

/// Threads of each of the shader's workgroups (`WORKGROUP_SIZE` in icp_candidates.wgsl).
pub const WORKGROUP_SIZE: usize = 64;

twin! {
    /// The candidates of each workgroup into `counts`, one entry per workgroup the
    /// shader's grid-stride loop runs (`counts.len()` of them: the host sums them; the CPU
    /// backend binds one, so its one entry is the total): pixel `pix` is thread
    /// `pix % (counts.len() * WORKGROUP_SIZE)`'s, of workgroup that / `WORKGROUP_SIZE`. The
    /// parameters are the shader's bindings in `@binding` order, named as there (see the
    /// declarations in `shaders/icp_candidates.wgsl` for shapes, units and frames).
    pub fn icp_candidates(
        params: &IcpParams,
        pred_vertex: &[[f32; 4]],
        normal_depth: &[[f32; 4]],
        counts: &mut [u32],
    ) {
        let w = params.camera.width as usize;
        let stride = counts.len() * WORKGROUP_SIZE;
        // Every pixel's test on every thread: whole counts, whose sum no order changes.
        let summed = par_sum_rows(
            w * params.camera.height as usize,
            || vec![0u32; counts.len()],
            |partial, pix| {
                let texel = [(pix % w) as u32, (pix / w) as u32];
                let candidate = is_candidate(params, texel, pred_vertex, normal_depth);
                partial[pix % stride / WORKGROUP_SIZE] += candidate as u32;
            },
            |total, partial| total.iter_mut().zip(partial).for_each(|(t, p)| *t += p),
        );
        counts.copy_from_slice(&summed);
    }
}
