// render_splat.wgsl: splats surfels as small discs into a depth|index map, for pictures
// of the map (not for tracking). CPU twin: crates/core/src/cpu/render_splat.rs.
//
// Prepended with common.wgsl (transform_point, transform_dir, xyz, depth_key).
// Bindings (@group(0)): each is described by the comment above its declaration.
// Each covered pixel keeps max(depth_key(z_cam) << 32 | index): the nearest surfel (by
// centre depth) wins, ties to the larger index, 0 = empty; as in project_model, and in its
// two variants (KEY_64: one u64 atomicMax, needs SHADER_INT64_ATOMIC_MIN_MAX; else
// render_splat_portable, (low, high) u32 words in two passes, KEY_PASS 0 then 1; see
// keep_nearer in shaders/key_writer.wgsl, appended). Grid-stride loop over surfels, so any
// workgroup count covers the whole map.

// RenderParams (mirrors `layout::render::RenderParams`) lives in common.wgsl.

// Mirrors `cpu::render_splat::MAX_PROJECTED_PX`.
const MAX_PROJECTED_PX: f32 = 1.0e7;

// The view and splat sizes (RenderParams mirrors crates/core/src/layout/render.rs).
@group(0) @binding(0) var<storage, read> params: RenderParams;
// Surfel centres, world frame, metres; surfel_count entries read.
@group(0) @binding(1) var<storage, read> positions: array<vec4<f32>>;
// Surfel normals, world frame; read only when cull_backfaces == 1.
@group(0) @binding(2) var<storage, read> normals: array<vec4<f32>>;
// width x height keys, row-major, cleared to 0 by the host (before pass 0): one u64 each,
// or without KEY_64 two u32 words each (low = index, high = depth word).
#ifdef KEY_64
@group(0) @binding(3) var<storage, read_write> index_map: array<atomic<u64>>;
#else
@group(0) @binding(3) var<storage, read_write> index_map: array<atomic<u32>>;
#endif

// Pixel radius of a splat at camera depth z. Mirrors `cpu::render_splat::splat_radius_px`.
fn splat_radius_px(z: f32) -> f32 {
    let f = max(abs(params.camera.fx), abs(params.camera.fy));
    return clamp(params.splat_radius_m * f / z, params.min_radius_px, params.max_radius_px);
}

@compute @workgroup_size(64)
fn main(
    @builtin(global_invocation_id) gid: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    let stride = groups.x * 64u;
    let w = params.camera.width;
    let h = params.camera.height;
    for (var i = gid.x; i < params.surfel_count; i += stride) {
        let p = transform_point(params.t_world_to_cam, xyz(positions[i]));
        // Negated so that a NaN depth is skipped too.
        if !(p.z > params.near_m && p.z <= params.far_m) {
            continue;
        }
        if params.cull_backfaces == 1u {
            let n = transform_dir(params.t_world_to_cam, xyz(normals[i]));
            if dot(n, p) > 0.0 {
                continue;
            }
        }
        let u = params.camera.fx * p.x / p.z + params.camera.cx;
        let v = params.camera.fy * p.y / p.z + params.camera.cy;
        if !(abs(u) < MAX_PROJECTED_PX && abs(v) < MAX_PROJECTED_PX) {
            continue;
        }
        let r = splat_radius_px(p.z);
        let u0 = max(ceil(u - r), 0.0);
        let u1 = min(floor(u + r), f32(w - 1u));
        let v0 = max(ceil(v - r), 0.0);
        let v1 = min(floor(v + r), f32(h - 1u));
        if u0 > u1 || v0 > v1 {
            continue;
        }
        let depth_word = depth_key(p.z);
        for (var py = u32(v0); py <= u32(v1); py++) {
            let dv = f32(py) - v;
            for (var px = u32(u0); px <= u32(u1); px++) {
                let du = f32(px) - u;
                if du * du + dv * dv <= r * r {
                    keep_nearer(py * w + px, depth_word, i);
                }
            }
        }
    }
}
