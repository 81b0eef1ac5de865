// system_grid.wgsl: the entry point of every kernel that reduces one 29-float
// normal-equation system over the pixels (icp_reduce, photo_reduce), appended to a kernel
// whose file says `#entry system_grid` (crates/gpu/src/shaders.rs).
// CPU twin: crates/core/src/cpu/entries.rs, fn system_grid (re-exported as cpu::system_grid).
// Not valid alone: the kernel declares
//   params                           a binding whose `camera: Camera` has the image's
//                                    width, height;
//   partials                         the output binding, ICP_SYSTEM_LEN floats per workgroup;
//   fn system_row(p, texel) -> IcpRow  the row of one pixel, on main's copy of the params.
//
// Grid-stride loop over pixels with few workgroups (few on a CPU adapter, many on a GPU):
// each thread sums its pixels in registers (f32), then, after one barrier, thread k sums
// entry k over the workgroup's threads (no tree reduction; see main).

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

// The valid row of a point p (camera frame) whose residual b moves along direction d
// (the frame normal, or the intensity gradient through the projection) under the twist
// (alpha, beta, gamma, tx, ty, tz): a = [(p x d), d] and b, both scaled by s = sqrt(weight).
// Mirrors `scaled_row` in crates/core/src/cpu/entries.rs.
fn scaled_row(p: vec3<f32>, d: vec3<f32>, b: f32, s: f32) -> IcpRow {
    let pxd = cross(p, d) * s;
    let ds = d * s;
    return IcpRow(array<f32, 6>(pxd.x, pxd.y, pxd.z, ds.x, ds.y, ds.z), b * s, true);
}

// Adds one row to a 29-entry system. Mirrors `accumulate` in crates/core/src/cpu/entries.rs: the
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
    @builtin(local_invocation_index) lid: u32,
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(global_invocation_id) gid: vec3<u32>,
) {
    var sys: array<f32, ICP_SYSTEM_LEN>;
    // The params copied once per thread: read inside the loop, lavapipe loads them from the
    // storage buffer again for every pixel.
    let p = params;
    let n_pix = p.camera.width * p.camera.height;
    let stride = nwg.x * WORKGROUP_SIZE;
    // (u, v) of `pix`, stepped along with it: one division per thread, not per pixel.
    let w = p.camera.width;
    var u = gid.x % w;
    var v = gid.x / w;
    let du = stride % w;
    let dv = stride / w;
    for (var pix = gid.x; pix < n_pix; pix += stride) {
        let row = system_row(p, vec2<u32>(u, v));
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
