//! CPU twin of `shaders/prefix_sum.wgsl`, the last of the three scan kernels: the
//! exclusive prefix sum of the keep flags, each block of [`SCAN_BLOCK`] flags scanned in the
//! shader's shape ([`SCAN_THREADS`] sums of [`SCAN_ITEMS`] flags, a Hillis-Steele scan of
//! them, then each thread's offsets from its exclusive start) and offset by the sum of the
//! blocks before it. [`scan`] runs the three kernels' twins in order, as both backends'
//! `FuseScan` and `CompactScan` do. Integer sums: the result is the plain running sum,
//! whatever the order.

use super::binding::{twin, Binding};
use super::invocations::{par_for_each_group, Storage};
use super::prefix_sum_blocks::prefix_sum_blocks;
use super::prefix_sum_reduce::{hillis_steele_inclusive, prefix_sum_reduce};
pub use super::prefix_sum_reduce::{scan_blocks, SCAN_BLOCK, SCAN_ITEMS, SCAN_THREADS};
use crate::layout::CompactParams;

twin! {
    /// Each flag's exclusive offset into `offsets`: its block's scan offset by the sum of
    /// the blocks before it. The parameters are the shader's bindings in `@binding` order,
    /// named as there (see the declarations in `shaders/prefix_sum.wgsl` for shapes, units
    /// and frames).
    pub fn prefix_sum(
        params: &CompactParams,
        flags: &[u32],
        block_sums: &[u32],
        offsets: &mut [u32],
    ) {
        let n = params.surfel_count;
        let offsets = Storage::new(offsets);
        // The workgroups on every thread, each writing its own block's offsets, weighed by
        // the SCAN_BLOCK flags each walks.
        let blocks = n.div_ceil(SCAN_BLOCK) as usize;
        par_for_each_group(blocks, SCAN_BLOCK as usize, |wid| {
            let wid = wid as u32;
            let range = |t: u32| {
                let begin = (wid * SCAN_BLOCK + t * SCAN_ITEMS).min(n);
                begin..(begin + SCAN_ITEMS).min(n)
            };
            let own: Vec<u32> = (0..SCAN_THREADS)
                .map(|t| range(t).map(|i| flags[i as usize]).sum())
                .collect();
            let sums = hillis_steele_inclusive(&own);
            for t in 0..SCAN_THREADS {
                let mut running = block_sums[wid as usize] + sums[t as usize] - own[t as usize];
                for i in range(t) {
                    offsets.store(i as usize, running);
                    running += flags[i as usize];
                }
            }
        });
    }
}

/// The whole scan of `params.surfel_count` flags, the three kernels' twins in order in
/// the one call shape: `offsets[i] = flags[0] + ... + flags[i - 1]` and `counter` their
/// total.
pub fn scan(params: &CompactParams, flags: &[u32], offsets: &mut [u32], counter: &mut u32) {
    let blocks = scan_blocks(params.surfel_count as usize);
    let mut block_sums = vec![0u32; blocks];
    let params = || Binding::of(params);
    prefix_sum_reduce(&mut [
        params(),
        Binding::read(flags),
        Binding::write(&mut block_sums),
    ]);
    prefix_sum_blocks(&mut [
        params(),
        Binding::write(&mut block_sums),
        Binding::write(std::slice::from_mut(counter)),
    ]);
    prefix_sum(&mut [
        params(),
        Binding::read(flags),
        Binding::read(&block_sums),
        Binding::write(offsets),
    ]);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::layout::scan_params;

    /// Around the block and chunk edges (none, fewer than a thread's, one block, one more,
    /// many blocks), the three twins give the running sum and the total.
    #[test]
    fn scan_is_the_running_sum() {
        let b = SCAN_BLOCK as usize;
        for n in [0, 1, 31, 33, b - 1, b, b + 1, 3 * b + 17, 300 * b + 5] {
            let flags: Vec<u32> = (0..n).map(|i| ((i * 7 + i / 5) % 3 == 0) as u32).collect();
            let mut offsets = vec![u32::MAX; n];
            let mut counter = u32::MAX;
            scan(&scan_params(n), &flags, &mut offsets, &mut counter);
            let mut running = 0;
            for i in 0..n {
                assert_eq!(offsets[i], running, "n = {n}, flag {i}");
                running += flags[i];
            }
            assert_eq!(counter, running, "n = {n}: total");
        }
    }
}
