// fuse_merge.wgsl: merges the new frame into the surfels it sees with projective
// association (the assignment): every surfel that lands on a pixel whose measurement passes
// the gates takes merged_surfel's averages (last_frame = frame_id), and the pixel is
// flagged. Best-candidate association merges from the pixels instead (fuse_merge_chosen).
// Dispatched once per map chunk; a merge that moves a surfel out of its block's box grows
// the box. CPU twin: crates/core/src/cpu/fuse_merge.rs (its header states both filter passes).
//
// Bindings (@group(0)): each is described by the comment above its declaration.
// Workgroups stride over the chunk's blocks, skipping those block_visible rejects (their
// surfels cannot project into the image); threads stride over a block. Each thread writes
// only its own surfels, so the result does not depend on thread order (several surfels may
// flag the same pixel); boxes only grow, by min/max, which no order changes.

// Tracked poses, intrinsics, surfel_count, gates, confidence_sigma.
@group(0) @binding(0) var<storage, read> params: FuseParams;
// width x height, camera-frame normal with the vertex's depth in w, zero where invalid
// (see vertex_to_normal.wgsl); the vertex is rebuilt with back_project, as in the twin.
@group(0) @binding(1) var normal_depth: texture_2d<f32>;
// width x height, RGB 0..255.
@group(0) @binding(2) var color_map: texture_2d<f32>;
// The chunk's first map-wide index and slots (see crates/gpu/src/map_buffers.rs).
@group(0) @binding(3) var<storage, read> chunk: MapChunk;
// Per block 8 words, min xyz, pad, max xyz, pad (ordered_from_f32; the vec4<u32> pairs
// other kernels read); grown with atomicMin/atomicMax to hold every merged surfel.
@group(0) @binding(4) var<storage, read_write> block_boxes: array<atomic<u32>>;
// The chunk's surfels, xyz world frame (metres), w = confidence.
@group(0) @binding(5) var<storage, read_write> position_weight: array<vec4<f32>>;
// Bits of the unit normal (world frame), w = frame that last touched the surfel.
@group(0) @binding(6) var<storage, read_write> normal_frame: array<vec4<u32>>;
// RGB 0..255, a = radius (metres).
@group(0) @binding(7) var<storage, read_write> color: array<vec4<f32>>;
// One 64-bit key per pixel as (low, high) u32 words, cleared to 0 by the host; the low
// word is maxed with 1 where merged, so the key reads 1 (as a u64, the word order of
// fuse_select's keys) and no 64-bit integers are needed.
@group(0) @binding(8) var<storage, read_write> assoc: array<atomic<u32>>;

const WORKGROUP_SIZE: u32 = 64u;

// Word k of block b's box (0..2 min xyz, 4..6 max xyz) as a float.
fn box_word(block: u32, k: u32) -> f32 {
    return f32_from_ordered(atomicLoad(&block_boxes[8u * block + k]));
}

@compute @workgroup_size(WORKGROUP_SIZE)
fn main(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(local_invocation_id) lid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
) {
    // The params copied once per thread (see pixel_grid.wgsl).
    let p = params;
    let cam = camera_intrinsics(p.camera);
    let span = chunk_blocks(chunk, p.surfel_count);
    // The chunk's first index copied once per thread, as the params.
    let base = chunk.base;
    for (var b = wid.x; b < span.x; b += nwg.x) {
        let block = base / BLOCK_SURFELS + b;
        let lo = vec3<f32>(box_word(block, 0u), box_word(block, 1u), box_word(block, 2u));
        let hi = vec3<f32>(box_word(block, 4u), box_word(block, 5u), box_word(block, 6u));
        if !block_visible(p.t_world_to_cam, cam, p.camera.width, p.camera.height, lo, hi) {
            continue;
        }
        // The box grown by this thread's merged surfels.
        var grown_lo = lo;
        var grown_hi = hi;
        let end = min(base + (b + 1u) * BLOCK_SURFELS, span.y);
        for (var i = base + b * BLOCK_SURFELS + lid.x; i < end; i += WORKGROUP_SIZE) {
            let moved = merge_surfel(p, i - base, cam);
            if moved.w > 0.0 {
                grown_lo = min(grown_lo, moved.xyz);
                grown_hi = max(grown_hi, moved.xyz);
            }
        }
        for (var k = 0u; k < 3u; k++) {
            if grown_lo[k] < lo[k] {
                atomicMin(&block_boxes[8u * block + k], ordered_from_f32(grown_lo[k]));
            }
            if grown_hi[k] > hi[k] {
                atomicMax(&block_boxes[8u * block + 4u + k], ordered_from_f32(grown_hi[k]));
            }
        }
    }
}

// Merges surfel `slot` of the chunk with its pixel when the filters pass: returns its new world-frame position with w = 1, or w = 0 if unmerged.
// `params` is main's copy of the binding.
fn merge_surfel(params: FuseParams, slot: u32, cam: vec4<f32>) -> vec4<f32> {
    let pw = position_weight[slot];
    let p_world = xyz(pw);
    let p_cam = transform_point(params.t_world_to_cam, p_world);
    let uv = project_to_texel(cam, params.camera.width, params.camera.height, p_cam);
    if uv.x < 0 {
        return INVALID;
    }
    let texel = vec2<u32>(uv);
    let pix = texel.y * params.camera.width + texel.x;
    // Valid normal (w = depth > 0) implies a valid vertex: the twin's two tests.
    let nd = textureLoad(normal_depth, texel, 0);
    if !is_valid(nd) {
        return INVALID;
    }
    let q_cam = back_project(cam, texel, nd.w);
    let q_world = transform_point(params.t_cam_to_world, q_cam);
    let nq_world = transform_dir(params.t_cam_to_world, xyz(nd));
    let n_old = bitcast<vec3<f32>>(normal_frame[slot].xyz);
    if length(q_world - p_world) >= params.dist_m
        || dot(n_old, nq_world) <= params.cos_normal_threshold {
        return INVALID;
    }
    let wq = pixel_confidence(cam, texel, params.confidence_sigma);
    let cq = textureLoad(color_map, texel, 0).xyz;
    let r_q = surfel_radius(params.camera.fx, q_cam, xyz(nd));
    let m = merged_surfel(pw, n_old, color[slot], q_world, nq_world, cq, wq, r_q);
    position_weight[slot] = m.position_weight;
    normal_frame[slot] = vec4<u32>(bitcast<vec3<u32>>(m.normal), params.frame_id);
    color[slot] = m.color;
    atomicMax(&assoc[2u * pix], 1u);
    return vec4<f32>(m.position_weight.xyz, 1.0);
}
