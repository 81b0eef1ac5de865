// prefix_sum.wgsl: the last of the three scan kernels (prefix_sum_reduce, prefix_sum_blocks,
// prefix_sum): the exclusive prefix sum of the keep flags (where each kept item goes), each
// block scanned on its own and offset by the sum of the blocks before it. The scan of a
// stream compaction (fusion's new surfels, the map's survivors). CPU twin:
// crates/core/src/cpu/prefix_sum.rs.
//
// Bindings (@group(0)): each is described by the comment above its declaration.
// One workgroup per block of SCAN_BLOCK flags, dispatched as [ceil(n / SCAN_BLOCK), 1]:
// thread t owns the SCAN_ITEMS flags [b SCAN_BLOCK + t SCAN_ITEMS, ...); it sums them, the
// workgroup scans the SCAN_THREADS sums in shared memory (Hillis-Steele), and each thread
// writes its flags' offsets from block_sums[b] plus its exclusive start. Integer sums, so
// the result does not depend on the order of anything.

// Uses surfel_count = n, the number of flags to scan.
@group(0) @binding(0) var<storage, read> params: CompactParams;
// 0 or 1 per item (compact_flags, fuse_flags), n entries.
@group(0) @binding(1) var<storage, read> flags: array<u32>;
// Per block, the sum of the flags of the blocks before it (prefix_sum_blocks).
@group(0) @binding(2) var<storage, read> block_sums: array<u32>;
// Out: n entries, offsets[i] = flags[0] + ... + flags[i - 1].
@group(0) @binding(3) var<storage, read_write> offsets: array<u32>;

// The block shape of the three scan kernels (see prefix_sum_reduce.wgsl).
const SCAN_THREADS: u32 = 64u;
const SCAN_ITEMS: u32 = 32u;
const SCAN_BLOCK: u32 = 2048u;

var<workgroup> sums: array<u32, SCAN_THREADS>;

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
    sums[t] = sum;
    workgroupBarrier();
    for (var stride = 1u; stride < SCAN_THREADS; stride *= 2u) {
        var add = 0u;
        if t >= stride {
            add = sums[t - stride];
        }
        workgroupBarrier();
        sums[t] += add;
        workgroupBarrier();
    }
    if begin >= end {
        return;
    }
    var running = block_sums[wid.x] + sums[t] - sum;
    for (var i = begin; i < end; i += 1u) {
        offsets[i] = running;
        running += flags[i];
    }
}
