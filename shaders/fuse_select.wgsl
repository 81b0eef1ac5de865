// fuse_select.wgsl: every pixel picks the one surfel it will fuse with (best-candidate
// association, robust profile), before fuse_merge and fuse_add. CPU twin:
// src/cpu/fuse_select.rs (its header states the gates and the choice).
//
// Bindings (@group(0)):
//   0 params      storage read FuseParams (tracked pose, intrinsics, surfel_count, gates)
//   1 normal_depth  texture_2d<f32>: width x height, camera-frame normal with the depth in
//                   w, zero where invalid; the vertex is rebuilt with back_project
//   2 position_weight  texture_2d<f32>: xyz world frame (metres), w = confidence
//   3 normal_frame     texture_2d<u32>: bits of the unit normal (world frame), w = last frame
//   4 color            texture_2d<f32>: RGB 0..255, a = radius (metres)
//   5 assoc       storage rw array<atomic<u64>>: one key per pixel, cleared to 0 by the
//                 host; the chosen surfel's pack_depth_index(off_ray_m, index)
//   (surfel i is texel surfel_texel(i) of each map texture; see src/gpu/map_textures.rs)
// Grid-stride loop over surfels; the atomicMax keeps the surfel nearest each pixel's ray
// (ties to the larger index) whatever the thread order. Needs SHADER_INT64_ATOMIC_MIN_MAX.

@group(0) @binding(0) var<storage, read> params: FuseParams;
@group(0) @binding(1) var normal_depth: texture_2d<f32>;
@group(0) @binding(2) var position_weight: texture_2d<f32>;
@group(0) @binding(3) var normal_frame: texture_2d<u32>;
@group(0) @binding(4) var color: texture_2d<f32>;
@group(0) @binding(5) var<storage, read_write> assoc: array<atomic<u64>>;

const WORKGROUP_SIZE: u32 = 64u;
// Largest half-width of the window a disc covers (mirrors `MAX_SELECT_RADIUS_PX`).
const MAX_SELECT_RADIUS_PX: i32 = 1;

@compute @workgroup_size(WORKGROUP_SIZE)
fn main(
    @builtin(global_invocation_id) gid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
) {
    let cam = vec4<f32>(params.fx, params.fy, params.cx, params.cy);
    let stride = nwg.x * WORKGROUP_SIZE;
    for (var i = gid.x; i < params.surfel_count; i += stride) {
        let surfel = surfel_texel(i);
        let p_cam = transform_point(params.t_world_to_cam, xyz(textureLoad(position_weight, surfel, 0)));
        let centre = project_to_texel(cam, params.width, params.height, p_cam);
        if centre.x < 0 {
            continue;
        }
        let n_world = bitcast<vec3<f32>>(textureLoad(normal_frame, surfel, 0).xyz);
        let n_cam = transform_dir(params.t_world_to_cam, n_world);
        let radius = textureLoad(color, surfel, 0).w;
        let reach = min(i32(radius * params.fx / p_cam.z), MAX_SELECT_RADIUS_PX);
        for (var dv = -reach; dv <= reach; dv++) {
            for (var du = -reach; du <= reach; du++) {
                let u = centre.x + du;
                let v = centre.y + dv;
                if u < 0 || v < 0 || u >= i32(params.width) || v >= i32(params.height) {
                    continue;
                }
                let texel = vec2<u32>(u32(u), u32(v));
                let pix = texel.y * params.width + texel.x;
                let nd = textureLoad(normal_depth, texel, 0);
                if !is_valid(nd) {
                    continue;
                }
                let q = back_project(cam, texel, nd.w);
                let ray = q / length(q);
                let d = p_cam - q;
                let along = dot(d, ray);
                let off_ray = length(d - ray * along);
                if abs(along) >= params.dist_threshold_m
                    || off_ray >= radius
                    || dot(n_cam, xyz(nd)) <= params.cos_normal_threshold {
                    continue;
                }
                atomicMax(&assoc[pix], pack_depth_index(off_ray, i));
            }
        }
    }
}
