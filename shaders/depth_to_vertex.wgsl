// depth_to_vertex.wgsl: raw 16-bit depth and RGBA8 to a camera-frame vertex map (metres)
// and a colour map, keeping every `stride`-th raw pixel. CPU twin: src/cpu/depth_to_vertex.rs.
//
// Bindings (@group(0)):
//   0 params      uniform PreprocessParams
//   1 raw_depth   storage read   array<u32>: u16 depth pairs, pixel k is the low half of
//                                word k/2 when k is even, the high half when odd
//                                (raw_width x raw_height pixels, depth units)
//   2 raw_rgba    storage read   array<u32>: packed RGBA8 (r | g << 8 | b << 16 | a << 24)
//   3 vertex_map  storage rw     array<vec4<f32>>: width x height, camera frame, w = 1 / 0
//   4 color_map   storage rw     array<vec4<f32>>: width x height, RGB 0..255, a = 255
// Grid-stride loop over output pixels (the host caps the workgroup count). Assumes raw_width >= stride * width (and the same for height).

@group(0) @binding(0) var<uniform> params: PreprocessParams;
@group(0) @binding(1) var<storage, read> raw_depth: array<u32>;
@group(0) @binding(2) var<storage, read> raw_rgba: array<u32>;
@group(0) @binding(3) var<storage, read_write> vertex_map: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read_write> color_map: array<vec4<f32>>;

// The u16 depth of raw pixel k, unpacked from its word.
fn raw_depth_at(k: u32) -> u32 {
    let word = raw_depth[k / 2u];
    return select(word & 0xffffu, word >> 16u, (k & 1u) == 1u);
}

const WORKGROUP_SIZE: u32 = 64u;

@compute @workgroup_size(WORKGROUP_SIZE)
fn main(
    @builtin(global_invocation_id) gid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
) {
    let w = params.width;
    let stride = nwg.x * WORKGROUP_SIZE;
    for (var pix = gid.x; pix < w * params.height; pix += stride) {
        let u = pix % w;
        let v = pix / w;
        let raw = v * params.stride * params.raw_width + u * params.stride;
        let z = f32(raw_depth_at(raw)) / params.depth_scale;
        let c = raw_rgba[raw];
        color_map[pix] = vec4<f32>(
            f32(c & 255u),
            f32((c >> 8u) & 255u),
            f32((c >> 16u) & 255u),
            255.0,
        );
        if z <= 0.0 || z < params.min_depth_m || z > params.max_depth_m {
            vertex_map[pix] = INVALID;
            continue;
        }
        let x = (f32(u) - params.cx) * z / params.fx;
        let y = (f32(v) - params.cy) * z / params.fy;
        vertex_map[pix] = valid_entry(vec3<f32>(x, y, z));
    }
}
