// fuse_add.wgsl: appends every valid pixel no surfel merged with (projective association)
// or covers (best candidate) as a new surfel (world frame, weight pixel_confidence, radius
// surfel_radius) through an atomic counter. CPU twin: src/cpu/fuse_add.rs.
//
// Bindings (@group(0)):
//   0 params      uniform FuseParams (t_cam_to_world, frame_id, capacity)
//   1 normal_depth  texture_2d<f32>: width x height, camera-frame normal with the vertex's
//                   depth in w, zero where invalid (see vertex_to_normal.wgsl); the vertex
//                   is rebuilt with back_project, as in the twin
//   2 color_map   texture_2d<f32>: width x height, RGB 0..255
//   3 assoc       storage read   array<vec2<u32>>: the u64 key per pixel (low word first),
//                 non-zero where a surfel merged with or was chosen by the pixel
//   4 counter     storage rw     atomic<u32>: surfels in the map (in: before, out: after)
//   5 position_weight  storage texture rgba32float, write: xyz world frame, w = confidence
//   6 normal_frame     storage texture rgba32uint, write: normal bits, w = last_frame
//   7 color            storage texture rgba32float, write: RGB 0..255, a = radius (m)
//   (surfel i is texel surfel_texel(i) of each; capacity slots; see src/gpu/map_textures.rs)
// One thread per pixel (8x8 workgroups); the append order is the atomics' order, not pixel order. Never
// writes at or past params.capacity: the counter still counts, and the host turns a count
// above capacity into a capacity error.

@group(0) @binding(0) var<uniform> params: FuseParams;
@group(0) @binding(1) var normal_depth: texture_2d<f32>;
@group(0) @binding(2) var color_map: texture_2d<f32>;
@group(0) @binding(3) var<storage, read> assoc: array<vec2<u32>>;
@group(0) @binding(4) var<storage, read_write> counter: atomic<u32>;
@group(0) @binding(5) var position_weight: texture_storage_2d<rgba32float, write>;
@group(0) @binding(6) var normal_frame: texture_storage_2d<rgba32uint, write>;
@group(0) @binding(7) var color: texture_storage_2d<rgba32float, write>;

// One thread per pixel in 8x8 tiles (see vertex_to_normal.wgsl).
@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= params.width || gid.y >= params.height {
        return;
    }
    let key = assoc[gid.y * params.width + gid.x];
    if key.x != 0u || key.y != 0u {
        return;
    }
    // Valid normal (w = depth > 0) implies a valid vertex: the twin's two tests.
    let nd = textureLoad(normal_depth, gid.xy, 0);
    if !is_valid(nd) {
        return;
    }
    let i = atomicAdd(&counter, 1u);
    if i >= params.capacity {
        return;
    }
    let cam = vec4<f32>(params.fx, params.fy, params.cx, params.cy);
    let q_cam = back_project(cam, gid.xy, nd.w);
    let p = transform_point(params.t_cam_to_world, q_cam);
    let n = transform_dir(params.t_cam_to_world, xyz(nd));
    let w = pixel_confidence(cam, gid.xy, params.confidence_sigma);
    let r = surfel_radius(params.fx, q_cam, xyz(nd));
    let surfel = surfel_texel(i);
    textureStore(position_weight, surfel, vec4<f32>(p, w));
    textureStore(normal_frame, surfel, vec4<u32>(bitcast<vec3<u32>>(n), params.frame_id));
    textureStore(color, surfel, vec4<f32>(textureLoad(color_map, gid.xy, 0).xyz, r));
}
