//! CPU twin of `shaders/prefix_sum.wgsl`: exclusive prefix sum of the keep flags and their
//! total, in the shader's shape (`SCAN_THREADS` chunk sums, a Hillis-Steele scan of the
//! sums, then each chunk's offsets from its exclusive start). Integer sums: the result is
//! the plain running sum, whatever the order.

use crate::layout::CompactParams;

/// Threads of the shader's one workgroup (`SCAN_THREADS` in prefix_sum.wgsl).
pub const SCAN_THREADS: u32 = 256;

/// Arguments: the shader's bindings in `@binding` order, named as there; see the
/// declarations in `shaders/prefix_sum.wgsl` for shapes, units and frames.
///
/// `counter` is the one element of the shader's `counter` array.
pub fn prefix_sum(params: &CompactParams, flags: &[u32], offsets: &mut [u32], counter: &mut u32) {
    let n = params.surfel_count;
    let chunk = n.div_ceil(SCAN_THREADS);
    let range = |t: u32| {
        let begin = (t * chunk).min(n);
        begin..(begin + chunk).min(n)
    };
    // Each thread's chunk sum.
    let own: Vec<u32> = (0..SCAN_THREADS)
        .map(|t| range(t).map(|i| flags[i as usize]).sum())
        .collect();
    // Inclusive scan of the chunk sums, pass by pass as the workgroup does it.
    let mut sums = own.clone();
    let mut stride = 1;
    while stride < SCAN_THREADS {
        let add: Vec<u32> = (0..SCAN_THREADS)
            .map(|t| {
                if t >= stride {
                    sums[(t - stride) as usize]
                } else {
                    0
                }
            })
            .collect();
        for (s, a) in sums.iter_mut().zip(add) {
            *s += a;
        }
        stride *= 2;
    }
    for t in 0..SCAN_THREADS {
        let mut running = sums[t as usize] - own[t as usize];
        for i in range(t) {
            offsets[i as usize] = running;
            running += flags[i as usize];
        }
    }
    *counter = sums[(SCAN_THREADS - 1) as usize];
}
