// prefix_sum_blocks.wgsl: the second of the three scan kernels: the exclusive prefix sum
// of prefix_sum_reduce's block sums, in place, and their total (the count after
// compaction). CPU twin: crates/core/src/cpu/prefix_sum_blocks.rs.
//
// Bindings (@group(0)): each is described by the comment above its declaration.
// One workgroup of BLOCKS_THREADS threads, dispatched as [1, 1], over the ceil(n /
// SCAN_BLOCK) block sums (not over the flags: 1 / 2048 of them, a few per thread even for
// millions of surfels): thread t sums its contiguous chunk of block sums, the workgroup
// scans the chunk sums in shared memory (Hillis-Steele), and each thread writes its
// chunk's exclusive offsets over its own entries. Integer sums.

// Uses surfel_count = n, the number of flags scanned.
@group(0) @binding(0) var<storage, read> params: CompactParams;
// In: per block its sum (prefix_sum_reduce). Out: per block the sum of the blocks before it.
@group(0) @binding(1) var<storage, read_write> block_sums: array<u32>;
// Out: counter[0] = the sum of all flags (the backend's surfel counter, which fuse_add
// counts with).
@group(0) @binding(2) var<storage, read_write> counter: array<u32>;

// The block shape of the three scan kernels (see prefix_sum_reduce.wgsl).
const SCAN_BLOCK: u32 = 2048u;
const BLOCKS_THREADS: u32 = 256u;

var<workgroup> sums: array<u32, BLOCKS_THREADS>;

@compute @workgroup_size(BLOCKS_THREADS)
fn main(@builtin(local_invocation_index) t: u32) {
    let blocks = (params.surfel_count + SCAN_BLOCK - 1u) / SCAN_BLOCK;
    let chunk = (blocks + BLOCKS_THREADS - 1u) / BLOCKS_THREADS;
    let begin = min(t * chunk, blocks);
    let end = min(begin + chunk, blocks);
    var sum = 0u;
    for (var i = begin; i < end; i += 1u) {
        sum += block_sums[i];
    }
    sums[t] = sum;
    workgroupBarrier();
    // Inclusive scan of the chunk sums: after the pass with stride s, sums[t] holds the
    // sum of the 2s chunks ending at t.
    for (var stride = 1u; stride < BLOCKS_THREADS; stride *= 2u) {
        var add = 0u;
        if t >= stride {
            add = sums[t - stride];
        }
        workgroupBarrier();
        sums[t] += add;
        workgroupBarrier();
    }
    var running = sums[t] - sum;
    for (var i = begin; i < end; i += 1u) {
        let own = block_sums[i];
        block_sums[i] = running;
        running += own;
    }
    if t == BLOCKS_THREADS - 1u {
        counter[0] = sums[t];
    }
}
