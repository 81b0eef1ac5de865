// predict_model.wgsl: turns the index map into the predicted (model) vertex and normal
// maps in the WORLD frame, the ICP source, and the predicted intensity. Dispatched once per map chunk: each pass writes
// the pixels whose surfel the chunk holds, and the first chunk's pass also the pixels with
// no surfel, so every pixel is written exactly once. CPU twin: crates/core/src/cpu/predict_model.rs.
//
// Bindings (@group(0)): each is described by the comment above its declaration.
// A 2-D grid-stride loop over the pixels in 8x8 tiles (see fuse_flags.wgsl).

// Only camera.width and camera.height are used.
@group(0) @binding(0) var<storage, read> params: ProjectParams;
// The u64 keys of project_model, low word (map-wide surfel index) first; (0, 0) means no
// surfel.
@group(0) @binding(1) var<storage, read> index_map: array<vec2<u32>>;
// The chunk's first map-wide index and slots.
@group(0) @binding(2) var<storage, read> chunk: MapChunk;
// The chunk's surfels, xyz world frame + weight.
@group(0) @binding(3) var<storage, read> position_weight: array<vec4<f32>>;
// Bits of the surfel normal (world frame) + last_frame (the packing:
// crates/gpu/src/map_buffers.rs).
@group(0) @binding(4) var<storage, read> normal_frame: array<vec4<u32>>;
// The chunk's surfel colours, RGB 0..255 + radius.
@group(0) @binding(5) var<storage, read> color: array<vec4<f32>>;
// Out: width x height, world frame, w = 1 / 0.
@group(0) @binding(6) var pred_vertex: texture_storage_2d<rgba32float, write>;
// Out: width x height, world frame, w = 1 / 0.
@group(0) @binding(7) var pred_normal: texture_storage_2d<rgba32float, write>;
// Out: width x height, the surfel's intensity (0..1, intensity_of its colour) for the
// photometric term (photo_reduce), INTENSITY_NONE where no surfel.
@group(0) @binding(8) var<storage, read_write> pred_intensity: array<f32>;

const TILE_X: u32 = 8u;
const TILE_Y: u32 = 8u;
#define MAP_CHUNK
#define CAMERA_PARAMS
#entry pixel_grid

// The predicted vertex and normal of pixel `texel`, if this chunk's pass writes it.
// `params` and `chunk` are main's copies of the bindings (the entry point:
// pixel_grid.wgsl).
fn per_pixel(params: ProjectParams, chunk: MapChunk, texel: vec2<u32>) {
    let key = index_map[texel.y * params.camera.width + texel.x];
    var vertex = INVALID;
    var normal = INVALID;
    var intensity = INTENSITY_NONE;
    if key.x != 0u || key.y != 0u {
        // key.x - chunk.base wraps to a huge value below the chunk: one test for both ends.
        let slot = key.x - chunk.base;
        if slot >= chunk.slots {
            return;
        }
        let p = position_weight[slot].xyz;
        let n = bitcast<vec3<f32>>(normal_frame[slot].xyz);
        vertex = vec4<f32>(p, 1.0);
        normal = vec4<f32>(n, 1.0);
        intensity = intensity_of(color[slot].xyz);
    } else if chunk.base != 0u {
        return;
    }
    textureStore(pred_vertex, texel, vertex);
    textureStore(pred_normal, texel, normal);
    pred_intensity[texel.y * params.camera.width + texel.x] = intensity;
}
