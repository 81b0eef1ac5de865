// intensity_pyramid.wgsl: one level of the frame's intensity pyramid for the photometric
// term (photo_reduce): per pixel its intensity patch, the intensities (0..1) of texels
// (u, v), (u + 1, v), (u, v + 1), (u + 1, v + 1), clamped to the level. Level 0's
// intensity is the colour map's luma; a coarser level's is the [1 2 1] x [1 2 1] / 16 mean
// of the finer level's around finer pixel (2u, 2v). Run once per frame, with RGB-D
// tracking only.
// CPU twin: crates/core/src/cpu/intensity_pyramid.rs (its header states the rules).
//
// Bindings (@group(0)): each is described by the comment above its declaration.
// A 2-D grid-stride loop over the level's pixels in 8x8 tiles (pixel_grid.wgsl).

// The level, its size and the size of the map read.
@group(0) @binding(0) var<storage, read> params: IntensityParams;
// fine_width x fine_height: at level 0 the frame's colour map (RGB 0..255,
// depth_to_vertex), at a coarser level the finer level's intensity patches (x: intensity).
@group(0) @binding(1) var fine_map: texture_2d<f32>;
// Out: width x height intensity patches (0..1).
@group(0) @binding(2) var intensity_patch: texture_storage_2d<rgba32float, write>;

// The intensity of the map read at texel (x, y), clamped to it. Mirrors `fine_intensity`
// in the twin.
fn fine_intensity(params: IntensityParams, x: i32, y: i32) -> f32 {
    let xc = clamp(x, 0, i32(params.fine_width) - 1);
    let yc = clamp(y, 0, i32(params.fine_height) - 1);
    let t = textureLoad(fine_map, vec2<i32>(xc, yc), 0);
    if params.level == 0u {
        return intensity_of(t.xyz);
    }
    return t.x;
}

// This level's intensity at pixel (u, v), clamped to the level. Mirrors `level_intensity`
// in the twin (the same order of adds).
fn level_intensity(params: IntensityParams, u: i32, v: i32) -> f32 {
    let uc = clamp(u, 0, i32(params.width) - 1);
    let vc = clamp(v, 0, i32(params.height) - 1);
    if params.level == 0u {
        return fine_intensity(params, uc, vc);
    }
    let binomial = array<f32, 3>(0.25, 0.5, 0.25);
    var sum = 0.0;
    for (var j = 0; j < 3; j++) {
        for (var i = 0; i < 3; i++) {
            let w = binomial[i] * binomial[j];
            sum += w * fine_intensity(params, 2 * uc + i - 1, 2 * vc + j - 1);
        }
    }
    return sum;
}

const TILE_X: u32 = 8u;
const TILE_Y: u32 = 8u;

// One pixel of the 2-D grid-stride loop in tiles (the entry point: pixel_grid.wgsl).
fn per_pixel(p: IntensityParams, texel: vec2<u32>) {
    let u = i32(texel.x);
    let v = i32(texel.y);
    let corners = vec4<f32>(
        level_intensity(p, u, v),
        level_intensity(p, u + 1, v),
        level_intensity(p, u, v + 1),
        level_intensity(p, u + 1, v + 1),
    );
    textureStore(intensity_patch, texel, corners);
}

#entry pixel_grid
