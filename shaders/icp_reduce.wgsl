// icp_reduce.wgsl: projective data association, both filters, the weighted point-to-plane
// row and the reduction to one 29-float normal-equation partial per workgroup.
// CPU twin: src/cpu/icp_reduce.rs (its header states the maths, the filters and weights).
//
// Bindings (@group(0)): each is described by the comment above its declaration.
// Grid-stride loop over pixels with few workgroups (few on a CPU adapter, many on a GPU):
// each thread sums its pixels in registers (f32), then, after one barrier, thread k sums
// entry k over the workgroup's threads (no tree reduction; see main).

// Current t_world_to_cam, intrinsics, the gates and the weights.
@group(0) @binding(0) var<storage, read> params: IcpParams;
// The source: width x height, WORLD frame, w = 1 / 0.
@group(0) @binding(1) var pred_vertex: texture_2d<f32>;
// The source's unit normals, WORLD frame, w = 1 / 0 (angle gate).
@group(0) @binding(2) var pred_normal: texture_2d<f32>;
// Target normals (camera frame) with the target vertex's depth in w, zero where invalid
// (see vertex_to_normal.wgsl); the vertex is rebuilt with back_project, as in the twin.
@group(0) @binding(3) var normal_depth: texture_2d<f32>;
// Out: ICP_SYSTEM_LEN floats per workgroup (21 of AᵀA upper triangle row-major, 6 of
// Aᵀb, count, sum of squared weighted residuals); the host sums them in f64.
@group(0) @binding(4) var<storage, read_write> partials: array<f32>;

const WORKGROUP_SIZE: u32 = 64u;

// One thread's partial system per lane: 64 x 29 x 4 = 7424 bytes of workgroup memory
// (the WebGPU minimum is 16384).
var<workgroup> scratch: array<array<f32, ICP_SYSTEM_LEN>, WORKGROUP_SIZE>;

// One correspondence: Jacobian row `a`, residual `b`, and whether both filters passed.
struct IcpRow {
    a: array<f32, 6>,
    b: f32,
    valid: bool,
}

// Axial depth noise of a Kinect-like sensor at depth z (metres), after Nguyen, Izadi and
// Lovell (2012): sigma(z) = 0.0012 + 0.0019 (z - 0.4)^2. Mirrors the twin's constants.
const NOISE_SIGMA_0_M: f32 = 0.0012;
const NOISE_SIGMA_QUAD: f32 = 0.0019;
const NOISE_Z_0_M: f32 = 0.4;

// Row weight of the depth noise at z: (sigma(0.4 m) / sigma(z))^2, 1 at 0.4 m and less
// beyond. Mirrors `noise_weight` in src/cpu/icp_reduce.rs.
fn noise_weight(z: f32) -> f32 {
    let dz = z - NOISE_Z_0_M;
    let sigma = NOISE_SIGMA_0_M + NOISE_SIGMA_QUAD * dz * dz;
    let r = NOISE_SIGMA_0_M / sigma;
    return r * r;
}

// Huber weight of a residual b (metres): 1 within delta, delta / |b| beyond; 1 when
// delta is 0 (off). Mirrors `huber_weight` in src/cpu/icp_reduce.rs.
fn huber_weight(b: f32, delta: f32) -> f32 {
    if delta <= 0.0 || abs(b) <= delta {
        return 1.0;
    }
    return delta / abs(b);
}

// The row of source pixel `src_texel`, or valid = false when a filter rejects it; weighted rows
// are scaled by sqrt(weight), so AᵀA and Aᵀb carry the weight once.
// Mirrors `icp_row` in src/cpu/icp_reduce.rs. `params` is main's copy of the binding (see
// main).
fn icp_row(params: IcpParams, src_texel: vec2<u32>) -> IcpRow {
    var row: IcpRow;
    row.valid = false;
    let src_world = textureLoad(pred_vertex, src_texel, 0);
    if !is_valid(src_world) {
        return row;
    }
    let cam = vec4<f32>(params.fx, params.fy, params.cx, params.cy);
    let p = transform_point(params.t_world_to_cam, xyz(src_world));
    let uv = project_to_texel(cam, params.width, params.height, p);
    if uv.x < 0 {
        return row;
    }
    let target_texel = vec2<u32>(uv);
    // Valid normal (w = depth > 0) implies a valid vertex: the twin's two validity tests.
    let nd = textureLoad(normal_depth, target_texel, 0);
    if !is_valid(nd) {
        return row;
    }
    let q = back_project(cam, target_texel, nd.w);
    let n = xyz(nd);
    let d = p - q;
    if length(d) >= params.dist_threshold_m {
        return row;
    }
    // The angle gate reads the source normal only when it is on.
    if params.cos_normal_threshold >= -1.0 {
        let src_normal_world = textureLoad(pred_normal, src_texel, 0);
        let n_p = transform_dir(params.t_world_to_cam, xyz(src_normal_world));
        if !is_valid(src_normal_world) || dot(n_p, n) <= params.cos_normal_threshold {
            return row;
        }
    }
    let b = dot(n, d);
    var w = huber_weight(b, params.huber_delta_m);
    if params.noise_weighting != 0u {
        w = w * noise_weight(q.z);
    }
    let s = sqrt(w);
    let pxn = cross(p, n) * s;
    let ns = n * s;
    row.a = array<f32, 6>(pxn.x, pxn.y, pxn.z, ns.x, ns.y, ns.z);
    row.b = b * s;
    row.valid = true;
    return row;
}

