// cross_covariance.wgsl: per-workgroup partial sums of the inlier pairs' cross-covariance
// for point-to-point ICP (Arun / Umeyama). Each thread accumulates its grid-stride share of
// the pairs in registers, then the 64 threads of a workgroup tree-reduce in shared memory
// and thread 0 writes one ScanCovPartial. The host sums partials in f64 and solves the SVD.
// CPU twin: crates/core/src/cpu/cross_covariance.rs (same loops and reduction order).
//
// Bindings (@group(0)): each is described by the comment above its declaration.
// Assumes: params.n_threads = workgroups * 64. Points are shifted by params.anchor (the
// queries' centroid) before accumulation so f32 sums of products stay well conditioned.

// ScanNnResult, ScanCovParams, ScanCovPartial and SCAN_NN_NONE live in scan_common.wgsl
// (prepended by crates/gpu/src/shaders.rs).

// The anchor, pair count, thread count and radius^2.
@group(0) @binding(0) var<storage, read> params: ScanCovParams;
// The transformed source points p, metres.
@group(0) @binding(1) var<storage, read> queries: array<vec4<f32>>;
// The target cloud, metres.
@group(0) @binding(2) var<storage, read> targets: array<vec4<f32>>;
// The nearest target of each query.
@group(0) @binding(3) var<storage, read> nn: array<ScanNnResult>;
// Out: one partial per workgroup.
@group(0) @binding(4) var<storage, read_write> partials: array<ScanCovPartial>;

var<workgroup> scratch: array<ScanCovPartial, 64>;

// Mirrors `scan_cov_add` in crates/core/src/cpu/cross_covariance.rs.
fn scan_cov_add(a: ScanCovPartial, b: ScanCovPartial) -> ScanCovPartial {
    return ScanCovPartial(
        a.count_sq + b.count_sq,
        a.sum_p + b.sum_p,
        a.sum_q + b.sum_q,
        a.pq0 + b.pq0,
        a.pq1 + b.pq1,
        a.pq2 + b.pq2,
    );
}

// Mirrors `scan_cov_pair` in crates/core/src/cpu/cross_covariance.rs.
fn scan_cov_pair(acc: ptr<function, ScanCovPartial>, p: vec3<f32>, q: vec3<f32>) {
    let d = p - q;
    (*acc).count_sq += vec4<f32>(
        1.0,
        d.x * d.x + d.y * d.y + d.z * d.z,
        p.x * p.x + p.y * p.y + p.z * p.z,
        q.x * q.x + q.y * q.y + q.z * q.z,
    );
    (*acc).sum_p += vec4<f32>(p, 0.0);
    (*acc).sum_q += vec4<f32>(q, 0.0);
    (*acc).pq0 += vec4<f32>(p.x * q, 0.0);
    (*acc).pq1 += vec4<f32>(p.y * q, 0.0);
    (*acc).pq2 += vec4<f32>(p.z * q, 0.0);
}

@compute @workgroup_size(64)
fn main(
    @builtin(global_invocation_id) gid: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
    @builtin(workgroup_id) wg: vec3<u32>,
) {
    var acc = ScanCovPartial(vec4<f32>(), vec4<f32>(), vec4<f32>(), vec4<f32>(), vec4<f32>(), vec4<f32>());
    let a = params.anchor.xyz;
    for (var i = gid.x; i < params.n_pairs; i += params.n_threads) {
        let r = nn[i];
        if r.index != SCAN_NN_NONE && r.dist_sq <= params.radius_sq {
            scan_cov_pair(&acc, queries[i].xyz - a, targets[r.index].xyz - a);
        }
    }
    scratch[lid] = acc;
    workgroupBarrier();
    for (var stride = 32u; stride > 0u; stride >>= 1u) {
        if lid < stride {
            scratch[lid] = scan_cov_add(scratch[lid], scratch[lid + stride]);
        }
        workgroupBarrier();
    }
    if lid == 0u {
        partials[wg.x] = scratch[0];
    }
}
