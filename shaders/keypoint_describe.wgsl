// keypoint_describe.wgsl: a binary descriptor (BRIEF-like, 256 tests) and the camera-frame
// point of each keypoint, for feature-based relocalisation.
// CPU twin: crates/core/src/cpu/keypoint_describe.rs (its header says why box means).
//
// Bindings (@group(0)): each is described by the comment above its declaration.
// One thread per keypoint in a grid-stride loop.

// width, height, count and tests are used.
@group(0) @binding(0) var<storage, read> params: KeypointParams;
// Level-0 colour, red, green, blue in 0..255.
@group(0) @binding(1) var color_map: texture_2d<f32>;
// Level-0 vertices, CAMERA frame, metres, w = 1 valid / 0.
@group(0) @binding(2) var vertex_map: texture_2d<f32>;
// `count` keypoints to describe.
@group(0) @binding(3) var<storage, read> keypoints: array<Keypoint>;
// `tests` pairs of pixel offsets (ax, ay, bx, by) from the keypoint.
@group(0) @binding(4) var<storage, read> pattern: array<vec4<i32>>;
// Out: DESCRIPTOR_WORDS words per keypoint; bit t set when the box mean at offset a is
// darker than at offset b.
@group(0) @binding(5) var<storage, read_write> descriptors: array<u32>;
// Out: the keypoint's vertex (CAMERA frame), as the vertex map holds it.
@group(0) @binding(6) var<storage, read_write> points: array<vec4<f32>>;

const WORKGROUP_SIZE: u32 = 64u;

// Sum of r + g + b over the 3x3 box around (u, v) + d, clamped to the image (whole
// numbers: exact in f32). Mirrors `box_grey` in crates/core/src/cpu/keypoint_describe.rs.
fn box_grey(p: KeypointParams, u: u32, v: u32, d: vec2<i32>) -> f32 {
    let last = vec2<i32>(i32(p.width) - 1, i32(p.height) - 1);
    let c = vec2<i32>(i32(u), i32(v)) + d;
    var sum = 0.0;
    for (var dy = -1; dy <= 1; dy++) {
        for (var dx = -1; dx <= 1; dx++) {
            let t = clamp(c + vec2<i32>(dx, dy), vec2<i32>(0), last);
            let rgb = textureLoad(color_map, vec2<u32>(t), 0);
            sum += rgb.x + rgb.y + rgb.z;
        }
    }
    return sum;
}

@compute @workgroup_size(WORKGROUP_SIZE)
fn main(
    @builtin(global_invocation_id) gid: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    let p = params;
    let stride = groups.x * WORKGROUP_SIZE;
    for (var k = gid.x; k < p.count; k += stride) {
        let kp = keypoints[k];
        for (var w = 0u; w < DESCRIPTOR_WORDS; w++) {
            var bits = 0u;
            for (var b = 0u; b < 32u; b++) {
                let t = w * 32u + b;
                if t < p.tests {
                    let o = pattern[t];
                    if box_grey(p, kp.u, kp.v, o.xy) < box_grey(p, kp.u, kp.v, o.zw) {
                        bits |= 1u << b;
                    }
                }
            }
            descriptors[k * DESCRIPTOR_WORDS + w] = bits;
        }
        points[k] = textureLoad(vertex_map, vec2<u32>(kp.u, kp.v), 0);
    }
}
