// block_bounds.wgsl: recomputes the world-frame box of each block of one map chunk from
// block params.block_from on (the blocks fusion appended to, or all of them after a
// compaction or an upload), the boxes project_model, fuse_select and fuse_merge cull with.
// Dispatched once per chunk. CPU twin: src/cpu/block_bounds.rs.
//
// Bindings (@group(0)): each is described by the comment above its declaration.
// One thread per block (grid-stride over the chunk's blocks); each writes only its own box.

// Uses surfel_count and block_from.
@group(0) @binding(0) var<storage, read> params: BoundsParams;
// The chunk's first map-wide index and slots.
@group(0) @binding(1) var<storage, read> chunk: MapChunk;
// The chunk's surfels, xyz world frame (metres).
@group(0) @binding(2) var<storage, read> position_weight: array<vec4<f32>>;
// Out: per block, min (2b) and max (2b + 1) of its surfels' positions, ordered_from_f32
// encoded, w = 0.
@group(0) @binding(3) var<storage, read_write> block_bounds: array<vec4<u32>>;

const WORKGROUP_SIZE: u32 = 64u;

@compute @workgroup_size(WORKGROUP_SIZE)
fn main(
    @builtin(global_invocation_id) gid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
) {
    let span = chunk_blocks(chunk, params.surfel_count);
    let first = chunk.base / BLOCK_SURFELS;
    let start = max(params.block_from, first) - first;
    let stride = nwg.x * WORKGROUP_SIZE;
    for (var b = start + gid.x; b < span.x; b += stride) {
        let end = min(chunk.base + (b + 1u) * BLOCK_SURFELS, span.y);
        var lo = xyz(position_weight[b * BLOCK_SURFELS]);
        var hi = lo;
        for (var i = chunk.base + b * BLOCK_SURFELS + 1u; i < end; i++) {
            let p = xyz(position_weight[i - chunk.base]);
            lo = min(lo, p);
            hi = max(hi, p);
        }
        let block = first + b;
        block_bounds[2u * block] = vec4<u32>(ordered_from_f32(lo.x), ordered_from_f32(lo.y), ordered_from_f32(lo.z), 0u);
        block_bounds[2u * block + 1u] = vec4<u32>(ordered_from_f32(hi.x), ordered_from_f32(hi.y), ordered_from_f32(hi.z), 0u);
    }
}
