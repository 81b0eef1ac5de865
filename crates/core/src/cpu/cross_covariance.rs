//! CPU twin of `shaders/cross_covariance.wgsl`: per-workgroup f32 partial sums of the
//! inlier pairs' cross-covariance, in the shader's shape (grid-stride accumulation per
//! thread, then a tree reduction over the 64 threads of each workgroup). The host sums the
//! partials in f64 with [`decode`]. Arguments follow the shader's bindings.

use super::binding::twin;
use bytemuck::Zeroable;
use glam::{DMat4, DVec3};

use crate::geometry::align::CrossCovariance;
use crate::geometry::se3;
use crate::layout::scan::{
    ScanCovParams, ScanCovPartial, ScanNnResult, SCAN_NN_NONE, SCAN_WORKGROUP_SIZE,
};

/// Component-wise sum of two partials. Mirrors `scan_cov_add`.
#[inline]
pub fn scan_cov_add(a: &ScanCovPartial, b: &ScanCovPartial) -> ScanCovPartial {
    let add4 = |x: [f32; 4], y: [f32; 4]| std::array::from_fn(|k| x[k] + y[k]);
    ScanCovPartial {
        count_sq: add4(a.count_sq, b.count_sq),
        sum_p: add4(a.sum_p, b.sum_p),
        sum_q: add4(a.sum_q, b.sum_q),
        pq0: add4(a.pq0, b.pq0),
        pq1: add4(a.pq1, b.pq1),
        pq2: add4(a.pq2, b.pq2),
    }
}

/// Adds pair `(p, q)` (already minus the anchor) to a partial. Mirrors `scan_cov_pair`.
#[inline]
pub fn scan_cov_pair(acc: &mut ScanCovPartial, p: [f32; 3], q: [f32; 3]) {
    let d = [p[0] - q[0], p[1] - q[1], p[2] - q[2]];
    acc.count_sq[0] += 1.0;
    acc.count_sq[1] += d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
    acc.count_sq[2] += p[0] * p[0] + p[1] * p[1] + p[2] * p[2];
    acc.count_sq[3] += q[0] * q[0] + q[1] * q[1] + q[2] * q[2];
    for k in 0..3 {
        acc.sum_p[k] += p[k];
        acc.sum_q[k] += q[k];
    }
    for (r, row) in [&mut acc.pq0, &mut acc.pq1, &mut acc.pq2]
        .into_iter()
        .enumerate()
    {
        for k in 0..3 {
            row[k] += p[r] * q[k];
        }
    }
}

twin! {
    /// Reduces the inlier pairs `(queries[i], targets[nn[i].index])` for `i < n_pairs`
    /// (inlier: index valid and `dist_sq <= radius_sq`) into one partial per workgroup;
    /// `partials.len()` is the workgroup count and `params.n_threads` must equal
    /// `partials.len() * 64`.
    ///
    /// Arguments: the shader's bindings in `@binding` order, named as there; see the
    /// declarations in `shaders/cross_covariance.wgsl` for shapes, units and frames.
    pub fn cross_covariance(
        params: &ScanCovParams,
        queries: &[[f32; 4]],
        targets: &[[f32; 4]],
        nn: &[ScanNnResult],
        partials: &mut [ScanCovPartial],
    ) {
        let wg_size = SCAN_WORKGROUP_SIZE as usize;
        assert_eq!(
            params.n_threads as usize,
            partials.len() * wg_size,
            "cross_covariance: n_threads must be workgroups * 64"
        );
        let a = params.anchor;
        for (wg, out) in partials.iter_mut().enumerate() {
            // Each thread's registers, then the workgroup's shared scratch.
            let mut scratch = vec![ScanCovPartial::zeroed(); wg_size];
            for (lid, acc) in scratch.iter_mut().enumerate() {
                let mut i = wg * wg_size + lid;
                while i < params.n_pairs as usize {
                    let r = nn[i];
                    if r.index != SCAN_NN_NONE && r.dist_sq <= params.radius_sq {
                        let s = queries[i];
                        let t = targets[r.index as usize];
                        scan_cov_pair(
                            acc,
                            [s[0] - a[0], s[1] - a[1], s[2] - a[2]],
                            [t[0] - a[0], t[1] - a[1], t[2] - a[2]],
                        );
                    }
                    i += params.n_threads as usize;
                }
            }
            let mut stride = wg_size / 2;
            while stride > 0 {
                for lid in 0..stride {
                    scratch[lid] = scan_cov_add(&scratch[lid], &scratch[lid + stride]);
                }
                stride /= 2;
            }
            *out = scratch[0];
        }
    }
}

/// Sums the partials in f64 into a [`CrossCovariance`] in ANCHOR-SHIFTED coordinates
/// (every point minus `anchor`). Its `solve()` gives `dT'` with `dT = Tr(a) dT' Tr(-a)`,
/// see [`unshift`].
pub fn decode(partials: &[ScanCovPartial]) -> CrossCovariance {
    let mut c = CrossCovariance::default();
    let mut count = 0.0f64;
    for p in partials {
        count += p.count_sq[0] as f64;
        c.sum_sq_dist += p.count_sq[1] as f64;
        c.sum_p_sq += p.count_sq[2] as f64;
        c.sum_q_sq += p.count_sq[3] as f64;
        c.sum_p += DVec3::new(p.sum_p[0] as f64, p.sum_p[1] as f64, p.sum_p[2] as f64);
        c.sum_q += DVec3::new(p.sum_q[0] as f64, p.sum_q[1] as f64, p.sum_q[2] as f64);
        for (dst, row) in c.sum_pq.iter_mut().zip(p.pq()) {
            for (d, v) in dst.iter_mut().zip(row) {
                *d += v as f64;
            }
        }
    }
    // Counts are exact integers in f32 below 2^24 per workgroup.
    c.count = count.round() as usize;
    c
}

/// `Tr(a) * t_shifted * Tr(-a)`: a transform solved in anchor-shifted coordinates, back
/// in the original ones.
pub fn unshift(t_shifted: &DMat4, anchor: [f32; 4]) -> DMat4 {
    let a = DVec3::new(anchor[0] as f64, anchor[1] as f64, anchor[2] as f64);
    let (r, t) = se3::to_rt(t_shifted);
    se3::from_rt(r, t + a - r * a)
}
