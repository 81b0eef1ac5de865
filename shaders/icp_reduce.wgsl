// icp_reduce.wgsl: projective data association, both filters, the weighted point-to-plane
// row and the reduction to one 29-float normal-equation partial per workgroup.
// CPU twin: crates/core/src/cpu/icp_reduce.rs (its header states the maths, the filters and weights).
//
// Bindings (@group(0)): each is described by the comment above its declaration.
// The loop over the pixels and the reduction: system_grid.wgsl (`#entry system_grid`).

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

// Axial depth noise of a Kinect-like sensor at depth z (metres), after Nguyen, Izadi and
// Lovell (2012): sigma(z) = 0.0012 + 0.0019 (z - 0.4)^2. Mirrors the twin's constants.
const NOISE_SIGMA_0_M: f32 = 0.0012;
const NOISE_SIGMA_QUAD: f32 = 0.0019;
const NOISE_Z_0_M: f32 = 0.4;

// Row weight of the depth noise at z: (sigma(0.4 m) / sigma(z))^2, 1 at 0.4 m and less
// beyond. Mirrors `noise_weight` in crates/core/src/cpu/icp_reduce.rs.
fn noise_weight(z: f32) -> f32 {
    let dz = z - NOISE_Z_0_M;
    let sigma = NOISE_SIGMA_0_M + NOISE_SIGMA_QUAD * dz * dz;
    let r = NOISE_SIGMA_0_M / sigma;
    return r * r;
}

// The row of source pixel `src_texel`, or valid = false when a filter rejects it; weighted rows
// are scaled by sqrt(weight), so AᵀA and Aᵀb carry the weight once.
// Mirrors `icp_row` in crates/core/src/cpu/icp_reduce.rs; system_grid.wgsl's main calls it for each
// pixel with its copy of the params.
fn system_row(params: IcpParams, src_texel: vec2<u32>) -> IcpRow {
    var row: IcpRow;
    row.valid = false;
    let src_world = textureLoad(pred_vertex, src_texel, 0);
    if !is_valid(src_world) {
        return row;
    }
    let cam = camera_intrinsics(params.camera);
    let p = transform_point(params.t_world_to_cam, xyz(src_world));
    let uv = project_to_texel(cam, params.camera.width, params.camera.height, p);
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
    if length(d) >= params.dist_m {
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
    var w = huber_weight(b, params.huber_m);
    if params.noise_weighting != 0u {
        w = w * noise_weight(q.z);
    }
    return scaled_row(p, n, b, sqrt(w));
}

#entry system_grid
