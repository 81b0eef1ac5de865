// pyramid_depth.wgsl: the next coarser level of the frame's ICP pyramid, an edge-aware
// average of the finer level's depth (KinectFusion's pyramid step). CPU twin:
// crates/core/src/cpu/pyramid_depth.rs (its header states the rules and the sampling convention).
//
// Bindings (@group(0)): each is described by the comment above its declaration.
// Coarse pixel (u, v) samples finer pixel (2u, 2v): invalid where that pixel is invalid,
// else the plain mean of the valid depths in the (2r+1)^2 window around it (clipped at the
// border) that lie within the depth gate of its depth (the pixel itself always does).
// A 2-D grid-stride loop over the coarse pixels in 8x8 tiles (see vertex_to_normal.wgsl).

// Coarse intrinsics and size, the finer size, the window and the depth gate.
@group(0) @binding(0) var<storage, read> params: PyramidParams;
// fine_width x fine_height, camera frame (metres), w = 1 / 0 (the finer level's vertex
// map: at level 0 the one the normals are made from).
@group(0) @binding(1) var fine_vertex: texture_2d<f32>;
// Out: the level's vertex map, width x height, camera frame (metres), the vertex re-built
// (back_project, coarse intrinsics) from the mean depth, w = 1 / 0.
@group(0) @binding(2) var vertex_map: texture_storage_2d<rgba32float, write>;

// The coarse vertex of pixel (u, v), or INVALID (the rules of the header). `params` is
// main's copy of the binding (see pixel_grid.wgsl).
fn coarse_at(params: PyramidParams, u: u32, v: u32) -> vec4<f32> {
    let fu = 2u * u;
    let fv = 2u * v;
    let c = textureLoad(fine_vertex, vec2<u32>(fu, fv), 0);
    if !is_valid(c) {
        return INVALID;
    }
    let r = params.radius_px;
    let u_lo = select(fu - r, 0u, fu < r);
    let v_lo = select(fv - r, 0u, fv < r);
    let u_hi = min(fu + r, params.fine_width - 1u);
    let v_hi = min(fv + r, params.fine_height - 1u);
    let gate = params.max_depth_diff_m + params.max_depth_diff_per_m2 * c.z * c.z;
    var sum_z = 0.0;
    var count = 0.0;
    for (var nv = v_lo; nv <= v_hi; nv++) {
        for (var nu = u_lo; nu <= u_hi; nu++) {
            let n = textureLoad(fine_vertex, vec2<u32>(nu, nv), 0);
            if is_valid(n) && abs(n.z - c.z) <= gate {
                sum_z += n.z;
                count += 1.0;
            }
        }
    }
    let cam = camera_intrinsics(params.camera);
    return valid_entry(back_project(cam, vec2<u32>(u, v), sum_z / count));
}

const TILE_X: u32 = 8u;
const TILE_Y: u32 = 8u;

// One pixel of the 2-D grid-stride loop in tiles (the entry point: pixel_grid.wgsl).
fn per_pixel(p: PyramidParams, texel: vec2<u32>) {
    textureStore(vertex_map, texel, coarse_at(p, texel.x, texel.y));
}

#define CAMERA_PARAMS
#entry pixel_grid
