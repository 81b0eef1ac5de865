// pixel_grid.wgsl: the entry point of every per-pixel kernel, appended to a kernel whose
// file says `#entry pixel_grid` (crates/gpu/src/shaders.rs).
// CPU twin: crates/core/src/cpu/entries.rs, fn pixel_grid (re-exported as cpu::pixel_grid).
// Not valid alone: the kernel declares
//   const TILE_X, TILE_Y: u32        its workgroup's tile of pixels;
//   params                           a binding whose struct has the image's width, height
//                                    (with `#define CAMERA_PARAMS`: its `camera: Camera`
//                                    has them);
//   fn per_pixel(p, texel)           the work of one pixel, on main's copy of the params;
//                                    with `#define MAP_CHUNK` it is per_pixel(p, chunk,
//                                    texel), on main's copy of the `chunk` binding too.
//
// A 2-D grid-stride loop in tiles: on lavapipe these beat a grid-stride loop over pixel
// indices (no index division, whole rows of neighbours per SIMD batch). The tiles stride
// over the image in both directions, so the host chooses the workgroup count
// (Kernel::grid_workgroups_for_image): one thread per pixel on a GPU; on lavapipe, which
// pays per workgroup, one workgroup per band of rows that walks the band left to right.
// The params (and chunk) are copied once per thread and passed down: read inside the
// loop, lavapipe loads them from the storage buffer again for every pixel
// (depth_to_vertex measured 15% slower that way).

@compute @workgroup_size(TILE_X, TILE_Y)
fn main(
    @builtin(global_invocation_id) gid: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    let stride = vec2<u32>(TILE_X, TILE_Y) * groups.xy;
    let p = params;
#ifdef MAP_CHUNK
    let ch = chunk;
#endif
#ifdef CAMERA_PARAMS
    let size = vec2<u32>(p.camera.width, p.camera.height);
#else
    let size = vec2<u32>(p.width, p.height);
#endif
    for (var v = gid.y; v < size.y; v += stride.y) {
        for (var u = gid.x; u < size.x; u += stride.x) {
#ifdef MAP_CHUNK
            per_pixel(p, ch, vec2<u32>(u, v));
#else
            per_pixel(p, vec2<u32>(u, v));
#endif
        }
    }
}
