// compact_flags.wgsl: one keep flag per surfel, the removal rule for unstable surfels
// (Keller et al. 2013): a surfel seen fewer than `stable_weight` times whose last
// observation is more than `max_age_frames` frames old is dropped. First of the three
// stream-compaction kernels (then prefix_sum, compact_scatter). CPU twin:
// crates/core/src/cpu/compact_flags.rs. Dispatched once per map chunk.
//
// Bindings (@group(0)): each is described by the comment above its declaration.
// Grid-stride loop over surfels; each thread writes only its own flag.

// Uses surfel_count, frame_id, stable_weight and max_age_frames.
@group(0) @binding(0) var<storage, read> params: CompactParams;
// The chunk's first map-wide index and slots (see crates/gpu/src/map_buffers.rs).
@group(0) @binding(1) var<storage, read> chunk: MapChunk;
// The chunk's surfels, xyz world frame, w = weight.
@group(0) @binding(2) var<storage, read> position_weight: array<vec4<f32>>;
// Normal bits, w = last_frame.
@group(0) @binding(3) var<storage, read> normal_frame: array<vec4<u32>>;
// Out: 1 keep / 0 remove per map-wide index, surfel_count entries (this pass writes the
// chunk's).
@group(0) @binding(4) var<storage, read_write> flags: array<u32>;

const WORKGROUP_SIZE: u32 = 64u;

// True when the surfel stays: it is stable (weight >= stable_weight) or was seen within
// the last max_age_frames frames (last_frame never exceeds frame_id; the test is written
// so it cannot underflow).
// `params` is main's copy of the binding.
fn keep_surfel(params: CompactParams, weight: f32, last_frame: u32, frame_id: u32) -> bool {
    let unstable = weight < params.stable_weight;
    let old = last_frame < frame_id && frame_id - last_frame > params.max_age_frames;
    return !(unstable && old);
}

@compute @workgroup_size(WORKGROUP_SIZE)
fn main(
    @builtin(global_invocation_id) gid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
) {
    let stride = nwg.x * WORKGROUP_SIZE;
    // The params copied once per thread (see pixel_grid.wgsl).
    let p = params;
    let end = chunk_blocks(chunk, p.surfel_count).y;
    // The chunk's first index copied once per thread, as the params.
    let base = chunk.base;
    for (var i = base + gid.x; i < end; i += stride) {
        let surfel = i - base;
        let weight = position_weight[surfel].w;
        let last_frame = normal_frame[surfel].w;
        flags[i] = select(0u, 1u, keep_surfel(p, weight, last_frame, p.frame_id));
    }
}
