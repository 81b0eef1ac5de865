// fuse_add.wgsl: appends every valid pixel no surfel merged with as a new surfel (world
// frame, weight 1) through an atomic counter. CPU twin: src/cpu/fuse_add.rs.
//
// Bindings (@group(0)):
//   0 params      uniform FuseParams (t_cam_to_world, frame_id, capacity)
//   1 vertex_map  texture_2d<f32>: width x height, camera frame
//   2 normal_map  texture_2d<f32>: width x height, camera frame
//   3 color_map   texture_2d<f32>: width x height, RGB 0..255
//   4 assoc       storage read   array<u32>: 1 where fuse_merge merged the pixel
//   5 counter     storage rw     atomic<u32>: surfels in the map (in: before, out: after)
//   6 positions   storage rw     array<vec4<f32>>: surfels, world frame (capacity entries)
//   7 normals     storage rw     array<vec4<f32>>
//   8 colors      storage rw     array<vec4<f32>>
//   9 weights     storage rw     array<f32>
//  10 last_frame  storage rw     array<u32>
// Grid-stride loop over pixels; the append order is the atomics' order, not pixel order. Never
// writes at or past params.capacity: the counter still counts, and the host turns a count
// above capacity into a capacity error.

@group(0) @binding(0) var<uniform> params: FuseParams;
@group(0) @binding(1) var vertex_map: texture_2d<f32>;
@group(0) @binding(2) var normal_map: texture_2d<f32>;
@group(0) @binding(3) var color_map: texture_2d<f32>;
@group(0) @binding(4) var<storage, read> assoc: array<u32>;
@group(0) @binding(5) var<storage, read_write> counter: atomic<u32>;
@group(0) @binding(6) var<storage, read_write> positions: array<vec4<f32>>;
@group(0) @binding(7) var<storage, read_write> normals: array<vec4<f32>>;
@group(0) @binding(8) var<storage, read_write> colors: array<vec4<f32>>;
@group(0) @binding(9) var<storage, read_write> weights: array<f32>;
@group(0) @binding(10) var<storage, read_write> last_frame: array<u32>;

const WORKGROUP_SIZE: u32 = 64u;

@compute @workgroup_size(WORKGROUP_SIZE)
fn main(
    @builtin(global_invocation_id) gid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
) {
    let stride = nwg.x * WORKGROUP_SIZE;
    for (var pix = gid.x; pix < params.width * params.height; pix += stride) {
        if assoc[pix] != 0u {
            continue;
        }
        let texel = texel_of(pix, params.width);
        let q4 = textureLoad(vertex_map, texel, 0);
        let nq4 = textureLoad(normal_map, texel, 0);
        if !is_valid(q4) || !is_valid(nq4) {
            continue;
        }
        let i = atomicAdd(&counter, 1u);
        if i >= params.capacity {
            continue;
        }
        let p = transform_point(params.t_cam_to_world, xyz(q4));
        let n = transform_dir(params.t_cam_to_world, xyz(nq4));
        positions[i] = vec4<f32>(p, 1.0);
        normals[i] = vec4<f32>(n, 0.0);
        colors[i] = textureLoad(color_map, texel, 0);
        weights[i] = 1.0;
        last_frame[i] = params.frame_id;
    }
}
