// icp_reduce_final.wgsl: the second stage of the ICP reduction: sums icp_reduce's
// per-workgroup partial systems into one, so each ICP iteration reads back ICP_SYSTEM_LEN
// floats (116 bytes) instead of one partial per workgroup (1.8 KB on lavapipe's 16
// workgroups, 116 KB on a GPU's 1024).
// CPU twin: src/cpu/icp_reduce_final.rs.
//
// Bindings (@group(0)): each is described by the comment above its declaration.
// One workgroup; thread k sums entry k over the partials in workgroup order, in f32, one
// add at a time (plain adds: the same result on every adapter and in the twin).

// ICP_SYSTEM_LEN floats per icp_reduce workgroup (the buffer holds exactly the dispatched
// workgroups' partials).
@group(0) @binding(0) var<storage, read> partials: array<f32>;
// Out: ICP_SYSTEM_LEN floats, the summed system.
@group(0) @binding(1) var<storage, read_write> system: array<f32>;

@compute @workgroup_size(32)
fn main(@builtin(local_invocation_index) k: u32) {
    if (k >= ICP_SYSTEM_LEN) {
        return;
    }
    let groups = arrayLength(&partials) / ICP_SYSTEM_LEN;
    var sum = 0.0;
    for (var g = 0u; g < groups; g = g + 1u) {
        sum = sum + partials[g * ICP_SYSTEM_LEN + k];
    }
    system[k] = sum;
}
