// vertex_to_normal.wgsl: normal map from the vertex map by central differences, oriented
// towards the camera, with each pixel's depth from the point map. CPU twin:
// crates/core/src/cpu/vertex_to_normal.rs (its header states the rules).
//
// Bindings (@group(0)): each is described by the comment above its declaration.
// A valid normal implies a valid vertex, and every later kernel that reads this frame needs
// both, so the normal and the depth share one texel and those kernels (icp_reduce,
// fuse_merge, fuse_add, and their twins) rebuild the vertex with back_project
// (common.wgsl), the function depth_to_vertex made it with: one texel fetch instead of two
// per association.
// A 2-D grid-stride loop over the pixels in 8x8 tiles (pixel_grid.wgsl). Invalid on the border, next to an invalid vertex, across a depth
// jump larger than max_depth_jump_m, or where the cross product vanishes.

// The size and max_depth_jump_m.
@group(0) @binding(0) var<storage, read> params: NormalParams;
// width x height, camera frame (metres), w = 1 / 0.
@group(0) @binding(1) var vertex_map: texture_2d<f32>;
// Out: width x height; xyz = the unit normal (camera frame), w = the point map's depth z
// (metres, > 0) where the normal and the point are valid; all zero where not.
@group(0) @binding(2) var normal_depth: texture_storage_2d<rgba32float, write>;
// width x height, camera frame (metres), w = 1 / 0: the points whose depth the texel
// carries, which ICP and fusion rebuild; vertex_map itself, or at level 0 with the
// bilateral filter the unfiltered map (the robust profile's raw points, see the twin).
@group(0) @binding(3) var point_map: texture_2d<f32>;

// The normal of pixel (u, v) with the pixel's depth in w, or INVALID (the rules of the
// module header). `params` is main's copy of the binding (see main).
fn normal_at(params: NormalParams, u: u32, v: u32) -> vec4<f32> {
    if u == 0u || v == 0u || u + 1u >= params.width || v + 1u >= params.height {
        return INVALID;
    }
    let c = textureLoad(vertex_map, vec2<u32>(u, v), 0);
    let l = textureLoad(vertex_map, vec2<u32>(u - 1u, v), 0);
    let r = textureLoad(vertex_map, vec2<u32>(u + 1u, v), 0);
    let t = textureLoad(vertex_map, vec2<u32>(u, v - 1u), 0);
    let b = textureLoad(vertex_map, vec2<u32>(u, v + 1u), 0);
    if !(is_valid(c) && is_valid(l) && is_valid(r) && is_valid(t) && is_valid(b)) {
        return INVALID;
    }
    let jump = params.max_depth_jump_m;
    if abs(l.z - c.z) > jump || abs(r.z - c.z) > jump || abs(t.z - c.z) > jump
        || abs(b.z - c.z) > jump {
        return INVALID;
    }
    let n = cross(xyz(r) - xyz(l), xyz(b) - xyz(t));
    let len = length(n);
    if len <= 1e-12 {
        return INVALID;
    }
    var nn = n / len;
    if dot(nn, xyz(c)) > 0.0 {
        nn = -nn;
    }
    let point = textureLoad(point_map, vec2<u32>(u, v), 0);
    if !is_valid(point) {
        return INVALID;
    }
    return vec4<f32>(nn, point.z);
}

const TILE_X: u32 = 8u;
const TILE_Y: u32 = 8u;

// One pixel of the 2-D grid-stride loop in tiles (the entry point: pixel_grid.wgsl).
fn per_pixel(p: NormalParams, texel: vec2<u32>) {
    textureStore(normal_depth, texel, normal_at(p, texel.x, texel.y));
}

#entry pixel_grid