// Adds one row to a 29-entry system. Mirrors `accumulate` in src/cpu/icp_reduce.rs: the
// twin's two loops written out in the same k order (row r, column c >= r), because
// constant indices let lavapipe keep `sys` in registers instead of per-lane stack memory.
fn accumulate(sys: ptr<function, array<f32, ICP_SYSTEM_LEN>>, a: array<f32, 6>, b: f32) {
    (*sys)[0] += a[0] * a[0];
    (*sys)[1] += a[0] * a[1];
    (*sys)[2] += a[0] * a[2];
    (*sys)[3] += a[0] * a[3];
    (*sys)[4] += a[0] * a[4];
    (*sys)[5] += a[0] * a[5];
    (*sys)[6] += a[1] * a[1];
    (*sys)[7] += a[1] * a[2];
    (*sys)[8] += a[1] * a[3];
    (*sys)[9] += a[1] * a[4];
    (*sys)[10] += a[1] * a[5];
    (*sys)[11] += a[2] * a[2];
    (*sys)[12] += a[2] * a[3];
    (*sys)[13] += a[2] * a[4];
    (*sys)[14] += a[2] * a[5];
    (*sys)[15] += a[3] * a[3];
    (*sys)[16] += a[3] * a[4];
    (*sys)[17] += a[3] * a[5];
    (*sys)[18] += a[4] * a[4];
    (*sys)[19] += a[4] * a[5];
    (*sys)[20] += a[5] * a[5];
    (*sys)[ICP_ATB_OFFSET + 0u] += a[0] * b;
    (*sys)[ICP_ATB_OFFSET + 1u] += a[1] * b;
    (*sys)[ICP_ATB_OFFSET + 2u] += a[2] * b;
    (*sys)[ICP_ATB_OFFSET + 3u] += a[3] * b;
    (*sys)[ICP_ATB_OFFSET + 4u] += a[4] * b;
    (*sys)[ICP_ATB_OFFSET + 5u] += a[5] * b;
    (*sys)[ICP_COUNT_INDEX] += 1.0;
    (*sys)[ICP_RESIDUAL_INDEX] += b * b;
}

@compute @workgroup_size(WORKGROUP_SIZE)
fn main(
    @builtin(global_invocation_id) gid: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
) {
    var sys: array<f32, ICP_SYSTEM_LEN>;
    // The params copied once per thread: read inside the loop, lavapipe loads them from the
    // storage buffer again for every pixel.
    let p = params;
    let n_pix = p.width * p.height;
    let stride = nwg.x * WORKGROUP_SIZE;
    // (u, v) of `pix`, stepped along with it: one division per thread, not per pixel.
    let w = p.width;
    var u = gid.x % w;
    var v = gid.x / w;
    let du = stride % w;
    let dv = stride / w;
    for (var pix = gid.x; pix < n_pix; pix += stride) {
        let row = icp_row(p, vec2<u32>(u, v));
        if row.valid {
            accumulate(&sys, row.a, row.b);
        }
        u += du;
        v += dv;
        if u >= w {
            u -= w;
            v += 1u;
        }
    }
    scratch[lid] = sys;
    workgroupBarrier();
    // One barrier, then thread k < ICP_SYSTEM_LEN sums entry k over the workgroup's threads
    // (on lavapipe every barrier is a coroutine switch of the whole workgroup, so one
    // barrier beats a log2(WORKGROUP_SIZE)-level tree).
    if lid < ICP_SYSTEM_LEN {
        var total = 0.0;
        for (var t = 0u; t < WORKGROUP_SIZE; t++) {
            total += scratch[t][lid];
        }
        partials[wid.x * ICP_SYSTEM_LEN + lid] = total;
    }
}
