// depth_to_vertex.wgsl: raw 16-bit depth and RGBA8 to a camera-frame vertex map (metres)
// and a colour map, keeping every `stride`-th raw pixel. CPU twin: crates/core/src/cpu/depth_to_vertex.rs.
//
// Bindings (@group(0)): each is described by the comment above its declaration.
// A 2-D grid-stride loop over the output pixels in 4x16 tiles (see main and vertex_to_normal.wgsl).
// Assumes raw_width >= stride * width (and the same for height).

// Intrinsics, output and raw sizes, stride, depth scale and range (PreprocessParams).
@group(0) @binding(0) var<storage, read> params: PreprocessParams;
// r16uint: raw_width x raw_height, depth units.
@group(0) @binding(1) var raw_depth: texture_2d<u32>;
// rgba8uint: raw_width x raw_height, RGBA 0..255.
@group(0) @binding(2) var raw_rgba: texture_2d<u32>;
// Out: width x height, camera frame (metres), w = 1 / 0.
@group(0) @binding(3) var vertex_map: texture_storage_2d<rgba32float, write>;
// Out: width x height, RGB 0..255, a = 255.
@group(0) @binding(4) var color_map: texture_storage_2d<rgba32float, write>;

// Converts output pixel (u, v). `params` is main's copy of the binding (see main).
fn convert_at(params: PreprocessParams, u: u32, v: u32) {
    let texel = vec2<u32>(u, v);
    let raw = vec2<u32>(u * params.stride, v * params.stride);
    let z = f32(textureLoad(raw_depth, raw, 0).x) / params.depth_scale;
    let c = textureLoad(raw_rgba, raw, 0);
    textureStore(color_map, texel, vec4<f32>(vec3<f32>(c.xyz), 255.0));
    var vertex = INVALID;
    if z > 0.0 && z >= params.min_depth_m && z <= params.max_depth_m {
        let cam = camera_intrinsics(params.camera);
        vertex = valid_entry(back_project(cam, texel, z));
    }
    textureStore(vertex_map, texel, vertex);
}

// Tiles 4 pixels wide and 16 high: on lavapipe this copy-and-convert kernel measured 0.6-0.7x
// the time of 8x8 tiles at 640x480 (4x4, 4x8 and 4x16 alike; 2x32 and 1x64 slower; why was
// not established). The kernels that read a window around each pixel were slower in
// 4-wide tiles, so they keep 8x8.
const TILE_X: u32 = 4u;
const TILE_Y: u32 = 16u;

// One pixel of the 2-D grid-stride loop in tiles (the entry point: pixel_grid.wgsl).
fn per_pixel(p: PreprocessParams, texel: vec2<u32>) {
    convert_at(p, texel.x, texel.y);
}

#define CAMERA_PARAMS
#entry pixel_grid
