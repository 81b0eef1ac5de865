// fuse_merge_chosen.wgsl: the merge of best-candidate association (robust profile), driven
// by the pixels: every pixel whose fuse_select key chose a surfel of this chunk merges its
// measurement into that surfel (merged_surfel's averages, last_frame = frame_id). A surfel
// keys only the pixel its centre projects to, so each surfel has at most one writer. The
// same merges as walking the surfels and asking their pixel whether it chose them, at the
// cost of the image instead of the map. A merge that moves a surfel out of its block's box
// grows the box. Dispatched once per map chunk. CPU twin: crates/core/src/cpu/fuse_merge_chosen.rs.
//
// Bindings (@group(0)): each is described by the comment above its declaration.
// A 2-D grid-stride loop over the pixels in 8x8 tiles (see fuse_flags.wgsl).

// Tracked poses, intrinsics, confidence_sigma.
@group(0) @binding(0) var<storage, read> params: FuseParams;
// width x height, camera-frame normal with the vertex's depth in w, zero where invalid;
// the vertex is rebuilt with back_project.
@group(0) @binding(1) var normal_depth: texture_2d<f32>;
// width x height, RGB 0..255.
@group(0) @binding(2) var color_map: texture_2d<f32>;
// The chunk's first map-wide index and slots (see crates/gpu/src/map_buffers.rs).
@group(0) @binding(3) var<storage, read> chunk: MapChunk;
// Per block 8 words, min xyz, pad, max xyz, pad (ordered_from_f32), grown to hold every
// merged surfel.
@group(0) @binding(4) var<storage, read_write> block_boxes: array<atomic<u32>>;
// The chunk's surfels, xyz world frame (metres), w = confidence.
@group(0) @binding(5) var<storage, read_write> position_weight: array<vec4<f32>>;
// Bits of the unit normal (world frame), w = last frame.
@group(0) @binding(6) var<storage, read_write> normal_frame: array<vec4<u32>>;
// RGB 0..255, a = radius (metres).
@group(0) @binding(7) var<storage, read_write> color: array<vec4<f32>>;
// fuse_select's u64 key per pixel (low word, the chosen map-wide surfel index, first);
// (0, 0) = no choice.
@group(0) @binding(8) var<storage, read> assoc: array<vec2<u32>>;
// Out: two entries per pixel, cleared by the host: the surfel this pixel merged into,
// position_weight (w > 0) at 2 pix, then its unit normal (world frame) and radius (metres)
// at 2 pix + 1; zero where the pixel merged nothing. fuse_flags and fuse_prune read it,
// whatever the chunk.
@group(0) @binding(9) var<storage, read_write> merged: array<vec4<f32>>;

const TILE_X: u32 = 8u;
const TILE_Y: u32 = 8u;
#define MAP_CHUNK
#define CAMERA_PARAMS
#entry pixel_grid

// Merges pixel `texel`'s measurement into the surfel it chose, if that surfel is in this
// chunk. `params` and `chunk` are main's copies of the bindings (the entry point:
// pixel_grid.wgsl).
fn per_pixel(params: FuseParams, chunk: MapChunk, texel: vec2<u32>) {
    let pix = texel.y * params.camera.width + texel.x;
    let key = assoc[pix];
    if key.x == 0u && key.y == 0u {
        return;
    }
    // key.x - chunk.base wraps to a huge value below the chunk: one test for both ends.
    let slot = key.x - chunk.base;
    if slot >= chunk.slots {
        return;
    }
    let cam = camera_intrinsics(params.camera);
    let pw = position_weight[slot];
    // fuse_select chose only on a valid pixel (a valid normal implies a valid vertex).
    let nd = textureLoad(normal_depth, texel, 0);
    let q_cam = back_project(cam, texel, nd.w);
    let q_world = transform_point(params.t_cam_to_world, q_cam);
    let nq_world = transform_dir(params.t_cam_to_world, xyz(nd));
    let n_old = bitcast<vec3<f32>>(normal_frame[slot].xyz);
    let wq = pixel_confidence(cam, texel, params.confidence_sigma);
    let cq = textureLoad(color_map, texel, 0).xyz;
    let r_q = surfel_radius(params.camera.fx, q_cam, xyz(nd));
    let m = merged_surfel(pw, n_old, color[slot], q_world, nq_world, cq, wq, r_q);
    position_weight[slot] = m.position_weight;
    normal_frame[slot] = vec4<u32>(bitcast<vec3<u32>>(m.normal), params.frame_id);
    color[slot] = m.color;
    merged[2u * pix] = m.position_weight;
    merged[2u * pix + 1u] = vec4<f32>(m.normal, m.color.w);
    // Grow the block's box if the surfel moved out of it.
    let block = key.x / BLOCK_SURFELS;
    let p = m.position_weight.xyz;
    for (var k = 0u; k < 3u; k++) {
        let e = ordered_from_f32(p[k]);
        if e < atomicLoad(&block_boxes[8u * block + k]) {
            atomicMin(&block_boxes[8u * block + k], e);
        }
        if e > atomicLoad(&block_boxes[8u * block + 4u + k]) {
            atomicMax(&block_boxes[8u * block + 4u + k], e);
        }
    }
}
