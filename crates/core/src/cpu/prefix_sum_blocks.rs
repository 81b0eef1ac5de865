//! CPU twin of `shaders/prefix_sum_blocks.wgsl`: the exclusive prefix sum of the block
//! sums, in place, and their total, in the shader's shape ([`BLOCKS_THREADS`] chunk sums,
//! a Hillis-Steele scan of them, then each chunk's offsets from its exclusive start). The
//! second of the three scan kernels (see [`super::prefix_sum`]).

use super::binding::twin;
use super::prefix_sum_reduce::{hillis_steele_inclusive, SCAN_BLOCK};
use crate::layout::CompactParams;

/// Threads of the shader's one workgroup (`BLOCKS_THREADS` in prefix_sum_blocks.wgsl).
pub const BLOCKS_THREADS: u32 = 256;

twin! {
    /// The block sums' exclusive prefix sum in place, and their total into `counter[0]`.
    /// The parameters are the shader's bindings in `@binding` order, named as there (see
    /// the declarations in `shaders/prefix_sum_blocks.wgsl` for shapes, units and frames).
    pub fn prefix_sum_blocks(params: &CompactParams, block_sums: &mut [u32], counter: &mut [u32]) {
        let blocks = params.surfel_count.div_ceil(SCAN_BLOCK);
        let chunk = blocks.div_ceil(BLOCKS_THREADS);
        let range = |t: u32| {
            let begin = (t * chunk).min(blocks);
            begin as usize..(begin + chunk).min(blocks) as usize
        };
        let own: Vec<u32> = (0..BLOCKS_THREADS)
            .map(|t| block_sums[range(t)].iter().sum())
            .collect();
        let sums = hillis_steele_inclusive(&own);
        for t in 0..BLOCKS_THREADS {
            let mut running = sums[t as usize] - own[t as usize];
            for s in &mut block_sums[range(t)] {
                let block = *s;
                *s = running;
                running += block;
            }
        }
        counter[0] = sums[(BLOCKS_THREADS - 1) as usize];
    }
}
