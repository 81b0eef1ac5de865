// fuse_prune.wgsl: duplicate removal of best-candidate fusion (robust profile), after
// fuse_merge_chosen. A surfel this frame did not refresh retires (weight 0, last frame 0,
// which the unstable-surfel removal drops at its first run after frame max_age_frames)
// when the pixel it projects to merged its measurement into a surfel (fuse_merge_chosen's
// `merged` entry) that lies within prune_scale times the larger of their radii,
// faces the same way (PRUNE_COS_NORMAL) and is at least as confident: a layered copy of
// the surface the merged surfel now stands for (Keller et al. 2013 merge such surfels).
// Without it, noisy depth leaves copies that different pixels keep refreshing, and the
// camera sees a denser map on every revisit. Dispatched once per map chunk; the merged
// surfel may be in any chunk, as its copy is per pixel. CPU twin: crates/core/src/cpu/fuse_prune.rs.
//
// Bindings (@group(0)): each is described by the comment above its declaration.
// Workgroups stride over the chunk's blocks, skipping those block_visible rejects; threads
// stride over a block. A thread writes only its own surfel, and only one this frame did not
// refresh; the merged surfels it compares with are per-pixel copies.

// Tracked pose, intrinsics, surfel_count, frame_id, prune_scale.
@group(0) @binding(0) var<storage, read> params: FuseParams;
// The chunk's first map-wide index and slots (see crates/gpu/src/map_buffers.rs).
@group(0) @binding(1) var<storage, read> chunk: MapChunk;
// Per block, min (2b) and max (2b + 1) corner of its surfels' world-frame box,
// ordered_from_f32 encoded.
@group(0) @binding(2) var<storage, read> block_boxes: array<vec4<u32>>;
// The chunk's surfels, xyz world frame (metres), w = confidence.
@group(0) @binding(3) var<storage, read_write> position_weight: array<vec4<f32>>;
// Bits of the unit normal (world frame), w = last frame.
@group(0) @binding(4) var<storage, read_write> normal_frame: array<vec4<u32>>;
// RGB 0..255, a = radius (metres).
@group(0) @binding(5) var<storage, read> color: array<vec4<f32>>;
// Per pixel, the surfel it merged into (fuse_merge_chosen): position_weight at 2 pix
// (w = 0: none), unit normal (world frame) and radius (metres) at 2 pix + 1.
@group(0) @binding(6) var<storage, read> merged: array<vec4<f32>>;

// Cosine of the largest angle between the normals of a pruned surfel and the chosen one:
// 45 degrees (mirrors `cpu::fuse_prune::PRUNE_COS_NORMAL`).
const PRUNE_COS_NORMAL: f32 = 0.70710678;

#entry visible_surfels

// Retires the surfel at `slot` in the chunk's arrays if it duplicates the surfel its
// pixel merged into. `params` is main's copy of the binding; `i`, the map-wide index, is
// not needed.
fn per_surfel(params: FuseParams, i: u32, slot: u32, cam: vec4<f32>) {
    let nf = normal_frame[slot];
    if nf.w == params.frame_id {
        return;
    }
    let pw = position_weight[slot];
    let centre = project_to_texel(cam, params.camera.width, params.camera.height,
        transform_point(params.t_world_to_cam, xyz(pw)));
    if centre.x < 0 {
        return;
    }
    let pix = u32(centre.y) * params.camera.width + u32(centre.x);
    let pw_t = merged[2u * pix];
    if pw_t.w <= 0.0 {
        return;
    }
    let nr_t = merged[2u * pix + 1u];
    let reach = params.prune_scale * max(color[slot].w, nr_t.w);
    if distance(xyz(pw), xyz(pw_t)) < reach
        && dot(bitcast<vec3<f32>>(nf.xyz), xyz(nr_t)) > PRUNE_COS_NORMAL
        && pw.w <= pw_t.w {
        position_weight[slot] = vec4<f32>(xyz(pw), 0.0);
        normal_frame[slot] = vec4<u32>(nf.xyz, 0u);
    }
}
