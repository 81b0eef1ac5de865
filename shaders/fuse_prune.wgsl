// fuse_prune.wgsl: duplicate removal of best-candidate fusion (robust profile), after
// fuse_merge_chosen. A surfel this frame did not refresh retires (weight 0, last frame 0,
// which the unstable-surfel removal drops at its next run after frame max_age_frames) when
// the pixel it projects to chose another surfel that this frame refreshed, lies within
// prune_radius_scale times the larger of their radii, faces the same way (PRUNE_COS_NORMAL)
// and is at least as confident: a layered copy of the surface the chosen surfel now stands
// for (Keller et al. 2013 merge such surfels). Without it, noisy depth leaves copies that
// different pixels keep refreshing, and the camera sees a denser map on every revisit.
// Dispatched once per map chunk; a chosen surfel in another chunk is left alone. CPU twin:
// src/cpu/fuse_prune.rs.
//
// Bindings (@group(0)):
//   0 params      storage read FuseParams (tracked pose, intrinsics, surfel_count,
//                 frame_id, prune_radius_scale)
//   1 chunk       storage read MapChunk: the chunk's first map-wide index and slots
//   2 block_bounds  storage read array<vec4<u32>>: per block, min (2b) and max (2b + 1)
//                   corner of its surfels' world-frame box, ordered_from_f32 encoded
//   3 position_weight  storage rw array<vec4<f32>>: xyz world frame (metres), w = confidence
//   4 normal_frame     storage rw array<vec4<u32>>: bits of the unit normal (world frame),
//                      w = last frame
//   5 color            storage read array<vec4<f32>>: RGB 0..255, a = radius (metres)
//   6 assoc       storage read array<vec2<u32>>: fuse_select's u64 key per pixel (low
//                 word, the chosen map-wide surfel index, first); (0, 0) = no choice
//   (see src/gpu/map_buffers.rs)
// Workgroups stride over the chunk's blocks, skipping those block_visible rejects; threads
// stride over a block. A thread writes only a surfel that was not refreshed and reads only
// ones that were, so no two threads touch the same surfel.

@group(0) @binding(0) var<storage, read> params: FuseParams;
@group(0) @binding(1) var<storage, read> chunk: MapChunk;
@group(0) @binding(2) var<storage, read> block_bounds: array<vec4<u32>>;
@group(0) @binding(3) var<storage, read_write> position_weight: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read_write> normal_frame: array<vec4<u32>>;
@group(0) @binding(5) var<storage, read> color: array<vec4<f32>>;
@group(0) @binding(6) var<storage, read> assoc: array<vec2<u32>>;

const WORKGROUP_SIZE: u32 = 64u;
// Cosine of the largest angle between the normals of a pruned surfel and the chosen one:
// 45 degrees (mirrors `cpu::fuse_prune::PRUNE_COS_NORMAL`).
const PRUNE_COS_NORMAL: f32 = 0.70710678;

@compute @workgroup_size(WORKGROUP_SIZE)
fn main(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(local_invocation_id) lid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
) {
    let cam = vec4<f32>(params.fx, params.fy, params.cx, params.cy);
    let span = chunk_blocks(chunk, params.surfel_count);
    for (var b = wid.x; b < span.x; b += nwg.x) {
        let block = chunk.base / BLOCK_SURFELS + b;
        let lo = decode_corner(block_bounds[2u * block]);
        let hi = decode_corner(block_bounds[2u * block + 1u]);
        if !block_visible(params.t_world_to_cam, cam, params.width, params.height, lo, hi) {
            continue;
        }
        let end = min(chunk.base + (b + 1u) * BLOCK_SURFELS, span.y);
        for (var i = chunk.base + b * BLOCK_SURFELS + lid.x; i < end; i += WORKGROUP_SIZE) {
            prune_surfel(i, i - chunk.base, cam);
        }
    }
}

// Retires surfel i (map-wide index; `slot` in the chunk's arrays) if it duplicates the
// surfel its pixel chose.
fn prune_surfel(i: u32, slot: u32, cam: vec4<f32>) {
    let nf = normal_frame[slot];
    if nf.w == params.frame_id {
        return;
    }
    let pw = position_weight[slot];
    let centre = project_to_texel(cam, params.width, params.height,
        transform_point(params.t_world_to_cam, xyz(pw)));
    if centre.x < 0 {
        return;
    }
    let key = assoc[u32(centre.y) * params.width + u32(centre.x)];
    // key.x - chunk.base wraps to a huge value below the chunk: one test for both ends.
    let t = key.x - chunk.base;
    if key.y == 0u || key.x == i || t >= chunk.slots {
        return;
    }
    let nf_t = normal_frame[t];
    if nf_t.w != params.frame_id {
        return;
    }
    let pw_t = position_weight[t];
    let reach = params.prune_radius_scale * max(color[slot].w, color[t].w);
    if distance(xyz(pw), xyz(pw_t)) < reach
        && dot(bitcast<vec3<f32>>(nf.xyz), bitcast<vec3<f32>>(nf_t.xyz)) > PRUNE_COS_NORMAL
        && pw.w <= pw_t.w {
        position_weight[slot] = vec4<f32>(xyz(pw), 0.0);
        normal_frame[slot] = vec4<u32>(nf.xyz, 0u);
    }
}
