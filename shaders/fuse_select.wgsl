// fuse_select.wgsl: every pixel picks the one surfel it will fuse with among those whose
// centres project into it (best-candidate association, robust profile), before
// fuse_merge_chosen and fuse_add. Dispatched once per map chunk (and key pass). CPU twin:
// crates/core/src/cpu/fuse_select.rs (its header states the gates and the choice).
//
// Bindings (@group(0)): each is described by the comment above its declaration.
// Workgroups stride over the chunk's blocks, skipping those block_visible rejects (a
// surfel whose centre misses the image is skipped anyway); threads stride over a block.
// The atomicMaxes keep the surfel nearest each pixel's ray, and the one nearest the camera
// (ties to the larger index), whatever the thread order. Two variants (keep_nearer in
// shaders/key_writer.wgsl, appended, keep_best below, and the key maps' types are all that
// differ): KEY_64, one u64 atomicMax per key (needs SHADER_INT64_ATOMIC_MIN_MAX); else
// fuse_select_portable, each key as (low, high) u32 words in two passes (KEY_PASS 0 over
// every chunk, then 1), equal bit for bit.

// Tracked pose, intrinsics, surfel_count, gates.
@group(0) @binding(0) var<storage, read> params: FuseParams;
// width x height, camera-frame normal with the depth in w, zero where invalid; the vertex
// is rebuilt with back_project.
@group(0) @binding(1) var normal_depth: texture_2d<f32>;
// The chunk's first map-wide index and slots; the chunk's arrays hold its surfels from
// slot 0 (see crates/gpu/src/map_buffers.rs).
@group(0) @binding(2) var<storage, read> chunk: MapChunk;
// Per block, min (2b) and max (2b + 1) corner of its surfels' world-frame box,
// ordered_from_f32 encoded.
@group(0) @binding(3) var<storage, read> block_boxes: array<vec4<u32>>;
// The chunk's surfels, xyz world frame (metres), w = confidence.
@group(0) @binding(4) var<storage, read> position_weight: array<vec4<f32>>;
// Bits of the unit normal (world frame), w = last frame.
@group(0) @binding(5) var<storage, read> normal_frame: array<vec4<u32>>;
// RGB 0..255, a = radius (metres).
@group(0) @binding(6) var<storage, read> color: array<vec4<f32>>;
// One key per pixel (a u64, or without KEY_64 (low, high) u32 words), cleared to 0 by the
// host (before pass 0); the chosen surfel's key (depth_key(off_ray_m), map-wide index).
#ifdef KEY_64
@group(0) @binding(7) var<storage, read_write> assoc: array<atomic<u64>>;
#else
@group(0) @binding(7) var<storage, read_write> assoc: array<atomic<u32>>;
#endif
// One key per pixel, as assoc; project_model's key (depth_key(z_cam), map-wide index) of
// every surfel whose centre lands in the image, before this frame's merges: the next
// frame's prediction at this pose (fuse_add adds the new surfels), so predict skips
// project_model (see Backend::predict).
#ifdef KEY_64
@group(0) @binding(8) var<storage, read_write> index_map: array<atomic<u64>>;
#else
@group(0) @binding(8) var<storage, read_write> index_map: array<atomic<u32>>;
#endif

#entry visible_surfels

// The pixel surfel i (map-wide index; `slot` in the chunk's arrays) projects to keeps the
// nearer of its index-map key and this surfel's, and the better of its association key and
// this surfel's, if the surfel passes its gates. `params` is main's copy of the binding.
fn per_surfel(params: FuseParams, i: u32, slot: u32, cam: vec4<f32>) {
    let p_cam = transform_point(params.t_world_to_cam, xyz(position_weight[slot]));
    let uv = project_to_texel(cam, params.camera.width, params.camera.height, p_cam);
    if uv.x < 0 {
        return;
    }
    let texel = vec2<u32>(uv);
    let pix = texel.y * params.camera.width + texel.x;
    keep_nearer(pix, depth_key(p_cam.z), i);
    let nd = textureLoad(normal_depth, texel, 0);
    if !is_valid(nd) {
        return;
    }
    let n_cam = transform_dir(params.t_world_to_cam, bitcast<vec3<f32>>(normal_frame[slot].xyz));
    let off_ray = candidate_off_ray(cam, texel, nd, p_cam, n_cam, color[slot].w,
        fuse_depth_gate(params, position_weight[slot].w), params.cos_normal_threshold);
    if off_ray < 0.0 {
        return;
    }
    keep_best(pix, depth_key(off_ray), i);
}

// The pixel `pix` keeps the larger of its association key and (high, index): keep_nearer
// (shaders/key_writer.wgsl) on `assoc` instead of `index_map`, in the same variant.
#ifdef KEY_64
fn keep_best(pix: u32, high: u32, index: u32) {
    atomicMax(&assoc[pix], (u64(high) << 32u) | u64(index));
}
#else
fn keep_best(pix: u32, high: u32, index: u32) {
    if KEY_PASS == 0u {
        atomicMax(&assoc[2u * pix + 1u], high);
    } else if atomicLoad(&assoc[2u * pix + 1u]) == high {
        atomicMax(&assoc[2u * pix], index);
    }
}
#endif
