// icp_reduce_final.wgsl: the second stage of the ICP reduction: sums icp_reduce's
// per-workgroup partial systems into one, so each ICP iteration reads back ICP_SYSTEM_LEN
// floats (116 bytes) instead of one partial per workgroup (1.8 KB on lavapipe's 16
// workgroups, 116 KB on a GPU's 1024).
// CPU twin: crates/core/src/cpu/icp_reduce_final.rs.
//
// Bindings (@group(0)): each is described by the comment above its declaration.
// Dispatched as [ICP_SYSTEM_LEN, 1]: workgroup k sums entry k over the G partials as a
// fixed-shape tree, in f32 with plain adds (no fused multiply-add can apply), so the result
// is the same on every adapter and in the twin. Thread t first sums partials t, t + T,
// t + 2T, ... in that order (T = FINAL_THREADS; at most G / T adds: 16 on a GPU's 1024
// partials); then the T sums are halved in place, `sums[t] += sums[t + s]` for
// s = T / 2, T / 4, ..., 1. The shape depends only on G (the adapter's icp_reduce
// workgroups), never on scheduling.

// ICP_SYSTEM_LEN floats per icp_reduce workgroup (the buffer holds exactly the dispatched
// workgroups' partials).
@group(0) @binding(0) var<storage, read> partials: array<f32>;
// Out: ICP_SYSTEM_LEN floats, the summed system.
@group(0) @binding(1) var<storage, read_write> system: array<f32>;

// Threads per workgroup, a power of two (the twin's `FINAL_THREADS`).
const FINAL_THREADS: u32 = 64u;

var<workgroup> sums: array<f32, FINAL_THREADS>;

@compute @workgroup_size(FINAL_THREADS)
fn main(
    @builtin(local_invocation_index) t: u32,
    @builtin(workgroup_id) wid: vec3<u32>,
) {
    let k = wid.x;
    let groups = arrayLength(&partials) / ICP_SYSTEM_LEN;
    var sum = 0.0;
    for (var g = t; g < groups; g += FINAL_THREADS) {
        sum = sum + partials[g * ICP_SYSTEM_LEN + k];
    }
    sums[t] = sum;
    workgroupBarrier();
    for (var s = FINAL_THREADS / 2u; s > 0u; s /= 2u) {
        if t < s {
            sums[t] = sums[t] + sums[t + s];
        }
        workgroupBarrier();
    }
    if t == 0u && k < ICP_SYSTEM_LEN {
        system[k] = sums[0];
    }
}
