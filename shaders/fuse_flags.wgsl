// fuse_flags.wgsl: one flag per pixel, 1 where the pixel becomes a new surfel: a valid
// measurement that no surfel merged with (projective association) or covers (best
// candidate), at the pixel's append_index. First of fuse_add's three kernels (then
// prefix_sum over the flags, which gives each new surfel its slot in append order, see
// `layout::APPEND_TILE_PX`, then fuse_add). CPU twin: src/cpu/fuse_flags.rs.
//
// Bindings (@group(0)):
//   0 params        storage read FuseParams (width, height)
//   1 normal_depth  texture_2d<f32>: width x height, camera-frame normal with the depth in
//                   w, zero where invalid
//   2 assoc         storage read array<vec2<u32>>: the u64 key per pixel (low word first),
//                   non-zero where a surfel merged with or was chosen by the pixel
//   3 flags         storage rw array<u32>: out, 1 new surfel / 0 not, at append_index of
//                   the pixel (layout::append_slots(width, height) entries; the holes, no
//                   pixel's, are never written and stay 0)
// A 2-D grid-stride loop over the pixels in 8x8 tiles (see vertex_to_normal.wgsl).

@group(0) @binding(0) var<storage, read> params: FuseParams;
@group(0) @binding(1) var normal_depth: texture_2d<f32>;
@group(0) @binding(2) var<storage, read> assoc: array<vec2<u32>>;
@group(0) @binding(3) var<storage, read_write> flags: array<u32>;

const TILE: u32 = 8u;

// A 2-D grid-stride loop in 8x8 tiles, like vertex_to_normal (the size read once per
// thread).
@compute @workgroup_size(TILE, TILE)
fn main(
    @builtin(global_invocation_id) gid: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    let stride = TILE * groups.xy;
    let size = vec2<u32>(params.width, params.height);
    for (var v = gid.y; v < size.y; v += stride.y) {
        for (var u = gid.x; u < size.x; u += stride.x) {
            let pix = v * size.x + u;
            let key = assoc[pix];
            // Valid normal (w = depth > 0) implies a valid vertex: the twin's two tests.
            let new_surfel = key.x == 0u && key.y == 0u
                && is_valid(textureLoad(normal_depth, vec2<u32>(u, v), 0));
            flags[append_index(vec2<u32>(u, v))] = select(0u, 1u, new_surfel);
        }
    }
}
