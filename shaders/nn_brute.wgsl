// nn_brute.wgsl: nearest target point of each query by brute force, reported only within
// the rejection radius. CPU twin: crates/core/src/cpu/nn_brute.rs (same loops, same tie rule: equal
// squared distances go to the lower target index).
//
// Bindings (@group(0)): each is described by the comment above its declaration.
// Assumes: dispatched with params.n_threads = workgroups * 64 threads; each thread walks
// the queries with a grid stride. One dispatch scans targets [target_begin, target_end)
// and continues from results[q] when target_begin > 0: llvmpipe (lavapipe) stops an
// invocation's loops after ~65535 iterations in total, so the host splits big targets.

// ScanNnParams, ScanNnResult, SCAN_NN_NONE, SCAN_F32_MAX, scan_closer and scan_dist_sq
// live in scan_common.wgsl (prepended by crates/gpu/src/shaders.rs).

// Counts, radius^2, grid-stride thread count.
@group(0) @binding(0) var<storage, read> params: ScanNnParams;
// xyz metres in the target frame, w unused.
@group(0) @binding(1) var<storage, read> queries: array<vec4<f32>>;
// xyz metres, w unused.
@group(0) @binding(2) var<storage, read> targets: array<vec4<f32>>;
// One per query.
@group(0) @binding(3) var<storage, read_write> results: array<ScanNnResult>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    for (var q = gid.x; q < params.n_queries; q += params.n_threads) {
        let p = queries[q];
        var best_d = SCAN_F32_MAX;
        var best_i = SCAN_NN_NONE;
        if params.target_begin > 0u {
            best_d = results[q].dist_sq;
            best_i = results[q].index;
        }
        for (var j = params.target_begin; j < params.target_end; j++) {
            let d2 = scan_dist_sq(targets[j], p);
            if scan_closer(d2, j, best_d, best_i) {
                best_d = d2;
                best_i = j;
            }
        }
        if params.target_end == params.n_targets && best_d > params.radius_sq {
            best_i = SCAN_NN_NONE;
        }
        results[q] = ScanNnResult(best_i, best_d);
    }
}
