// visible_surfels.wgsl: the entry point of every kernel that walks the map chunk's surfels
// in view, appended to a kernel whose file says `#entry visible_surfels`
// (crates/gpu/src/shaders.rs).
// CPU twin: crates/core/src/cpu/entries.rs, fn visible_surfels (re-exported as cpu::visible_surfels).
// Not valid alone: the kernel declares
//   params                             a binding whose struct has t_world_to_cam,
//                                      camera: Camera (intrinsics and image size) and
//                                      surfel_count;
//   chunk: MapChunk, block_boxes        the chunk and its blocks' world-frame boxes
//                                      (array<vec4<u32>>, min at 2b, max at 2b + 1);
//   fn per_surfel(p, i, slot, cam)     the work of surfel i (map-wide index; `slot` in the
//                                      chunk's arrays), on main's copy of the params, with
//                                      cam = (fx, fy, cx, cy).
//
// Workgroups stride over the chunk's blocks; a block whose box is out of view is skipped
// whole (block_visible); the workgroup's threads stride over the block's surfels.

const WORKGROUP_SIZE: u32 = 64u;

@compute @workgroup_size(WORKGROUP_SIZE)
fn main(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(local_invocation_id) lid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
) {
    // The params copied once per thread (see pixel_grid.wgsl).
    let p = params;
    let cam = camera_intrinsics(p.camera);
    let span = chunk_blocks(chunk, p.surfel_count);
    // The chunk's first index copied once per thread, as the params.
    let base = chunk.base;
    for (var b = wid.x; b < span.x; b += nwg.x) {
        let block = base / BLOCK_SURFELS + b;
        let lo = decode_corner(block_boxes[2u * block]);
        let hi = decode_corner(block_boxes[2u * block + 1u]);
        if !block_visible(p.t_world_to_cam, cam, p.camera.width, p.camera.height, lo, hi) {
            continue;
        }
        let end = min(base + (b + 1u) * BLOCK_SURFELS, span.y);
        for (var i = base + b * BLOCK_SURFELS + lid.x; i < end; i += WORKGROUP_SIZE) {
            per_surfel(p, i, i - base, cam);
        }
    }
}
