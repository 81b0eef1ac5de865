// prefix_sum_reduce.wgsl: the first of a stream compaction's three scan kernels
// (prefix_sum_reduce, prefix_sum_blocks, prefix_sum): the sum of each block of SCAN_BLOCK
// flags. CPU twin: crates/core/src/cpu/prefix_sum_reduce.rs.
//
// Bindings (@group(0)): each is described by the comment above its declaration.
// One workgroup per block, dispatched as [ceil(n / SCAN_BLOCK), 1] (or more: blocks past
// n sum to 0): thread t sums the SCAN_ITEMS flags [b SCAN_BLOCK + t SCAN_ITEMS, ...) of
// block b, and the workgroup adds the SCAN_THREADS sums with one workgroup atomic (integer
// sums: the result does not depend on the order). No thread loops over more than
// SCAN_ITEMS flags.

// Uses surfel_count = n, the number of flags to scan.
@group(0) @binding(0) var<storage, read> params: CompactParams;
// 0 or 1 per item, n entries.
@group(0) @binding(1) var<storage, read> flags: array<u32>;
// Out: per block, the sum of its flags (at least ceil(n / SCAN_BLOCK) entries).
@group(0) @binding(2) var<storage, read_write> block_sums: array<u32>;

// The block shape, shared by the three scan kernels and the twins (crates/core/src/cpu/prefix_sum.rs).
const SCAN_THREADS: u32 = 64u;
const SCAN_ITEMS: u32 = 32u;
const SCAN_BLOCK: u32 = 2048u;

var<workgroup> block_total: atomic<u32>;

@compute @workgroup_size(SCAN_THREADS)
fn main(
    @builtin(local_invocation_index) t: u32,
    @builtin(workgroup_id) wid: vec3<u32>,
) {
    let n = params.surfel_count;
    let begin = min(wid.x * SCAN_BLOCK + t * SCAN_ITEMS, n);
    let end = min(begin + SCAN_ITEMS, n);
    var sum = 0u;
    for (var i = begin; i < end; i += 1u) {
        sum += flags[i];
    }
    atomicAdd(&block_total, sum);
    workgroupBarrier();
    if t == 0u && wid.x < arrayLength(&block_sums) {
        block_sums[wid.x] = atomicLoad(&block_total);
    }
}
