// compact_scatter.wgsl: copies one surfel array of every kept surfel i to slot offsets[i] of
// a second map (chunk set), so the survivors end up at the front in their current order
// (stream compaction); the host then swaps the two sets. Last of the three
// stream-compaction kernels. Dispatched once per pair of input chunk and output chunk
// (output chunks no later than the input's, as offsets[i] <= i) and per surfel array
// (position_weight, normal_frame, color: one at a time keeps the kernel within WebGPU's 8
// storage buffers per stage): each pass copies the input chunk's kept surfels whose new
// slot the output chunk holds. CPU twin: crates/core/src/cpu/compact_scatter.rs.
//
// Bindings (@group(0)): each is described by the comment above its declaration.
// Grid-stride loop over the input chunk's surfels; each kept surfel has its own output slot.

// Uses surfel_count.
@group(0) @binding(0) var<storage, read> params: CompactParams;
// 1 keep / 0 remove (compact_flags).
@group(0) @binding(1) var<storage, read> flags: array<u32>;
// Exclusive prefix sum of flags (prefix_sum).
@group(0) @binding(2) var<storage, read> offsets: array<u32>;
// The input chunk (first map-wide index, slots); see crates/gpu/src/map_buffers.rs.
@group(0) @binding(3) var<storage, read> chunk: MapChunk;
// One of the input chunk's surfel arrays (position_weight, normal_frame or color, see
// crates/gpu/src/map_buffers.rs), its 16-byte entries copied as bits.
@group(0) @binding(4) var<storage, read> surfel_array: array<vec4<u32>>;
// The output chunk: a chunk of the second map, which has the input's chunks.
@group(0) @binding(5) var<storage, read> out_chunk: MapChunk;
// Out: the same array of the output chunk (its slots entries); only the kept surfels
// whose new slot this chunk holds are written.
@group(0) @binding(6) var<storage, read_write> out_surfel_array: array<vec4<u32>>;

const WORKGROUP_SIZE: u32 = 64u;

@compute @workgroup_size(WORKGROUP_SIZE)
fn main(
    @builtin(global_invocation_id) gid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
) {
    let stride = nwg.x * WORKGROUP_SIZE;
    let end = chunk_blocks(chunk, params.surfel_count).y;
    // The chunk's first index copied once per thread, as the params.
    let base = chunk.base;
    for (var i = base + gid.x; i < end; i += stride) {
        // offsets[i] - out_chunk.base wraps to a huge value below the output chunk.
        let dst = offsets[i] - out_chunk.base;
        if flags[i] == 0u || dst >= out_chunk.slots {
            continue;
        }
        let src = i - base;
        out_surfel_array[dst] = surfel_array[src];
    }
}
