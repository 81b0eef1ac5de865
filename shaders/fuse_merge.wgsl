// fuse_merge.wgsl: merges the new frame into the surfels it sees (confidence-weighted
// averages of position, normal, colour and radius; weight + confidence; last_frame =
// frame_id). With projective association (the assignment) the gates are tested here and
// merged pixels are flagged; with best-candidate association a surfel merges only with the
// pixel whose fuse_select chose it. CPU twin: src/cpu/fuse_merge.rs (its header states both
// filter passes).
//
// Bindings (@group(0)):
//   0 params      storage read FuseParams (tracked poses, intrinsics, surfel_count, gates,
//                 association, confidence_sigma)
//   1 normal_depth  texture_2d<f32>: width x height, camera-frame normal with the vertex's
//                   depth in w, zero where invalid (see vertex_to_normal.wgsl); the vertex
//                   is rebuilt with back_project, as in the twin
//   2 color_map   texture_2d<f32>: width x height, RGB 0..255
//   3 position_weight  storage texture rgba32float, read_write: xyz world frame (metres),
//                      w = confidence
//   4 normal_frame     storage texture rgba32uint, read_write: bits of the unit normal
//                      (world frame), w = frame that last touched the surfel
//   5 color            storage texture rgba32float, read_write: RGB 0..255, a = radius (m)
//   6 assoc            storage rw array<atomic<u64>>: one key per pixel, cleared by the
//                      host; projective: max with 1 where merged; best candidate:
//                      fuse_select's choice (surfel index in the low 32 bits)
//   (surfel i is texel surfel_texel(i) of each map texture; see src/gpu/map_textures.rs)
// Grid-stride loop over surfels; each thread writes only its own surfel, so the result
// does not depend on thread order (several surfels may flag the same pixel).

@group(0) @binding(0) var<storage, read> params: FuseParams;
@group(0) @binding(1) var normal_depth: texture_2d<f32>;
@group(0) @binding(2) var color_map: texture_2d<f32>;
@group(0) @binding(3) var position_weight: texture_storage_2d<rgba32float, read_write>;
@group(0) @binding(4) var normal_frame: texture_storage_2d<rgba32uint, read_write>;
@group(0) @binding(5) var color: texture_storage_2d<rgba32float, read_write>;
@group(0) @binding(6) var<storage, read_write> assoc: array<atomic<u64>>;

const WORKGROUP_SIZE: u32 = 64u;

// v / |v|, or zero when |v| is zero (glam's `normalize_or_zero` in the twin).
fn normalize_or_zero(v: vec3<f32>) -> vec3<f32> {
    let len = length(v);
    if len > 0.0 {
        return v * (1.0 / len);
    }
    return vec3<f32>(0.0);
}

@compute @workgroup_size(WORKGROUP_SIZE)
fn main(
    @builtin(global_invocation_id) gid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
) {
    let cam = vec4<f32>(params.fx, params.fy, params.cx, params.cy);
    let stride = nwg.x * WORKGROUP_SIZE;
    for (var i = gid.x; i < params.surfel_count; i += stride) {
        let surfel = surfel_texel(i);
        let pw = textureLoad(position_weight, surfel);
        let p_world = xyz(pw);
        let p_cam = transform_point(params.t_world_to_cam, p_world);
        let uv = project_to_texel(cam, params.width, params.height, p_cam);
        if uv.x < 0 {
            continue;
        }
        let texel = vec2<u32>(uv);
        let pix = texel.y * params.width + texel.x;
        // Best candidate: only the pixel that chose this surfel (fuse_select tested the
        // gates, on a valid pixel), before any other load.
        if params.association == ASSOCIATION_BEST_CANDIDATE {
            let key = atomicLoad(&assoc[pix]);
            if key == 0lu || u32(key) != i {
                continue;
            }
        }
        // Valid normal (w = depth > 0) implies a valid vertex: the twin's two tests.
        let nd = textureLoad(normal_depth, texel, 0);
        if !is_valid(nd) {
            continue;
        }
        let q_cam = back_project(cam, texel, nd.w);
        let q_world = transform_point(params.t_cam_to_world, q_cam);
        let nq_world = transform_dir(params.t_cam_to_world, xyz(nd));
        let n_old = bitcast<vec3<f32>>(textureLoad(normal_frame, surfel).xyz);
        if params.association == ASSOCIATION_PROJECTIVE
            && (length(q_world - p_world) >= params.dist_threshold_m
                || dot(n_old, nq_world) <= params.cos_normal_threshold) {
            continue;
        }
        let w = pw.w;
        let wq = pixel_confidence(cam, texel, params.confidence_sigma);
        let inv = 1.0 / (w + wq);
        let p = (p_world * w + q_world * wq) * inv;
        let n = normalize_or_zero((n_old * w + nq_world * wq) * inv);
        let c = textureLoad(color, surfel);
        let cq = textureLoad(color_map, texel, 0);
        let r = (c.w * w + surfel_radius(params.fx, q_cam, xyz(nd)) * wq) * inv;
        textureStore(position_weight, surfel, vec4<f32>(p, w + wq));
        textureStore(normal_frame, surfel, vec4<u32>(bitcast<vec3<u32>>(n), params.frame_id));
        textureStore(color, surfel, vec4<f32>((c.xyz * w + cq.xyz * wq) * inv, r));
        if params.association == ASSOCIATION_PROJECTIVE {
            atomicMax(&assoc[pix], 1lu);
        }
    }
}
