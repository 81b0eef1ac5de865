//! CPU twin of `shaders/prefix_sum_reduce.wgsl`: the sum of each block of
//! [`SCAN_BLOCK`] flags, the first of the three scan kernels (see [`super::prefix_sum`]).

use super::binding::twin;
use crate::layout::CompactParams;

pub use crate::layout::{scan_blocks, SCAN_BLOCK, SCAN_ITEMS, SCAN_THREADS};

/// The inclusive Hillis-Steele scan of `own`, pass by pass as a workgroup does it: after
/// the pass with stride s, entry t holds the sum of the 2s entries ending at t.
pub(super) fn hillis_steele_inclusive(own: &[u32]) -> Vec<u32> {
    let mut sums = own.to_vec();
    let mut stride = 1;
    while stride < sums.len() {
        let add: Vec<u32> = (0..sums.len())
            .map(|t| if t >= stride { sums[t - stride] } else { 0 })
            .collect();
        for (s, a) in sums.iter_mut().zip(add) {
            *s += a;
        }
        stride *= 2;
    }
    sums
}

twin! {
    /// The sum of each block of flags into `block_sums`: every entry, as the shader
    /// dispatched with one workgroup per entry does (blocks past the flags sum to 0). The
    /// parameters are the shader's bindings in `@binding` order, named as there (see the
    /// declarations in `shaders/prefix_sum_reduce.wgsl` for shapes, units and frames).
    pub fn prefix_sum_reduce(params: &CompactParams, flags: &[u32], block_sums: &mut [u32]) {
        let n = params.surfel_count;
        for wid in 0..block_sums.len() as u32 {
            let mut block_total = 0u32;
            for t in 0..SCAN_THREADS {
                let begin = (wid * SCAN_BLOCK + t * SCAN_ITEMS).min(n);
                let end = (begin + SCAN_ITEMS).min(n);
                let sum: u32 = flags[begin as usize..end as usize].iter().sum();
                block_total += sum;
            }
            block_sums[wid as usize] = block_total;
        }
    }
}
