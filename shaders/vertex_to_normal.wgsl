// vertex_to_normal.wgsl: normal map from the vertex map by central differences, oriented
// towards the camera. CPU twin: src/cpu/vertex_to_normal.rs (its header states the rules).
//
// Bindings (@group(0)):
//   0 params      uniform NormalParams
//   1 vertex_map  storage read   array<vec4<f32>>: width x height, camera frame, w = 1 / 0
//   2 normal_map  storage rw     array<vec4<f32>>: width x height, camera frame, unit, w = 1 / 0
// Grid-stride loop over pixels. Invalid on the border, next to an invalid vertex, across a depth
// jump larger than max_depth_jump_m, or where the cross product vanishes.

@group(0) @binding(0) var<uniform> params: NormalParams;
@group(0) @binding(1) var<storage, read> vertex_map: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read_write> normal_map: array<vec4<f32>>;

const WORKGROUP_SIZE: u32 = 64u;

@compute @workgroup_size(WORKGROUP_SIZE)
fn main(
    @builtin(global_invocation_id) gid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
) {
    let w = params.width;
    let h = params.height;
    let stride = nwg.x * WORKGROUP_SIZE;
    for (var pix = gid.x; pix < w * h; pix += stride) {
        let u = pix % w;
        let v = pix / w;
        normal_map[pix] = INVALID;
        if u == 0u || v == 0u || u + 1u >= w || v + 1u >= h {
            continue;
        }
        let c = vertex_map[pix];
        let l = vertex_map[pix - 1u];
        let r = vertex_map[pix + 1u];
        let t = vertex_map[pix - w];
        let b = vertex_map[pix + w];
        if !(is_valid(c) && is_valid(l) && is_valid(r) && is_valid(t) && is_valid(b)) {
            continue;
        }
        let jump = params.max_depth_jump_m;
        if abs(l.z - c.z) > jump || abs(r.z - c.z) > jump || abs(t.z - c.z) > jump
            || abs(b.z - c.z) > jump {
            continue;
        }
        let n = cross(xyz(r) - xyz(l), xyz(b) - xyz(t));
        let len = length(n);
        if len <= 1e-12 {
            continue;
        }
        var nn = n / len;
        if dot(nn, xyz(c)) > 0.0 {
            nn = -nn;
        }
        normal_map[pix] = valid_entry(nn);
    }
}
