// project_model.wgsl: splats every surfel of one map chunk into an index map with a depth
// test, one key per pixel, skipping blocks the camera cannot see. Dispatched once per
// chunk (and key pass). CPU twin: crates/core/src/cpu/project_model.rs.
//
// Bindings (@group(0)): each is described by the comment above its declaration.
// Key = (u64(depth_key(z_cam)) << 32) | map-wide surfel index; the pixel keeps the maximum
// (nearest surfel, ties to the larger index); 0 means no surfel. Two variants from this
// file (crates/gpu/src/shaders.rs, docs/portable-gpu.md): KEY_64 defined, one atomicMax on a u64
// per pixel (needs SHADER_INT64_ATOMIC_MIN_MAX); else project_model_portable, the key as
// (low, high) u32 words in two passes (KEY_PASS), equal bit for bit. keep_nearer
// (shaders/key_writer.wgsl, appended) and index_map's type are all that differ.
// Workgroups stride over the chunk's blocks; a block
// whose box block_visible rejects is skipped whole (conservative: no surfel that would
// land in the image is skipped); the workgroup's threads stride over a visible block.

// Uses t_world_to_cam, the intrinsics, the map size and surfel_count.
@group(0) @binding(0) var<storage, read> params: ProjectParams;
// The chunk's first map-wide index and slots.
@group(0) @binding(1) var<storage, read> chunk: MapChunk;
// Per block, min (2b) and max (2b + 1) corner of its surfels' world-frame box,
// ordered_from_f32 encoded.
@group(0) @binding(2) var<storage, read> block_boxes: array<vec4<u32>>;
// The chunk's surfels, xyz world frame (metres) + weight (see crates/gpu/src/map_buffers.rs).
@group(0) @binding(3) var<storage, read> position_weight: array<vec4<f32>>;
// width x height keys, cleared to 0 by the host (before pass 0): one u64 each, or
// without KEY_64 two u32 words each (low = index, high = depth word).
#ifdef KEY_64
@group(0) @binding(4) var<storage, read_write> index_map: array<atomic<u64>>;
#else
@group(0) @binding(4) var<storage, read_write> index_map: array<atomic<u32>>;
#endif

#entry visible_surfels

// Surfel i keeps the nearer of its pixel's key and its own, if its centre lands in the
// image. `view` is main's copy of the params; `slot` is i in the chunk's arrays.
fn per_surfel(view: ProjectParams, i: u32, slot: u32, cam: vec4<f32>) {
    let p = transform_point(view.t_world_to_cam, xyz(position_weight[slot]));
    let pix = project_to_pixel(cam, view.camera.width, view.camera.height, p);
    if pix >= 0 {
        keep_nearer(u32(pix), depth_key(p.z), i);
    }
}
