//! CPU twin of `shaders/icp_reduce_final.wgsl`: the second stage of the GPU's ICP
//! reduction, the per-workgroup partial systems of `icp_reduce` summed into one.
//!
//! The CPU backend does not need it (its `icp_reduce` sums every row into one f64 system
//! directly); it is the GPU stage's reference, bit for bit: entry `k` is the f32 sum of the
//! partials' entry `k` over the shader's fixed-shape tree ([`FINAL_THREADS`] strided
//! serial sums, then halved pairwise), one plain add at a time in the shader's order.

use crate::layout::ICP_SYSTEM_LEN;

/// Threads of each of the shader's workgroups (`FINAL_THREADS` in icp_reduce_final.wgsl),
/// a power of two.
pub const FINAL_THREADS: usize = 64;

/// Arguments: the shader's bindings in `@binding` order, named as there; see the
/// declarations in `shaders/icp_reduce_final.wgsl` for shapes, units and frames.
///
/// `system` is returned instead of written: the summed system, f32.
pub fn icp_reduce_final(partials: &[f32]) -> [f32; ICP_SYSTEM_LEN] {
    let groups = partials.len() / ICP_SYSTEM_LEN;
    let mut system = [0.0f32; ICP_SYSTEM_LEN];
    // Workgroup k.
    for (k, entry) in system.iter_mut().enumerate() {
        // Thread t's strided serial sum.
        let mut sums = [0.0f32; FINAL_THREADS];
        for (t, sum) in sums.iter_mut().enumerate() {
            for g in (t..groups).step_by(FINAL_THREADS) {
                *sum += partials[g * ICP_SYSTEM_LEN + k];
            }
        }
        // The tree: sums[t] += sums[t + s] for s = T / 2, ..., 1.
        let mut s = FINAL_THREADS / 2;
        while s > 0 {
            for t in 0..s {
                sums[t] += sums[t + s];
            }
            s /= 2;
        }
        *entry = sums[0];
    }
    system
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Integers small enough to be exact in f32 sum to the exact total in any order, so the
    /// tree must give it; and the tree is not the serial order (a sum whose rounding
    /// depends on order gives another value serially).
    #[test]
    fn the_tree_sums_every_partial_once() {
        let groups = 1024;
        let partials: Vec<f32> = (0..groups * ICP_SYSTEM_LEN)
            .map(|i| (i % 97) as f32)
            .collect();
        let system = icp_reduce_final(&partials);
        for (k, &s) in system.iter().enumerate() {
            let exact: f32 = (0..groups).map(|g| partials[g * ICP_SYSTEM_LEN + k]).sum();
            assert_eq!(s, exact, "entry {k}");
        }
        // One large value among many small ones: serial order loses the small ones
        // added after it, the tree keeps more of them.
        let mut p = vec![0.0f32; groups * ICP_SYSTEM_LEN];
        for g in 0..groups {
            p[g * ICP_SYSTEM_LEN] = if g == 0 { 1.0e8 } else { 1.0 };
        }
        let serial: f32 = (0..groups).map(|g| p[g * ICP_SYSTEM_LEN]).sum();
        assert_ne!(
            icp_reduce_final(&p)[0],
            serial,
            "the tree is not the serial sum"
        );
    }
}
