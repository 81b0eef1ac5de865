// icp_candidates.wgsl: how many source pixels pass ICP's filter 1 at a pose (they project
// inside the image onto a valid target), the denominator of the tracking-health inlier
// fraction. Run once per frame at the final pose, so icp_reduce's per-iteration system
// stays 29 floats (counting there cost 30 % of every iteration on lavapipe).
// CPU twin: crates/core/src/cpu/icp_candidates.rs.
//
// Bindings (@group(0)): each is described by the comment above its declaration.
// icp_reduce's grid-stride loop; each thread counts its pixels, one workgroup atomic sums
// them.

// The pose, intrinsics and size (the gates of filter 2 are not read).
@group(0) @binding(0) var<storage, read> params: IcpParams;
// The source: width x height, WORLD frame, w = 1 / 0.
@group(0) @binding(1) var pred_vertex: texture_2d<f32>;
// Target normals (camera frame) with depth in w, zero where invalid.
@group(0) @binding(2) var normal_depth: texture_2d<f32>;
// Out: the candidates of each workgroup (the host sums them).
@group(0) @binding(3) var<storage, read_write> counts: array<u32>;

const WORKGROUP_SIZE: u32 = 64u;

var<workgroup> total: atomic<u32>;

// Whether source pixel `src_texel` passes filter 1. Mirrors `is_candidate` in
// crates/core/src/cpu/icp_candidates.rs and the first half of `icp_row` in icp_reduce.wgsl.
fn is_candidate(p: IcpParams, src_texel: vec2<u32>) -> bool {
    let src_world = textureLoad(pred_vertex, src_texel, 0);
    if !is_valid(src_world) {
        return false;
    }
    let cam = camera_intrinsics(p.camera);
    let q = transform_point(p.t_world_to_cam, xyz(src_world));
    let uv = project_to_texel(cam, p.camera.width, p.camera.height, q);
    if uv.x < 0 {
        return false;
    }
    return is_valid(textureLoad(normal_depth, vec2<u32>(uv), 0));
}

@compute @workgroup_size(WORKGROUP_SIZE)
fn main(
    @builtin(global_invocation_id) gid: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
) {
    let p = params;
    let n_pix = p.camera.width * p.camera.height;
    let stride = nwg.x * WORKGROUP_SIZE;
    var n = 0u;
    for (var pix = gid.x; pix < n_pix; pix += stride) {
        if is_candidate(p, vec2<u32>(pix % p.camera.width, pix / p.camera.width)) {
            n += 1u;
        }
    }
    atomicAdd(&total, n);
    workgroupBarrier();
    if lid == 0u {
        counts[wid.x] = atomicLoad(&total);
    }
}
