// block_bounds.wgsl: recomputes the world-frame box of each block of one map chunk from
// block params.block_from on (the blocks fusion appended to, or all of them after a
// compaction or an upload), the boxes project_model, fuse_select and fuse_merge cull with.
// Dispatched once per chunk. CPU twin: crates/core/src/cpu/block_bounds.rs.
//
// Bindings (@group(0)): each is described by the comment above its declaration.
// One workgroup per block (grid-stride over the chunk's stale blocks by workgroup): thread
// t takes the block's surfels t, t + WORKGROUP_SIZE, ..., and the workgroup halves the
// WORKGROUP_SIZE boxes in shared memory (min and max: exact in any order). No thread
// walks more than BLOCK_SURFELS / WORKGROUP_SIZE surfels; thread 0 writes the box.

// Uses surfel_count and block_from.
@group(0) @binding(0) var<storage, read> params: BoundsParams;
// The chunk's first map-wide index and slots.
@group(0) @binding(1) var<storage, read> chunk: MapChunk;
// The chunk's surfels, xyz world frame (metres).
@group(0) @binding(2) var<storage, read> position_weight: array<vec4<f32>>;
// Out: per block, min (2b) and max (2b + 1) of its surfels' positions, ordered_from_f32
// encoded, w = 0.
@group(0) @binding(3) var<storage, read_write> block_boxes: array<vec4<u32>>;

const WORKGROUP_SIZE: u32 = 64u;

var<workgroup> lo_box: array<vec3<f32>, WORKGROUP_SIZE>;
var<workgroup> hi_box: array<vec3<f32>, WORKGROUP_SIZE>;

@compute @workgroup_size(WORKGROUP_SIZE)
fn main(
    @builtin(local_invocation_index) t: u32,
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
) {
    let span = chunk_blocks(chunk, params.surfel_count);
    let first = chunk.base / BLOCK_SURFELS;
    let start = max(params.block_from, first) - first;
    // The same b in every thread of a workgroup: the barriers below stay uniform.
    for (var b = start + wid.x; b < span.x; b += nwg.x) {
        let begin = chunk.base + b * BLOCK_SURFELS;
        let end = min(begin + BLOCK_SURFELS, span.y);
        // A block's first surfel always exists: every thread starts from it.
        var lo = xyz(position_weight[b * BLOCK_SURFELS]);
        var hi = lo;
        for (var i = begin + t; i < end; i += WORKGROUP_SIZE) {
            let p = xyz(position_weight[i - chunk.base]);
            lo = min(lo, p);
            hi = max(hi, p);
        }
        lo_box[t] = lo;
        hi_box[t] = hi;
        workgroupBarrier();
        for (var s = WORKGROUP_SIZE / 2u; s > 0u; s /= 2u) {
            if t < s {
                lo_box[t] = min(lo_box[t], lo_box[t + s]);
                hi_box[t] = max(hi_box[t], hi_box[t + s]);
            }
            workgroupBarrier();
        }
        if t == 0u {
            let block = first + b;
            lo = lo_box[0];
            hi = hi_box[0];
            block_boxes[2u * block] = vec4<u32>(ordered_from_f32(lo.x), ordered_from_f32(lo.y), ordered_from_f32(lo.z), 0u);
            block_boxes[2u * block + 1u] = vec4<u32>(ordered_from_f32(hi.x), ordered_from_f32(hi.y), ordered_from_f32(hi.z), 0u);
        }
        // The next block's boxes overwrite these only after thread 0 has read them.
        workgroupBarrier();
    }
}
