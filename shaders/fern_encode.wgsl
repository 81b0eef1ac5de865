// fern_encode.wgsl: the frame's randomised-fern code, one 4-bit code per fern, for the
// relocalisation keyframe database (ElasticFusion's ferns; Glocker et al. 2015).
// CPU twin: crates/core/src/cpu/fern_encode.rs (its header says why cells and why sums).
//
// Bindings (@group(0)): each is described by the comment above its declaration.
// One thread per fern in a grid-stride loop; each reads only its own cell (a few dozen
// texels), so the kernel is tiny next to the per-pixel ones.

// The level-0 size, the cell size and the fern count.
@group(0) @binding(0) var<storage, read> params: FernParams;
// fern_count ferns: a cell and four thresholds each.
@group(0) @binding(1) var<storage, read> ferns: array<Fern>;
// Level-0 normals (camera frame) with depth (metres) in w, zero where invalid.
@group(0) @binding(2) var normal_depth: texture_2d<f32>;
// Level-0 colour, red, green, blue in 0..255.
@group(0) @binding(3) var color_map: texture_2d<f32>;
// Out: fern_count codes, 0..15, or FERN_NO_DEPTH for a cell without valid depth.
@group(0) @binding(4) var<storage, read_write> codes: array<u32>;

const WORKGROUP_SIZE: u32 = 64u;

// The code of `fern`: bit 3 red, bit 2 green, bit 1 blue, bit 0 depth, each set when the
// cell's mean over its valid-depth pixels is above the threshold. The means are compared
// as sums (sum > threshold * count) so no division rounds differently from the twin.
// Mirrors `fern_code` in crates/core/src/cpu/fern_encode.rs.
fn fern_code(p: FernParams, fern: Fern) -> u32 {
    let u0 = fern.cell_u * p.cell_width;
    let v0 = fern.cell_v * p.cell_height;
    var rgb = vec3<f32>(0.0);
    var depth = 0.0;
    var count = 0u;
    for (var v = v0; v < min(v0 + p.cell_height, p.height); v++) {
        for (var u = u0; u < min(u0 + p.cell_width, p.width); u++) {
            let nd = textureLoad(normal_depth, vec2<u32>(u, v), 0);
            if nd.w <= 0.0 {
                continue;
            }
            rgb += textureLoad(color_map, vec2<u32>(u, v), 0).xyz;
            depth += nd.w;
            count += 1u;
        }
    }
    if count == 0u {
        return FERN_NO_DEPTH;
    }
    let n = f32(count);
    let t = fern.threshold;
    return select(0u, 8u, rgb.x > t.x * n) | select(0u, 4u, rgb.y > t.y * n)
        | select(0u, 2u, rgb.z > t.z * n) | select(0u, 1u, depth > t.w * n);
}

@compute @workgroup_size(WORKGROUP_SIZE)
fn main(
    @builtin(global_invocation_id) gid: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    let p = params;
    let stride = groups.x * WORKGROUP_SIZE;
    for (var i = gid.x; i < p.fern_count; i += stride) {
        codes[i] = fern_code(p, ferns[i]);
    }
}
