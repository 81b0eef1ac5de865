// fuse_flags.wgsl: one flag per pixel, 1 where the pixel becomes a new surfel: a valid
// measurement that no surfel merged with (projective association) or covers (best
// candidate), at the pixel's append_index. First of fuse_add's three kernels (then
// prefix_sum over the flags, which gives each new surfel its slot in append order, see
// `layout::APPEND_TILE_PX`, then fuse_add). CPU twin: crates/core/src/cpu/fuse_flags.rs (its header
// says why best-candidate association asks the neighbours).
//
// Bindings (@group(0)): each is described by the comment above its declaration.
// A 2-D grid-stride loop over the pixels in 8x8 tiles (see vertex_to_normal.wgsl).

// Tracked pose, intrinsics, size, association, gates.
@group(0) @binding(0) var<storage, read> params: FuseParams;
// width x height, camera-frame normal with the depth in w, zero where invalid.
@group(0) @binding(1) var normal_depth: texture_2d<f32>;
// The u64 key per pixel (low word first), non-zero where a surfel merged with or was
// chosen by the pixel.
@group(0) @binding(2) var<storage, read> assoc: array<vec2<u32>>;
// Best-candidate association only: per pixel the surfel it merged into
// (fuse_merge_chosen: position_weight at 2 pix, w > 0 where it merged; unit normal and
// radius at 2 pix + 1).
@group(0) @binding(3) var<storage, read> merged: array<vec4<f32>>;
// Out: 1 new surfel / 0 not, at append_index of the pixel (layout::append_slots(width,
// height) entries; the holes, no pixel's, are never written and stay 0).
@group(0) @binding(4) var<storage, read_write> flags: array<u32>;

const TILE_X: u32 = 8u;
const TILE_Y: u32 = 8u;

// Whether pixel `texel` becomes a new surfel, at its append slot (the entry point:
// pixel_grid.wgsl).
fn per_pixel(p: FuseParams, texel: vec2<u32>) {
    let key = assoc[texel.y * p.camera.width + texel.x];
    let nd = textureLoad(normal_depth, texel, 0);
    // Valid normal (w = depth > 0) implies a valid vertex: the twin's two tests.
    var new_surfel = key.x == 0u && key.y == 0u && is_valid(nd);
    if new_surfel && p.association == ASSOCIATION_BEST_CANDIDATE {
        new_surfel = !neighbour_covers(p, texel, nd);
    }
    flags[append_index(texel)] = select(0u, 1u, new_surfel);
}

#define CAMERA_PARAMS
#entry pixel_grid

// Whether a surfel that one of the 8 neighbours of `texel` (measurement nd, valid) merged
// into passes this pixel's gates (fuse_select's filter 2). `params` is main's copy of the
// binding.
fn neighbour_covers(params: FuseParams, texel: vec2<u32>, nd: vec4<f32>) -> bool {
    let cam = camera_intrinsics(params.camera);
    for (var dv = -1; dv <= 1; dv++) {
        for (var du = -1; du <= 1; du++) {
            let u = i32(texel.x) + du;
            let v = i32(texel.y) + dv;
            if (du == 0 && dv == 0) || u < 0 || v < 0 || u >= i32(params.camera.width)
                || v >= i32(params.camera.height) {
                continue;
            }
            let pix = u32(v) * params.camera.width + u32(u);
            let pw = merged[2u * pix];
            if !is_valid(pw) {
                continue;
            }
            let nr = merged[2u * pix + 1u];
            let p_cam = transform_point(params.t_world_to_cam, xyz(pw));
            let n_cam = transform_dir(params.t_world_to_cam, xyz(nr));
            if candidate_off_ray(cam, texel, nd, p_cam, n_cam, nr.w, fuse_depth_gate(params, pw.w),
                params.cos_normal_threshold) >= 0.0 {
                return true;
            }
        }
    }
    return false;
}
