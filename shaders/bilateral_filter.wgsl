// bilateral_filter.wgsl: KinectFusion's edge-preserving bilateral filter on the depth of the
// camera-frame vertex map. CPU twin: crates/core/src/cpu/bilateral_filter.rs (its header states the
// rules, the defaults and why sigma_depth grows with depth squared).
//
// Bindings (@group(0)): each is described by the comment above its declaration.
// For each valid pixel, the weighted mean of the valid depths in its (2r+1)^2 window
// (clipped at the border), weight exp(-d_px^2 / (2 sigma_space^2)) *
// exp(-(z_n - z)^2 / (2 sigma_depth^2)), as one exp of the summed exponents; the pixel
// itself has weight 1, so the sum of weights is >= 1. Invalid pixels stay invalid.
// A 2-D grid-stride loop over the pixels in 8x8 tiles (see vertex_to_normal.wgsl).

// The intrinsics, size, window radius and sigmas (BilateralParams).
@group(0) @binding(0) var<storage, read> params: BilateralParams;
// width x height, camera frame (depth_to_vertex's output), metres, w = 1 valid / 0
// invalid; its z is the depth in metres.
@group(0) @binding(1) var vertex_map: texture_2d<f32>;
// Out: width x height, camera frame (metres), the vertex re-built (back_project) from the
// filtered depth, w = 1 / 0.
@group(0) @binding(2) var filtered_vertex: texture_storage_2d<rgba32float, write>;

// The filtered vertex of pixel (u, v), or INVALID where the pixel's vertex is invalid.
// `params` is main's copy of the binding (see pixel_grid.wgsl).
fn filtered_at(params: BilateralParams, u: u32, v: u32) -> vec4<f32> {
    let c = textureLoad(vertex_map, vec2<u32>(u, v), 0);
    if !is_valid(c) {
        return INVALID;
    }
    let r = params.radius_px;
    let u_lo = select(u - r, 0u, u < r);
    let v_lo = select(v - r, 0u, v < r);
    let u_hi = min(u + r, params.camera.width - 1u);
    let v_hi = min(v + r, params.camera.height - 1u);
    let k_space = 1.0 / (2.0 * params.sigma_space_px * params.sigma_space_px);
    let sigma_depth = params.sigma_depth_m + params.sigma_depth_per_m2 * c.z * c.z;
    let k_depth = 1.0 / (2.0 * sigma_depth * sigma_depth);
    var sum_w = 0.0;
    var sum_wz = 0.0;
    for (var nv = v_lo; nv <= v_hi; nv++) {
        for (var nu = u_lo; nu <= u_hi; nu++) {
            let n = textureLoad(vertex_map, vec2<u32>(nu, nv), 0);
            if is_valid(n) {
                let du = f32(nu) - f32(u);
                let dv = f32(nv) - f32(v);
                let dz = n.z - c.z;
                let w = exp(-((du * du + dv * dv) * k_space) - dz * dz * k_depth);
                sum_w += w;
                sum_wz += w * n.z;
            }
        }
    }
    let cam = camera_intrinsics(params.camera);
    return valid_entry(back_project(cam, vec2<u32>(u, v), sum_wz / sum_w));
}

const TILE_X: u32 = 8u;
const TILE_Y: u32 = 8u;

// One pixel of the 2-D grid-stride loop in tiles (the entry point: pixel_grid.wgsl).
fn per_pixel(p: BilateralParams, texel: vec2<u32>) {
    textureStore(filtered_vertex, texel, filtered_at(p, texel.x, texel.y));
}

#define CAMERA_PARAMS
#entry pixel_grid
