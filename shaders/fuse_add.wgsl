// fuse_add.wgsl: appends every pixel fuse_flags flagged (a valid measurement no surfel
// merged with or covers) as a new surfel at slot surfel_count + offsets[append_index(pixel)]
// (prefix_sum of the flags, so new surfels lie in append order, see layout::APPEND_TILE_PX,
// as on the CPU, and two runs write the same map): world frame, weight pixel_confidence,
// radius surfel_radius. Last of three kernels (fuse_flags, prefix_sum, fuse_add).
// Dispatched once per map chunk: each pass writes the new surfels whose slots the chunk
// holds. CPU twin: crates/core/src/cpu/fuse_add.rs.
//
// Bindings (@group(0)): each is described by the comment above its declaration.
// A 2-D grid-stride loop over the pixels in 8x8 tiles (see fuse_flags.wgsl). Never writes
// at or past params.capacity (the host grows the map first so that every pixel fits).
// Two variants (keep_nearer and first_key_pass in shaders/key_writer.wgsl, appended, and
// index_map's type are all that differ): KEY_64, one u64 atomicMax per new surfel (needs
// SHADER_INT64_ATOMIC_MIN_MAX); else fuse_add_portable on fuse_select_portable's (low,
// high) u32 words, dispatched once per chunk and pass: KEY_PASS 0 over every chunk writes
// the new surfels and raises the depth words, KEY_PASS 1 over every chunk (with
// best-candidate association only: it writes nothing else) sets the index words. A new
// surfel's index is larger than every index already in the map (new surfels are
// appended), so where its depth word is the pixel's the index word becomes its index, and
// the pair equals the 64-bit key bit for bit.

// Uses t_cam_to_world, surfel_count, frame_id and capacity.
@group(0) @binding(0) var<storage, read> params: FuseParams;
// width x height, camera-frame normal with the vertex's depth in w, zero where invalid
// (see vertex_to_normal.wgsl); the vertex is rebuilt with back_project, as in the twin.
@group(0) @binding(1) var normal_depth: texture_2d<f32>;
// width x height, RGB 0..255.
@group(0) @binding(2) var color_map: texture_2d<f32>;
// 1 where the pixel becomes a new surfel (fuse_flags), at the pixel's append_index.
@group(0) @binding(3) var<storage, read> flags: array<u32>;
// Exclusive prefix sum of flags (prefix_sum).
@group(0) @binding(4) var<storage, read> offsets: array<u32>;
// The chunk's first map-wide index and slots: map-wide surfel i is element i - chunk.base
// of the chunk's arrays, which hold chunk.slots entries each (see crates/gpu/src/map_buffers.rs).
@group(0) @binding(5) var<storage, read> chunk: MapChunk;
// Out: xyz world frame, w = confidence.
@group(0) @binding(6) var<storage, read_write> position_weight: array<vec4<f32>>;
// Out: normal bits, w = last_frame.
@group(0) @binding(7) var<storage, read_write> normal_frame: array<vec4<u32>>;
// Out: RGB 0..255, a = radius (metres).
@group(0) @binding(8) var<storage, read_write> color: array<vec4<f32>>;
// With best-candidate association, the index map fuse_select began (a u64 per pixel, or
// without KEY_64 (low, high) u32 words); each new surfel competes for its own pixel with
// the key (depth_key(z_cam), map-wide index), as project_model's (left alone otherwise).
#ifdef KEY_64
@group(0) @binding(9) var<storage, read_write> index_map: array<atomic<u64>>;
#else
@group(0) @binding(9) var<storage, read_write> index_map: array<atomic<u32>>;
#endif

const TILE_X: u32 = 8u;
const TILE_Y: u32 = 8u;
#define MAP_CHUNK
#define CAMERA_PARAMS
#entry pixel_grid

// Pixel `texel`'s new surfel, if the pixel is flagged and its slot is in this chunk.
// `params` and `chunk` are main's copies of the bindings (the entry point:
// pixel_grid.wgsl).
fn per_pixel(params: FuseParams, chunk: MapChunk, texel: vec2<u32>) {
    let a = append_index(texel);
    if flags[a] == 0u {
        return;
    }
    let nd = textureLoad(normal_depth, texel, 0);
    let i = params.surfel_count + offsets[a];
    // i - chunk.base wraps to a huge value below the chunk: one test for both ends.
    let slot = i - chunk.base;
    if i >= params.capacity || slot >= chunk.slots {
        return;
    }
    let cam = camera_intrinsics(params.camera);
    let q_cam = back_project(cam, texel, nd.w);
    let p = transform_point(params.t_cam_to_world, q_cam);
    let n = transform_dir(params.t_cam_to_world, xyz(nd));
    let w = pixel_confidence(cam, texel, params.confidence_sigma);
    let r = surfel_radius(params.camera.fx, q_cam, xyz(nd));
    if first_key_pass() {
        position_weight[slot] = vec4<f32>(p, w);
        normal_frame[slot] = vec4<u32>(bitcast<vec3<u32>>(n), params.frame_id);
        color[slot] = vec4<f32>(textureLoad(color_map, texel, 0).xyz, r);
    }
    if params.association == ASSOCIATION_BEST_CANDIDATE {
        keep_nearer(texel.y * params.camera.width + texel.x, depth_key(q_cam.z), i);
    }
}
