//! CPU twin of `shaders/nn_brute.wgsl`: the nearest target point of each query by brute
//! force, reported only within the radius. Arguments follow the shader's bindings.
//!
//! Ties (equal squared distances) go to the lower target index, in both twins, so the
//! brute-force and grid kernels agree exactly on the CPU.

use super::binding::twin;
use super::{scan_closer, scan_dist_sq};
use crate::layout::scan::{ScanNnParams, ScanNnResult, SCAN_NN_NONE};

twin! {
    /// For every query (`params.n_queries` of `queries`, metres), the nearest of targets
    /// `params.target_begin..params.target_end`, continuing from `results` when
    /// `target_begin > 0`; when `target_end == n_targets`, `index = SCAN_NN_NONE` if the
    /// nearest is beyond `radius_sq`. `results` has one entry per query.
    ///
    /// Arguments: the shader's bindings in `@binding` order, named as there; see the
    /// declarations in `shaders/nn_brute.wgsl` for shapes, units and frames.
    pub fn nn_brute(
        params: &ScanNnParams,
        queries: &[[f32; 4]],
        targets: &[[f32; 4]],
        results: &mut [ScanNnResult],
    ) {
        // The shader's grid-stride loop over threads visits every query exactly once; the
        // order does not change any result, so the twin walks the queries directly.
        for q in 0..params.n_queries as usize {
            let p = queries[q];
            let (mut best_d, mut best_i) = (f32::MAX, SCAN_NN_NONE);
            if params.target_begin > 0 {
                (best_d, best_i) = (results[q].dist_sq, results[q].index);
            }
            for j in params.target_begin..params.target_end {
                let d2 = scan_dist_sq(targets[j as usize], p);
                if scan_closer(d2, j, best_d, best_i) {
                    best_d = d2;
                    best_i = j;
                }
            }
            if params.target_end == params.n_targets && best_d > params.radius_sq {
                best_i = SCAN_NN_NONE;
            }
            results[q] = ScanNnResult {
                index: best_i,
                dist_sq: best_d,
            };
        }
    }
}
