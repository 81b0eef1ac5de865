// compact_scatter.wgsl: copies every kept surfel i to slot offsets[i] of a second set of
// map textures, so the survivors end up at the front in their current order (stream
// compaction); the host then swaps the two sets. Last of the three stream-compaction
// kernels. CPU twin: src/cpu/compact_scatter.rs.
//
// Bindings (@group(0)):
//   0 params               storage read CompactParams (surfel_count)
//   1 flags                storage read array<u32>: 1 keep / 0 remove (compact_flags)
//   2 offsets              storage read array<u32>: exclusive prefix sum of flags
//                          (prefix_sum)
//   3 position_weight      texture_2d<f32> (rgba32float): xyz world frame, w = weight
//   4 normal_frame         texture_2d<u32> (rgba32uint): normal bits, w = last_frame
//   5 color                texture_2d<f32> (rgba32float): RGB 0..255, a = 255
//   6 out_position_weight  storage texture rgba32float, write
//   7 out_normal_frame     storage texture rgba32uint, write
//   8 out_color            storage texture rgba32float, write
//   (surfel i is texel surfel_texel(i) of each; see src/gpu/map_textures.rs; the output
//   textures have the input's capacity, and offsets[i] <= i, so no write goes past it)
// Grid-stride loop over surfels; each kept surfel has its own output slot.

@group(0) @binding(0) var<storage, read> params: CompactParams;
@group(0) @binding(1) var<storage, read> flags: array<u32>;
@group(0) @binding(2) var<storage, read> offsets: array<u32>;
@group(0) @binding(3) var position_weight: texture_2d<f32>;
@group(0) @binding(4) var normal_frame: texture_2d<u32>;
@group(0) @binding(5) var color: texture_2d<f32>;
@group(0) @binding(6) var out_position_weight: texture_storage_2d<rgba32float, write>;
@group(0) @binding(7) var out_normal_frame: texture_storage_2d<rgba32uint, write>;
@group(0) @binding(8) var out_color: texture_storage_2d<rgba32float, write>;

const WORKGROUP_SIZE: u32 = 64u;

@compute @workgroup_size(WORKGROUP_SIZE)
fn main(
    @builtin(global_invocation_id) gid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
) {
    let stride = nwg.x * WORKGROUP_SIZE;
    for (var i = gid.x; i < params.surfel_count; i += stride) {
        if flags[i] == 0u {
            continue;
        }
        let src = surfel_texel(i);
        let dst = surfel_texel(offsets[i]);
        textureStore(out_position_weight, dst, textureLoad(position_weight, src, 0));
        textureStore(out_normal_frame, dst, textureLoad(normal_frame, src, 0));
        textureStore(out_color, dst, textureLoad(color, src, 0));
    }
}
