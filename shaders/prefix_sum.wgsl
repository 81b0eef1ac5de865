// prefix_sum.wgsl: exclusive prefix sum of the keep flags (where each kept surfel goes)
// and their total (the surfel count after compaction). Second of the three
// stream-compaction kernels. CPU twin: src/cpu/prefix_sum.rs.
//
// Bindings (@group(0)): each is described by the comment above its declaration.
// One workgroup of SCAN_THREADS threads, dispatched as [1, 1]: thread t owns the contiguous
// chunk [t c, (t + 1) c) with c = ceil(n / SCAN_THREADS); it sums its chunk serially, the
// workgroup scans the SCAN_THREADS sums in shared memory (Hillis-Steele), and each thread
// writes its chunk's offsets from its exclusive start. Integer sums, so the result does not
// depend on the order of anything. One workgroup reads the flags twice: ~1 ms for 350k
// surfels on lavapipe, where a workgroup runs on one core anyway; a large map on a real GPU
// would want a multi-workgroup scan (reduce, scan the block sums, then scan-and-add).

// Uses surfel_count = n, the number of flags to scan.
@group(0) @binding(0) var<storage, read> params: CompactParams;
// 0 or 1 per surfel (compact_flags), n entries.
@group(0) @binding(1) var<storage, read> flags: array<u32>;
// Out: n entries, offsets[i] = flags[0] + ... + flags[i - 1].
@group(0) @binding(2) var<storage, read_write> offsets: array<u32>;
// Out: counter[0] = flags[0] + ... + flags[n - 1] (the backend's surfel counter, which
// fuse_add counts with).
@group(0) @binding(3) var<storage, read_write> counter: array<u32>;

const SCAN_THREADS: u32 = 256u;

var<workgroup> sums: array<u32, SCAN_THREADS>;

@compute @workgroup_size(SCAN_THREADS)
fn main(@builtin(local_invocation_id) lid: vec3<u32>) {
    let n = params.surfel_count;
    let t = lid.x;
    let chunk = (n + SCAN_THREADS - 1u) / SCAN_THREADS;
    let begin = min(t * chunk, n);
    let end = min(begin + chunk, n);
    var sum = 0u;
    for (var i = begin; i < end; i += 1u) {
        sum += flags[i];
    }
    sums[t] = sum;
    workgroupBarrier();
    // Inclusive scan of the chunk sums: after the pass with stride s, sums[t] holds the
    // sum of the 2s chunks ending at t.
    for (var stride = 1u; stride < SCAN_THREADS; stride *= 2u) {
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
        offsets[i] = running;
        running += flags[i];
    }
    if t == SCAN_THREADS - 1u {
        counter[0] = sums[t];
    }
}
