// project_model.wgsl: splats every surfel into an index map with a depth test, one packed
// 64-bit key per pixel. CPU twin: src/cpu/project_model.rs.
//
// Bindings (@group(0)):
//   0 params     storage read ProjectParams (t_world_to_cam, intrinsics, map size, surfel_count)
//   1 position_weight  texture_2d<f32>: surfel xyz (world frame, metres) + weight,
//                      surfel i at surfel_texel(i) (see src/gpu/map_textures.rs)
//   2 index_map  storage rw     array<atomic<u64>>: width x height, cleared to 0 by the host
// Key = (u64(~bitcast<u32>(z_cam)) << 32) | surfel index; the pixel keeps the maximum
// (nearest surfel, ties to the larger index); 0 means no surfel. Needs the
// SHADER_INT64_ATOMIC_MIN_MAX feature. Grid-stride loop over surfels: the host dispatches
// at most max_compute_workgroups_per_dimension workgroups.

@group(0) @binding(0) var<storage, read> params: ProjectParams;
@group(0) @binding(1) var position_weight: texture_2d<f32>;
@group(0) @binding(2) var<storage, read_write> index_map: array<atomic<u64>>;

const WORKGROUP_SIZE: u32 = 64u;

@compute @workgroup_size(WORKGROUP_SIZE)
fn main(
    @builtin(global_invocation_id) gid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
) {
    let cam = vec4<f32>(params.fx, params.fy, params.cx, params.cy);
    let stride = nwg.x * WORKGROUP_SIZE;
    for (var i = gid.x; i < params.surfel_count; i += stride) {
        let p = transform_point(params.t_world_to_cam, xyz(textureLoad(position_weight, surfel_texel(i), 0)));
        let pix = project_to_pixel(cam, params.width, params.height, p);
        if pix >= 0 {
            atomicMax(&index_map[pix], pack_depth_index(p.z, i));
        }
    }
}
