// photo_reduce.wgsl: the photometric term of RGB-D tracking: per model pixel the
// intensity residual of the new frame against the map's predicted intensity at the
// current estimate, its Jacobian row through the frame's image gradient, and the reduction
// to one 29-float normal-equation partial per workgroup (the layout of icp_reduce's).
// CPU twin: crates/core/src/cpu/photo_reduce.rs (its header states the maths and the gates).
//
// Bindings (@group(0)): each is described by the comment above its declaration.
// The loop over the pixels and the reduction: system_grid.wgsl (`#entry system_grid`).

// Current t_world_to_cam, intrinsics and the photo_* gates.
@group(0) @binding(0) var<storage, read> params: IcpParams;
// The source: level 0's prediction (whatever the level), WORLD frame, w = 1 / 0; the
// level's pixel (u, v) reads its pixel (step u, step v), step = params.photo_source_step.
@group(0) @binding(1) var level0_pred_vertex: texture_2d<f32>;
// The source's intensity (0..1; INTENSITY_NONE where no surfel), level 0's size
// (predict_model), rows of params.photo_source_width.
@group(0) @binding(2) var<storage, read> pred_intensity: array<f32>;
// The level's frame normals with the depth (metres) in w, zero where invalid: the depth
// gate.
@group(0) @binding(3) var normal_depth: texture_2d<f32>;
// The level's frame intensity patches (0..1; intensity_pyramid): texel (u, v) holds the
// intensities of (u, v), (u + 1, v), (u, v + 1), (u + 1, v + 1).
@group(0) @binding(4) var intensity_patch: texture_2d<f32>;
// Out: ICP_SYSTEM_LEN floats per workgroup (21 of JᵀJ upper triangle row-major, 6 of
// Jᵀr, count, sum of squared weighted residuals); the host sums them in f64.
@group(0) @binding(5) var<storage, read_write> partials: array<f32>;

// The bilinear interpolant of the four texel intensities i = (i00, i10, i01, i11) at
// fractions t, and its exact gradient there: (I, Ix, Iy). Mirrors `bilinear` in the twin.
fn bilinear(i: vec4<f32>, t: vec2<f32>) -> vec3<f32> {
    let top = i.x + t.x * (i.y - i.x);
    let bottom = i.z + t.x * (i.w - i.z);
    let left = i.x + t.y * (i.z - i.x);
    let right = i.y + t.y * (i.w - i.y);
    return vec3<f32>(top + t.y * (bottom - top), right - left, bottom - top);
}

// The row of source pixel `src_texel`, or valid = false when a gate rejects it, scaled by
// sqrt(weight). Mirrors `photo_row` in the twin; system_grid.wgsl's main calls it for each
// pixel with its copy of the params.
fn system_row(params: IcpParams, src_texel: vec2<u32>) -> IcpRow {
    var row: IcpRow;
    row.valid = false;
    let w = params.camera.width;
    let src = params.photo_source_step * src_texel;
    let src_world = textureLoad(level0_pred_vertex, src, 0);
    let i_model = pred_intensity[src.y * params.photo_source_width + src.x];
    if !is_valid(src_world) || i_model < 0.0 {
        return row;
    }
    let p = transform_point(params.t_world_to_cam, xyz(src_world));
    if p.z <= 0.0 {
        return row;
    }
    let x = params.camera.fx * p.x / p.z + params.camera.cx;
    let y = params.camera.fy * p.y / p.z + params.camera.cy;
    // The four texels around (x, y) inside the image.
    if !(x >= 0.0 && y >= 0.0 && x < f32(w - 1u) && y < f32(params.camera.height - 1u)) {
        return row;
    }
    // x, y >= 0: truncation is the floor.
    let u0 = u32(x);
    let v0 = u32(y);
    let t = vec2<f32>(x - f32(u0), y - f32(v0));
    let near = vec2<u32>(u0 + select(0u, 1u, t.x >= 0.5), v0 + select(0u, 1u, t.y >= 0.5));
    let nd = textureLoad(normal_depth, near, 0);
    if !is_valid(nd) || abs(nd.w - p.z) >= params.photo_depth_gate_m {
        return row;
    }
    let corners = textureLoad(intensity_patch, vec2<u32>(u0, v0), 0);
    let s = bilinear(corners, t);
    let g_min = params.photo_gradient_min;
    if s.y * s.y + s.z * s.z < g_min * g_min {
        return row;
    }
    let r = s.x - i_model;
    let sw = sqrt(huber_weight(r, params.photo_huber));
    let fgx = params.camera.fx * s.y;
    let fgy = params.camera.fy * s.z;
    let g = vec3<f32>(fgx / p.z, fgy / p.z, -((fgx * p.x + fgy * p.y) / p.z) / p.z);
    return scaled_row(p, g, r, sw);
}

#entry system_grid
