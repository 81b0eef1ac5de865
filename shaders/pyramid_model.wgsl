// pyramid_model.wgsl: the next coarser level of the predicted (model) maps, the ICP source,
// by subsampling. CPU twin: crates/core/src/cpu/pyramid_model.rs (its header says why subsampling).
//
// Bindings (@group(0)): each is described by the comment above its declaration.
// Coarse pixel (u, v) is a copy of finer pixel (2u, 2v) (the frame pyramid's sampling);
// the finer level is at least 2 width - 1 by 2 height - 1, so the texel exists.
// A 2-D grid-stride loop over the coarse pixels in 4x16 tiles (see main and vertex_to_normal.wgsl).

// Only camera.width and camera.height, the coarse size, are used.
@group(0) @binding(0) var<storage, read> params: PyramidParams;
// The finer level's pred_vertex, WORLD frame, w = 1 / 0.
@group(0) @binding(1) var fine_pred_vertex: texture_2d<f32>;
// The finer level's pred_normal, WORLD frame, w = 1 / 0.
@group(0) @binding(2) var fine_pred_normal: texture_2d<f32>;
// Out: the level's pred_vertex, width x height, WORLD frame.
@group(0) @binding(3) var pred_vertex: texture_storage_2d<rgba32float, write>;
// Out: the level's pred_normal, width x height, WORLD frame.
@group(0) @binding(4) var pred_normal: texture_storage_2d<rgba32float, write>;

// Tiles 4 pixels wide and 16 high: on lavapipe this copy-and-convert kernel measured 0.6-0.7x
// the time of 8x8 tiles at 640x480 (4x4, 4x8 and 4x16 alike; 2x32 and 1x64 slower; why was
// not established). The kernels that read a window around each pixel were slower in
// 4-wide tiles, so they keep 8x8.
const TILE_X: u32 = 4u;
const TILE_Y: u32 = 16u;

// Coarse pixel `texel` takes its fine pixel 2 texel (the entry point: pixel_grid.wgsl).
fn per_pixel(p: PyramidParams, texel: vec2<u32>) {
    let fine = 2u * texel;
    textureStore(pred_vertex, texel, textureLoad(fine_pred_vertex, fine, 0));
    textureStore(pred_normal, texel, textureLoad(fine_pred_normal, fine, 0));
}

#define CAMERA_PARAMS
#entry pixel_grid
