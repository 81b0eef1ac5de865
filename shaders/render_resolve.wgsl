// render_resolve.wgsl: shades each pixel of a render_splat index map from its winning
// surfel (colour, normal, weight or depth), background where empty.
// CPU twin: crates/core/src/cpu/render_resolve.rs.
//
// Prepended with common.wgsl. Bindings (@group(0)): each is described by the
// comment above its declaration.
// One pixel per invocation (grid-stride, so any workgroup count works).
// Gap filling (params.fill_gap_px > 0): an empty pixel with covered pixels at most
// fill_gap_px away on both sides (above and below, or left and right) whose depths agree
// within GAP_DEPTH_TOLERANCE shows the nearer of the two (see crates/core/src/cpu/render_resolve.rs).

// RenderParams (mirrors `layout::render::RenderParams`) lives in common.wgsl.

// Mirror `layout::render::VIEW_*`.
const VIEW_COLOR: u32 = 0u;
const VIEW_NORMALS: u32 = 1u;
const VIEW_WEIGHT: u32 = 2u;
const VIEW_DEPTH: u32 = 3u;

// Mirror `cpu::render_resolve::RAMP_*`.
const RAMP_LOW: vec3<f32> = vec3<f32>(0.267, 0.005, 0.329);
const RAMP_MID: vec3<f32> = vec3<f32>(0.128, 0.567, 0.551);
const RAMP_HIGH: vec3<f32> = vec3<f32>(0.993, 0.906, 0.144);

// Mirrors `cpu::render_resolve::GAP_DEPTH_TOLERANCE`.
const GAP_DEPTH_TOLERANCE: f32 = 0.05;

// The view (RenderParams mirrors crates/core/src/layout/render.rs).
@group(0) @binding(0) var<storage, read> params: RenderParams;
// width x height: the u64 keys of render_splat read as (low, high) words,
// little-endian: x = surfel index, y = ~bits(z_cam).
@group(0) @binding(1) var<storage, read> index_map: array<vec2<u32>>;
// Per surfel index, the normal, world frame (VIEW_NORMALS only).
@group(0) @binding(2) var<storage, read> normals: array<vec4<f32>>;
// Per surfel index, the colour, RGB 0..255 (VIEW_COLOR only).
@group(0) @binding(3) var<storage, read> colors: array<vec4<f32>>;
// Per surfel index, the weight (VIEW_WEIGHT only).
@group(0) @binding(4) var<storage, read> weights: array<f32>;
// Out: width x height, r | g << 8 | b << 16 | 255 << 24.
@group(0) @binding(5) var<storage, read_write> out_rgba: array<u32>;

// Camera depth (metres) of a non-zero key. Mirrors `cpu::render_resolve::key_depth`.
fn key_depth(key: vec2<u32>) -> f32 {
    return bitcast<f32>(~key.y);
}

// Key order (high word, then low word), as the u64 keys compare.
fn key_max(a: vec2<u32>, b: vec2<u32>) -> vec2<u32> {
    if a.y > b.y || (a.y == b.y && a.x >= b.x) {
        return a;
    }
    return b;
}

fn is_empty(key: vec2<u32>) -> bool {
    return key.x == 0u && key.y == 0u;
}

// The first non-empty key at most fill_gap_px pixels from (x, y) in the direction
// (dx, dy), or empty. Mirrors `cpu::render_resolve::nearest_covered`.
fn nearest_covered(x: i32, y: i32, dx: i32, dy: i32) -> vec2<u32> {
    for (var s = 1; s <= i32(params.fill_gap_px); s++) {
        let qx = x + dx * s;
        let qy = y + dy * s;
        if qx < 0 || qy < 0 || qx >= i32(params.camera.width) || qy >= i32(params.camera.height) {
            break;
        }
        let key = index_map[u32(qy) * params.camera.width + u32(qx)];
        if !is_empty(key) {
            return key;
        }
    }
    return vec2<u32>(0u, 0u);
}

// The nearer of two keys when both are covered and their depths agree, else empty.
// Mirrors `cpu::render_resolve::bridge`.
fn bridge(a: vec2<u32>, b: vec2<u32>) -> vec2<u32> {
    if is_empty(a) || is_empty(b) {
        return vec2<u32>(0u, 0u);
    }
    let za = key_depth(a);
    let zb = key_depth(b);
    if abs(za - zb) > GAP_DEPTH_TOLERANCE * min(za, zb) {
        return vec2<u32>(0u, 0u);
    }
    return key_max(a, b);
}

// The key an empty pixel shows after gap filling (empty: stays background).
// Mirrors `cpu::render_resolve::fill_gap`.
fn fill_gap(pix: u32) -> vec2<u32> {
    let x = i32(pix % params.camera.width);
    let y = i32(pix / params.camera.width);
    let vertical = bridge(nearest_covered(x, y, 0, -1), nearest_covered(x, y, 0, 1));
    let horizontal = bridge(nearest_covered(x, y, -1, 0), nearest_covered(x, y, 1, 0));
    return key_max(vertical, horizontal);
}

// Colour (RGB 0..1) of t on the two-segment ramp. Mirrors `cpu::render_resolve::ramp`.
fn ramp(t_in: f32) -> vec3<f32> {
    let t = clamp(t_in, 0.0, 1.0);
    if t < 0.5 {
        return mix(RAMP_LOW, RAMP_MID, t * 2.0);
    }
    return mix(RAMP_MID, RAMP_HIGH, t * 2.0 - 1.0);
}

// Mirrors `cpu::render_resolve::pack_rgb`.
fn pack_rgb(c: vec3<f32>) -> u32 {
    let q = vec3<u32>(clamp(c, vec3<f32>(0.0), vec3<f32>(255.0)) + 0.5);
    return q.x | (q.y << 8u) | (q.z << 16u) | (255u << 24u);
}

// Mirrors `cpu::render_resolve::shade`.
fn shade(index: u32, z: f32) -> vec3<f32> {
    switch params.view {
        case VIEW_COLOR: {
            return colors[index].xyz;
        }
        case VIEW_NORMALS: {
            return (normals[index].xyz + 1.0) * 127.5;
        }
        case VIEW_WEIGHT: {
            return ramp(weights[index] / params.weight_max) * 255.0;
        }
        case VIEW_DEPTH: {
            return ramp(1.0 - (z - params.near_m) / (params.far_m - params.near_m)) * 255.0;
        }
        default: {
            return vec3<f32>(0.0);
        }
    }
}

@compute @workgroup_size(64)
fn main(
    @builtin(global_invocation_id) gid: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    let stride = groups.x * 64u;
    let n = params.camera.width * params.camera.height;
    for (var pix = gid.x; pix < n; pix += stride) {
        var key = index_map[pix];
        if is_empty(key) {
            key = fill_gap(pix);
        }
        if is_empty(key) {
            out_rgba[pix] = params.background;
            continue;
        }
        let z = key_depth(key);
        out_rgba[pix] = pack_rgb(shade(key.x, z));
    }
}
