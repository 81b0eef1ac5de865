// nn_grid.wgsl: radius-limited nearest neighbour through a hashed uniform voxel grid.
// Each query searches the 3x3x3 cells around its own; with a cell edge >= the radius this
// equals brute force within the radius. CPU twin: crates/core/src/cpu/nn_grid.rs (same loops, same
// hash, same tie rule), which also builds the grid (`HashGrid::build`).
//
// Bindings (@group(0)): each is described by the comment above its declaration.
// Assumes: params.n_threads = workgroups * 64 (grid-stride over queries).

// ScanNnParams, ScanNnResult, SCAN_NN_NONE, SCAN_F32_MAX, scan_closer and scan_dist_sq
// live in scan_common.wgsl (prepended by crates/gpu/src/shaders.rs).

// Counts, radius^2, thread count, cell, mask.
@group(0) @binding(0) var<storage, read> params: ScanNnParams;
// xyz metres in the target frame.
@group(0) @binding(1) var<storage, read> queries: array<vec4<f32>>;
// The target points sorted by bucket; w holds the original target index (bitcast<u32>).
@group(0) @binding(2) var<storage, read> grid_points: array<vec4<f32>>;
// Bucket b is [bucket_start[b], bucket_start[b+1]).
@group(0) @binding(3) var<storage, read> bucket_start: array<u32>;
// One per query, index into the ORIGINAL target cloud.
@group(0) @binding(4) var<storage, read_write> results: array<ScanNnResult>;

// Mirrors `scan_cell_of` in crates/core/src/cpu/nn_grid.rs.
fn scan_cell_of(p: vec4<f32>, cell_size: f32) -> vec3<i32> {
    return vec3<i32>(floor(p.xyz / cell_size));
}

// Mirrors `scan_bucket` in crates/core/src/cpu/nn_grid.rs (u32 multiplication wraps in WGSL).
fn scan_bucket(c: vec3<i32>, table_mask: u32) -> u32 {
    let h = (bitcast<u32>(c.x) * 73856093u) ^ (bitcast<u32>(c.y) * 19349663u)
        ^ (bitcast<u32>(c.z) * 83492791u);
    return h & table_mask;
}

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    for (var q = gid.x; q < params.n_queries; q += params.n_threads) {
        let p = queries[q];
        let c = scan_cell_of(p, params.cell_size);
        var best_d = SCAN_F32_MAX;
        var best_i = SCAN_NN_NONE;
        for (var dz = -1; dz <= 1; dz++) {
            for (var dy = -1; dy <= 1; dy++) {
                for (var dx = -1; dx <= 1; dx++) {
                    let b = scan_bucket(c + vec3<i32>(dx, dy, dz), params.table_mask);
                    let end = bucket_start[b + 1u];
                    for (var k = bucket_start[b]; k < end; k++) {
                        let t = grid_points[k];
                        let d2 = scan_dist_sq(t, p);
                        let i = bitcast<u32>(t.w);
                        if scan_closer(d2, i, best_d, best_i) {
                            best_d = d2;
                            best_i = i;
                        }
                    }
                }
            }
        }
        if best_d > params.radius_sq {
            best_i = SCAN_NN_NONE;
        }
        results[q] = ScanNnResult(best_i, best_d);
    }
}
