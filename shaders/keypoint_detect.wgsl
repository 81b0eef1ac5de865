// keypoint_detect.wgsl: Harris corners of the level-0 colour for feature-based
// relocalisation: every pixel with valid depth whose response is above the threshold and
// above its 8 neighbours' is appended to the candidate list.
// CPU twin: crates/core/src/cpu/keypoint_detect.rs (its header says why Harris and why sums).
//
// Bindings (@group(0)): each is described by the comment above its declaration.
// A 2-D grid-stride loop over the pixels in 8x8 tiles; the response of a neighbour is
// computed only for a pixel that passes the threshold (few do).

// width, height, threshold and capacity are used.
@group(0) @binding(0) var<storage, read> params: KeypointParams;
// Level-0 colour, red, green, blue in 0..255.
@group(0) @binding(1) var color_map: texture_2d<f32>;
// Level-0 normals with depth (metres) in w; a corner needs valid depth (w > 0).
@group(0) @binding(2) var normal_depth: texture_2d<f32>;
// Out: the first `capacity` corners found, in no particular order.
@group(0) @binding(3) var<storage, read_write> keypoints: array<Keypoint>;
// Out: corners found (may exceed capacity); zeroed by the host before the dispatch.
@group(0) @binding(4) var<storage, read_write> counter: array<atomic<u32>>;

const TILE: u32 = 8u;
// Pixels this close to the border have no full window for their neighbours' responses.
const BORDER: u32 = 3u;
// Harris's k.
const HARRIS_K: f32 = 0.04;

// Grey level of texel (u, v): r + g + b (0..765; a sum, not a mean, so it is exact).
// Mirrors `grey` in crates/core/src/cpu/keypoint_detect.rs.
fn grey(u: u32, v: u32) -> f32 {
    let c = textureLoad(color_map, vec2<u32>(u, v), 0);
    return c.x + c.y + c.z;
}

// Harris response at (u, v) over a 3x3 window of central differences. Mirrors `harris`.
fn harris(u: u32, v: u32) -> f32 {
    var sxx = 0.0;
    var syy = 0.0;
    var sxy = 0.0;
    for (var y = v - 1u; y <= v + 1u; y++) {
        for (var x = u - 1u; x <= u + 1u; x++) {
            let ix = grey(x + 1u, y) - grey(x - 1u, y);
            let iy = grey(x, y + 1u) - grey(x, y - 1u);
            sxx += ix * ix;
            syy += iy * iy;
            sxy += ix * iy;
        }
    }
    let trace = sxx + syy;
    return sxx * syy - sxy * sxy - HARRIS_K * trace * trace;
}

// Whether (u, v) is a corner: valid depth, response above the threshold and above every
// neighbour's (a tie goes to the neighbour earlier in raster order). Mirrors `corner_at`.
fn corner_at(p: KeypointParams, u: u32, v: u32) -> f32 {
    if textureLoad(normal_depth, vec2<u32>(u, v), 0).w <= 0.0 {
        return -1.0;
    }
    let r = harris(u, v);
    if r <= p.threshold {
        return -1.0;
    }
    for (var y = v - 1u; y <= v + 1u; y++) {
        for (var x = u - 1u; x <= u + 1u; x++) {
            if x == u && y == v {
                continue;
            }
            let n = harris(x, y);
            let earlier = y < v || (y == v && x < u);
            if n > r || (n == r && earlier) {
                return -1.0;
            }
        }
    }
    return r;
}

@compute @workgroup_size(TILE, TILE)
fn main(
    @builtin(global_invocation_id) gid: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    let p = params;
    let stride = vec2<u32>(TILE, TILE) * groups.xy;
    for (var v = BORDER + gid.y; v + BORDER < p.height; v += stride.y) {
        for (var u = BORDER + gid.x; u + BORDER < p.width; u += stride.x) {
            let r = corner_at(p, u, v);
            if r < 0.0 {
                continue;
            }
            let slot = atomicAdd(&counter[0], 1u);
            if slot < p.capacity {
                keypoints[slot] = Keypoint(u, v, r, 0u);
            }
        }
    }
}
