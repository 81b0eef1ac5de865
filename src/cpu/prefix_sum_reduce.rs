//! CPU twin of `shaders/prefix_sum_reduce.wgsl`: the sum of each block of
//! [`SCAN_BLOCK`] flags, the first of the three scan kernels (see [`super::prefix_sum`]).

use super::prefix_sum::{SCAN_BLOCK, SCAN_ITEMS, SCAN_THREADS};
use crate::layout::CompactParams;

/// Arguments: the shader's bindings in `@binding` order, named as there; see the
/// declarations in `shaders/prefix_sum_reduce.wgsl` for shapes, units and frames.
///
/// Writes every entry of `block_sums`, as the shader dispatched with one workgroup per
/// entry does (blocks past the flags sum to 0).
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
