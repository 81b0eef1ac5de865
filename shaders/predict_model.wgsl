// predict_model.wgsl: turns the index map into the predicted (model) vertex and normal
// maps in the WORLD frame, the ICP source. CPU twin: src/cpu/predict_model.rs.
//
// Bindings (@group(0)):
//   0 params       storage read ProjectParams (only width and height are used)
//   1 index_map    storage read   array<vec2<u32>>: the u64 keys of project_model, low word
//                                 (surfel index) first; (0, 0) means no surfel
//   2 position_weight  texture_2d<f32>: surfel xyz (world frame) + weight, surfel_texel(i)
//   3 normal_frame     texture_2d<u32>: bits of the surfel normal (world frame) + last_frame
//   (the packing is documented in src/gpu/map_textures.rs)
//   4 pred_vertex  storage texture rgba32float, write: width x height, world frame, w = 1 / 0
//   5 pred_normal  storage texture rgba32float, write: width x height, world frame, w = 1 / 0
// One thread per pixel (8x8 workgroups).

@group(0) @binding(0) var<storage, read> params: ProjectParams;
@group(0) @binding(1) var<storage, read> index_map: array<vec2<u32>>;
@group(0) @binding(2) var position_weight: texture_2d<f32>;
@group(0) @binding(3) var normal_frame: texture_2d<u32>;
@group(0) @binding(4) var pred_vertex: texture_storage_2d<rgba32float, write>;
@group(0) @binding(5) var pred_normal: texture_storage_2d<rgba32float, write>;

// One thread per pixel in 8x8 tiles (see vertex_to_normal.wgsl).
@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= params.width || gid.y >= params.height {
        return;
    }
    let key = index_map[gid.y * params.width + gid.x];
    var vertex = INVALID;
    var normal = INVALID;
    if key.x != 0u || key.y != 0u {
        let surfel = surfel_texel(key.x);
        let p = textureLoad(position_weight, surfel, 0).xyz;
        let n = bitcast<vec3<f32>>(textureLoad(normal_frame, surfel, 0).xyz);
        vertex = vec4<f32>(p, 1.0);
        normal = vec4<f32>(n, 1.0);
    }
    textureStore(pred_vertex, gid.xy, vertex);
    textureStore(pred_normal, gid.xy, normal);
}
