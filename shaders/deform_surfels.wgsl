// deform_surfels.wgsl: moves the map with the pose graph after a loop closure. Each surfel
// blends the world-frame corrections of its two nearest graph nodes in time: the last node
// at or before its last_frame and the first one after it, weighted linearly by frame; a
// surfel before the first node or after the last takes that node's correction alone.
// Position: the two corrected positions blended; normal: the two rotated normals blended,
// renormalised (as ElasticFusion's deformation graph blends its nodes' transforms). CPU
// twin: crates/core/src/cpu/deform_surfels.rs. Dispatched once per map chunk.
//
// Bindings (@group(0)): each is described by the comment above its declaration.
// Grid-stride loop over surfels; each thread writes only its own surfel.

// Uses surfel_count and node_count.
@group(0) @binding(0) var<storage, read> params: DeformParams;
// The chunk's first map-wide index and slots (see crates/gpu/src/map_buffers.rs).
@group(0) @binding(1) var<storage, read> chunk: MapChunk;
// node_count nodes sorted by frame, each a frame and a world-frame correction.
@group(0) @binding(2) var<storage, read> nodes: array<DeformNode>;
// In/out: the chunk's surfels, xyz world frame (metres), w = weight (kept).
@group(0) @binding(3) var<storage, read_write> position_weight: array<vec4<f32>>;
// In/out: normal bits (world frame), w = last_frame (kept).
@group(0) @binding(4) var<storage, read_write> normal_frame: array<vec4<u32>>;

const WORKGROUP_SIZE: u32 = 64u;

// The first node whose frame is after `frame` (node_count when none): a binary search
// over the sorted table.
fn node_after(frame: u32, node_count: u32) -> u32 {
    var lo = 0u;
    var hi = node_count;
    while lo < hi {
        let mid = (lo + hi) / 2u;
        if nodes[mid].frame <= frame {
            lo = mid + 1u;
        } else {
            hi = mid;
        }
    }
    return lo;
}

// R p + t with a node's correction.
fn correct_point(node: DeformNode, p: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(
        dot(node.rows[0].xyz, p) + node.rows[0].w,
        dot(node.rows[1].xyz, p) + node.rows[1].w,
        dot(node.rows[2].xyz, p) + node.rows[2].w,
    );
}

// R n with a node's correction.
fn correct_normal(node: DeformNode, n: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(dot(node.rows[0].xyz, n), dot(node.rows[1].xyz, n), dot(node.rows[2].xyz, n));
}

@compute @workgroup_size(WORKGROUP_SIZE)
fn main(
    @builtin(global_invocation_id) gid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
) {
    let stride = nwg.x * WORKGROUP_SIZE;
    // The params copied once per thread (see pixel_grid.wgsl).
    let p = params;
    if p.node_count == 0u {
        return;
    }
    let end = chunk_blocks(chunk, p.surfel_count).y;
    let base = chunk.base;
    for (var i = base + gid.x; i < end; i += stride) {
        let surfel = i - base;
        let pw = position_weight[surfel];
        let nf = normal_frame[surfel];
        let k = node_after(nf.w, p.node_count);
        // The bracketing nodes and the weight of the later one.
        let a = nodes[select(k - 1u, 0u, k == 0u)];
        let b = nodes[min(k, p.node_count - 1u)];
        var w = 0.0;
        if k > 0u && k < p.node_count {
            w = f32(nf.w - a.frame) / f32(b.frame - a.frame);
        }
        let position = correct_point(a, pw.xyz) * (1.0 - w) + correct_point(b, pw.xyz) * w;
        let n = bitcast<vec3<f32>>(nf.xyz);
        let normal = normalize(correct_normal(a, n) * (1.0 - w) + correct_normal(b, n) * w);
        position_weight[surfel] = vec4<f32>(position, pw.w);
        normal_frame[surfel] = vec4<u32>(bitcast<vec3<u32>>(normal), nf.w);
    }
}
