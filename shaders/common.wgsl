// common.wgsl: structs and helpers shared by the dense-SLAM and render kernels (the scan
// kernels have their own prefix, scan_common.wgsl, with no 64-bit integers).
//
// Prepended to each `shaders/<kernel>.wgsl` by `crates/gpu/src/shaders.rs` (WGSL has no
// includes), so this file declares no bindings and no entry point. Each struct mirrors the
// `#[repr(C)]` struct of the same name in `crates/core/src/layout/mod.rs` (checked by `tests/it/layout.rs`;
// RenderParams: `crates/core/src/layout/render.rs`, checked by `tests/it/render/gpu.rs`); each helper mirrors
// the function of the same name in `crates/core/src/cpu/mod.rs`, its one Rust twin.
// Conventions: metres; pixel centres at integer (u, v); maps are row-major `v * width + u`;
// a `vec4` map entry is valid when `w > 0` (vertices and normals use w = 1, normal_depth
// the depth; invalid = 0).
// Matrices are column-major `mat4x4<f32>` (the layout of `GpuMat4`).

// Mirrors `layout::Camera`: a pinhole camera's intrinsics (pixels; fy may be negative) and
// image size, nested as `camera` in every params struct whose kernel projects or
// back-projects (`params.camera.fx`); the kernels' `cam` vec4 is (fx, fy, cx, cy).
struct Camera {
    fx: f32,
    fy: f32,
    cx: f32,
    cy: f32,
    width: u32,
    height: u32,
    _pad0: u32,
    _pad1: u32,
}

// The camera's (fx, fy, cx, cy), pixels: the `cam` vec4 the helpers below take. Mirrors
// `cpu::camera_intrinsics`.
fn camera_intrinsics(c: Camera) -> vec4<f32> {
    return vec4<f32>(c.fx, c.fy, c.cx, c.cy);
}

// Mirrors `layout::PreprocessParams` (depth_to_vertex).
struct PreprocessParams {
    camera: Camera,
    raw_width: u32,
    raw_height: u32,
    stride: u32,
    depth_scale: f32,
    min_depth_m: f32,
    max_depth_m: f32,
    _pad0: u32,
    _pad1: u32,
}

// Mirrors `layout::NormalParams` (vertex_to_normal).
struct NormalParams {
    width: u32,
    height: u32,
    max_depth_jump_m: f32,
    _pad: u32,
}

// Mirrors `layout::PyramidParams` (pyramid_depth, pyramid_model): coarse pixel (u, v)
// samples finer pixel (2u, 2v); the camera is the coarse level's.
struct PyramidParams {
    camera: Camera,
    fine_width: u32,
    fine_height: u32,
    radius_px: u32,
    max_depth_diff_m: f32,
    max_depth_diff_per_m2: f32,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
}

// Mirrors `layout::IntensityParams` (intensity_pyramid): level 0 reads the colour map, a
// coarser level the finer level's intensity patches; coarse pixel (u, v) is centred on
// finer pixel (2u, 2v).
struct IntensityParams {
    width: u32,
    height: u32,
    fine_width: u32,
    fine_height: u32,
    level: u32,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
}

// Mirrors `layout::FernParams` (fern_encode): the level-0 size and one fern cell's size.
struct FernParams {
    width: u32,
    height: u32,
    cell_width: u32,
    cell_height: u32,
    fern_count: u32,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
}

// Mirrors `layout::Fern`: a cell of the fern grid and the red, green, blue (0..255) and
// depth (metres) thresholds.
struct Fern {
    cell_u: u32,
    cell_v: u32,
    _pad0: u32,
    _pad1: u32,
    threshold: vec4<f32>,
}

// The code of a fern whose cell has no valid depth (mirrors `layout::FERN_NO_DEPTH`).
const FERN_NO_DEPTH: u32 = 16u;

// Mirrors `layout::KeypointParams` (keypoint_detect, keypoint_describe).
struct KeypointParams {
    width: u32,
    height: u32,
    threshold: f32,
    capacity: u32,
    count: u32,
    tests: u32,
    _pad0: u32,
    _pad1: u32,
}

// Mirrors `layout::Keypoint`: a corner's pixel and Harris response.
struct Keypoint {
    u: u32,
    v: u32,
    score: f32,
    _pad: u32,
}

// Words of one descriptor (mirrors `layout::DESCRIPTOR_WORDS`).
const DESCRIPTOR_WORDS: u32 = 8u;

// Mirrors `layout::BilateralParams` (bilateral_filter).
struct BilateralParams {
    camera: Camera,
    radius_px: u32,
    sigma_space_px: f32,
    sigma_depth_m: f32,
    sigma_depth_per_m2: f32,
    filter_points: u32,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
}

// Mirrors `layout::ProjectParams` (project_model, predict_model).
struct ProjectParams {
    t_world_to_cam: mat4x4<f32>,
    camera: Camera,
    surfel_count: u32,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
}

// Mirrors `layout::IcpParams` (icp_reduce, photo_reduce).
struct IcpParams {
    t_world_to_cam: mat4x4<f32>,
    camera: Camera,
    dist_m: f32,
    cos_normal_threshold: f32,
    huber_m: f32,
    noise_weighting: u32,
    photo_depth_gate_m: f32,
    photo_huber: f32,
    photo_gradient_min: f32,
    photo_source_step: u32,
    photo_source_width: u32,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
}

// Mirrors `layout::FuseParams` (fuse_merge, fuse_add).
struct FuseParams {
    t_world_to_cam: mat4x4<f32>,
    t_cam_to_world: mat4x4<f32>,
    camera: Camera,
    surfel_count: u32,
    frame_id: u32,
    dist_m: f32,
    cos_normal_threshold: f32,
    capacity: u32,
    association: u32,
    confidence_sigma: f32,
    prune_scale: f32,
    dist_confident_m: f32,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
}

// Best-candidate fusion's depth gate (metres) for a surfel of weight `weight`: from
// dist_m for a surfel seen once towards dist_confident_m as its weight grows.
// Mirrors `fuse_depth_gate` in crates/core/src/cpu/mod.rs.
fn fuse_depth_gate(params: FuseParams, weight: f32) -> f32 {
    return params.dist_confident_m
        + (params.dist_m - params.dist_confident_m) / max(weight, 1.0);
}

// FuseParams::association (mirror `layout::ASSOCIATION_PROJECTIVE`, `..._BEST_CANDIDATE`).
const ASSOCIATION_PROJECTIVE: u32 = 0u;
const ASSOCIATION_BEST_CANDIDATE: u32 = 1u;

// Mirrors `layout::CompactParams` (compact_flags, prefix_sum, compact_scatter).
struct CompactParams {
    surfel_count: u32,
    frame_id: u32,
    stable_weight: f32,
    max_age_frames: u32,
}

// Floats in one reduced ICP system (mirrors `layout::ICP_SYSTEM_LEN`): 21 of AᵀA (upper
// triangle, row-major), 6 of Aᵀb, the inlier count and the sum of squared residuals.
const ICP_SYSTEM_LEN: u32 = 29u;
// Where the parts start (mirror `layout::ICP_ATB_OFFSET`, `ICP_COUNT_INDEX`,
// `ICP_RESIDUAL_INDEX`): Aᵀb at 21..27, the count at 27, the squared residuals at 28.
const ICP_ATB_OFFSET: u32 = 21u;
const ICP_COUNT_INDEX: u32 = 27u;
const ICP_RESIDUAL_INDEX: u32 = 28u;

// Mirrors `layout::MapChunk`: one chunk of the surfel map (three storage arrays of `slots`
// surfels; surfel i of the map is element i - base of the chunk that holds it). Kernels
// that walk the map are dispatched once per chunk. See crates/gpu/src/map_buffers.rs.
struct MapChunk {
    base: u32,
    slots: u32,
    _pad0: u32,
    _pad1: u32,
}

// Mirrors `layout::DeformParams` (deform_surfels).
struct DeformParams {
    surfel_count: u32,
    node_count: u32,
    _pad0: u32,
    _pad1: u32,
}

// Mirrors `layout::DeformNode` (deform_surfels): a pose-graph node's frame and its
// world-frame correction, rows of [R | t].
struct DeformNode {
    frame: u32,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
    rows: array<vec4<f32>, 3>,
}

// Mirrors `layout::BoundsParams` (block_bounds).
struct BoundsParams {
    surfel_count: u32,
    block_from: u32,
    _pad0: u32,
    _pad1: u32,
}

// Surfels per culling block (mirrors `layout::BLOCK_SURFELS`): block b holds map slots
// b * BLOCK_SURFELS .. (b + 1) * BLOCK_SURFELS; its box is entries 2b (min) and 2b + 1 (max)
// of block_bounds, as vec4<u32> of ordered_from_f32 values (w unused).
const BLOCK_SURFELS: u32 = 1024u;

// Side, pixels, of the square tiles that order a frame's new surfels (mirrors
// `layout::APPEND_TILE_PX`, which says why): fuse_add appends in append order, tiles in
// Morton order, pixels row-major inside a tile, so a block's new surfels come from one
// compact patch of the image and its box stays small.
const APPEND_TILE_PX: u32 = 16u;

// The low 16 bits of v moved to the even bit positions. Mirrors `layout::spread_bits`.
fn spread_bits(v: u32) -> u32 {
    var x = v & 0x0000ffffu;
    x = (x | (x << 8u)) & 0x00ff00ffu;
    x = (x | (x << 4u)) & 0x0f0f0f0fu;
    x = (x | (x << 2u)) & 0x33333333u;
    return (x | (x << 1u)) & 0x55555555u;
}

// Morton (Z-order) code of tile (x, y). Mirrors `layout::morton_2d`.
fn morton_2d(x: u32, y: u32) -> u32 {
    return spread_bits(x) | (spread_bits(y) << 1u);
}

// Position of pixel `texel` in append order: the index of its entry in fuse_flags' flags
// and their prefix sum (arrays of `layout::append_slots(width, height)`). Mirrors
// `cpu::append_index`.
fn append_index(texel: vec2<u32>) -> u32 {
    let tile = texel / APPEND_TILE_PX;
    let inside = texel % APPEND_TILE_PX;
    return morton_2d(tile.x, tile.y) * (APPEND_TILE_PX * APPEND_TILE_PX)
        + inside.y * APPEND_TILE_PX + inside.x;
}

// An f32 as a u32 whose unsigned order is the float order, so boxes grow with atomicMin /
// atomicMax. Mirrors `layout::ordered_from_f32`.
fn ordered_from_f32(x: f32) -> u32 {
    let bits = bitcast<u32>(x);
    if (bits & 0x80000000u) != 0u {
        return ~bits;
    }
    return bits | 0x80000000u;
}

// The inverse of ordered_from_f32. Mirrors `layout::f32_from_ordered`.
fn f32_from_ordered(u: u32) -> f32 {
    if (u & 0x80000000u) != 0u {
        return bitcast<f32>(u & 0x7fffffffu);
    }
    return bitcast<f32>(~u);
}

// (blocks, end): the blocks `chunk` spans and the end (map-wide index, exclusive) of its
// surfels when the map holds surfel_count; the loop bounds of every map-walking kernel.
// Mirrors `cpu::chunk_blocks`.
fn chunk_blocks(chunk: MapChunk, surfel_count: u32) -> vec2<u32> {
    let end = min(surfel_count, chunk.base + chunk.slots);
    if end <= chunk.base {
        return vec2<u32>(0u, chunk.base);
    }
    return vec2<u32>((end - chunk.base + BLOCK_SURFELS - 1u) / BLOCK_SURFELS, end);
}

// A box corner decoded from block_bounds.
fn decode_corner(v: vec4<u32>) -> vec3<f32> {
    return vec3<f32>(f32_from_ordered(v.x), f32_from_ordered(v.y), f32_from_ordered(v.z));
}

// How much wider than the image, in pixels, the culling frustum is: block_visible must
// never cull a surfel that project_to_texel would put in the image, and the box corners
// are transformed in f32 like the surfel (errors of ~1e-6 of the coordinates), so a
// 2-pixel band is far more than rounding can move a projection.
const CULL_MARGIN_PX: f32 = 2.0;
// Same for the near plane, metres: a box is behind the camera only if every corner is at
// least this far behind it.
const CULL_NEAR_MARGIN_M: f32 = 0.001;

// False only when no point of the world-frame box lo..hi can project into the width x
// height image (project_to_texel's filter 1): every corner lies outside one of five
// half-spaces of the camera frame, behind the camera or beyond an image edge (by
// CULL_MARGIN_PX), written without dividing by z (u = fx x / z + cx + 0.5 < -margin is
// fx x + (cx + 0.5 + margin) z < 0 for z > 0, any sign of fx). Each half-space is convex,
// so holding the 8 corners means holding the box; points behind the camera fail filter 1
// anyway. Conservative: a box it keeps may still be invisible. `t` = world to camera,
// cam = (fx, fy, cx, cy). Mirrors `cpu::block_visible`.
fn block_visible(t: mat4x4<f32>, cam: vec4<f32>, width: u32, height: u32, lo: vec3<f32>, hi: vec3<f32>) -> bool {
    let m = CULL_MARGIN_PX;
    var behind = true;
    var left = true;
    var right = true;
    var top = true;
    var bottom = true;
    for (var k = 0u; k < 8u; k++) {
        let pick = vec3<bool>((k & 1u) != 0u, (k & 2u) != 0u, (k & 4u) != 0u);
        let p = transform_point(t, select(lo, hi, pick));
        behind = behind && p.z < -CULL_NEAR_MARGIN_M;
        left = left && cam.x * p.x + (cam.z + 0.5 + m) * p.z < 0.0;
        right = right && cam.x * p.x + (cam.z + 0.5 - f32(width) - m) * p.z > 0.0;
        top = top && cam.y * p.y + (cam.w + 0.5 + m) * p.z < 0.0;
        bottom = bottom && cam.y * p.y + (cam.w + 0.5 - f32(height) - m) * p.z > 0.0;
    }
    return !(behind || left || right || top || bottom);
}

// The invalid map entry (mirrors `cpu::INVALID`).
const INVALID: vec4<f32> = vec4<f32>(0.0, 0.0, 0.0, 0.0);

// predict_model's pred_intensity where the pixel has no surfel (mirrors
// `cpu::photo_reduce::INTENSITY_NONE`; intensities are 0..1).
const INTENSITY_NONE: f32 = -1.0;

// `T p` for a point (w = 1). Mirrors `cpu::transform_point`.
fn transform_point(t: mat4x4<f32>, p: vec3<f32>) -> vec3<f32> {
    return (t * vec4<f32>(p, 1.0)).xyz;
}

// `R n` for a direction (w = 0). Mirrors `cpu::transform_dir`.
fn transform_dir(t: mat4x4<f32>, n: vec3<f32>) -> vec3<f32> {
    return (t * vec4<f32>(n, 0.0)).xyz;
}

// Filter 1: the pixel index a camera-frame point projects to, rounding to the nearest
// pixel centre, or -1 when it is behind the camera (z <= 0) or outside the image.
// `cam` = (fx, fy, cx, cy). Mirrors `cpu::project_to_pixel` (which returns None for -1).
fn project_to_pixel(cam: vec4<f32>, width: u32, height: u32, p: vec3<f32>) -> i32 {
    let uv = project_to_texel(cam, width, height, p);
    if uv.x < 0 {
        return -1;
    }
    return uv.y * i32(width) + uv.x;
}

// Filter 1 as a texel: the pixel (u, v) of project_to_pixel, or (-1, -1) when it misses.
// Kernels that read textures use this directly (no index division on CPU adapters).
fn project_to_texel(cam: vec4<f32>, width: u32, height: u32, p: vec3<f32>) -> vec2<i32> {
    if p.z <= 0.0 {
        return vec2<i32>(-1);
    }
    let u = floor(cam.x * p.x / p.z + cam.z + 0.5);
    let v = floor(cam.y * p.y / p.z + cam.w + 0.5);
    if u < 0.0 || v < 0.0 || u >= f32(width) || v >= f32(height) {
        return vec2<i32>(-1);
    }
    return vec2<i32>(i32(u), i32(v));
}

// The camera-frame point of pixel `texel` at depth z (metres), cam = (fx, fy, cx, cy):
// depth_to_vertex's back-projection, `((u - cx) z / fx, (v - cy) z / fy, z)`, in the order
// of its twin. Kernels that rebuild a vertex from a normal_depth texel call this same
// function, so they get the vertex map's bits back.
fn back_project(cam: vec4<f32>, texel: vec2<u32>, z: f32) -> vec3<f32> {
    let x = (f32(texel.x) - cam.z) * z / cam.x;
    let y = (f32(texel.y) - cam.w) * z / cam.y;
    return vec3<f32>(x, y, z);
}

// Filter 2 of best-candidate association (fuse_select, fuse_flags): how far surfel centre
// p_cam (camera frame, metres; unit normal n_cam, radius_m) lies off the ray of pixel
// `texel`, whose measurement nd is its camera-frame normal with the depth in w (valid).
// Negative when a gate fails: the distance along the ray is dist_m or more, the distance
// off the ray radius_m or more (the disc misses the ray), or the normals' cosine is
// cos_normal or less. Mirrors `cpu::candidate_off_ray`.
fn candidate_off_ray(
    cam: vec4<f32>,
    texel: vec2<u32>,
    nd: vec4<f32>,
    p_cam: vec3<f32>,
    n_cam: vec3<f32>,
    radius_m: f32,
    dist_m: f32,
    cos_normal: f32,
) -> f32 {
    let q = back_project(cam, texel, nd.w);
    let ray = q / length(q);
    let d = p_cam - q;
    let along = dot(d, ray);
    let off_ray = length(d - ray * along);
    if abs(along) >= dist_m || off_ray >= radius_m || dot(n_cam, xyz(nd)) <= cos_normal {
        return -1.0;
    }
    return off_ray;
}

// xyz of a vec4 map entry. Mirrors `cpu::xyz`.
fn xyz(v: vec4<f32>) -> vec3<f32> {
    return v.xyz;
}

// Huber weight of a residual b (metres in icp_reduce, intensity in photo_reduce): 1 within delta, delta / |b| beyond; 1 when
// delta is 0 (off). Mirrors `cpu::huber_weight`.
fn huber_weight(b: f32, delta: f32) -> f32 {
    if delta <= 0.0 || abs(b) <= delta {
        return 1.0;
    }
    return delta / abs(b);
}

// Intensity (0..1) of an RGB colour (0..255): ITU-R BT.601 luma over 255, the
// photometric term's unit. Mirrors `cpu::intensity_of`.
fn intensity_of(rgb: vec3<f32>) -> f32 {
    return (0.299 * rgb.x + 0.587 * rgb.y + 0.114 * rgb.z) / 255.0;
}

// A map entry is valid when its w is positive. Mirrors `cpu::is_valid`.
fn is_valid(v: vec4<f32>) -> bool {
    return v.w > 0.0;
}

// Packs a valid point or direction into a map entry (w = 1). Mirrors `cpu::valid_entry`.
fn valid_entry(p: vec3<f32>) -> vec4<f32> {
    return vec4<f32>(p, 1.0);
}

// The high word of an index-map key: the complement of a camera depth's bits (metres,
// > 0), so the larger word is the nearer surfel and 0 means none. The 64-bit kernels pack
// it with the surfel index (pack_depth_index, kept in those kernels so that this file
// needs no 64-bit integers); the portable kernels keep it and the index as two u32 words
// (keep_nearer). Mirrors `cpu::depth_key`.
fn depth_key(z_cam: f32) -> u32 {
    return ~bitcast<u32>(z_cam);
}

// Radius (metres) of the disc a pixel's measurement covers: the pixel's footprint at depth
// q_cam.z times sqrt(2) (the disc through the pixel's corners), grown by the viewing angle
// (1 / cos between the normal and the ray) up to twice that (Keller et al. 2013, Sec. 4.1;
// ElasticFusion). q_cam, n_cam: camera frame; focal_px = fx. Mirrors `cpu::surfel_radius`.
fn surfel_radius(focal_px: f32, q_cam: vec3<f32>, n_cam: vec3<f32>) -> f32 {
    let footprint = 1.41421356 * q_cam.z / focal_px;
    let cos_view = abs(dot(n_cam, q_cam)) / length(q_cam);
    return footprint / max(cos_view, 0.5);
}

// v / |v|, or zero when |v| is zero (glam's `normalize_or_zero` in the twin).
// Mirrors `cpu::normalize_or_zero`.
fn normalize_or_zero(v: vec3<f32>) -> vec3<f32> {
    let len = length(v);
    if len > 0.0 {
        return v * (1.0 / len);
    }
    return vec3<f32>(0.0);
}

// A surfel after merging one measurement into it. Mirrors `cpu::MergedSurfel`.
struct MergedSurfel {
    position_weight: vec4<f32>,
    normal: vec3<f32>,
    color: vec4<f32>,
}

// Fusion's merge (Keller et al. 2013, Sec. 4.2): the confidence-weighted averages
// (w x + wq x_q) / (w + wq) of position, normal (renormalised), colour and radius, and the
// weight w + wq, of a surfel (pw: world position + weight w; n_old: world normal; c: RGB +
// radius) and a measurement (q_world, nq_world: world frame; cq: RGB; wq: its confidence;
// r_q: its radius, metres). fuse_merge and fuse_merge_chosen share it. Mirrors
// `cpu::merged_surfel`.
fn merged_surfel(pw: vec4<f32>, n_old: vec3<f32>, c: vec4<f32>, q_world: vec3<f32>, nq_world: vec3<f32>, cq: vec3<f32>, wq: f32, r_q: f32) -> MergedSurfel {
    let w = pw.w;
    let inv = 1.0 / (w + wq);
    let p = (pw.xyz * w + q_world * wq) * inv;
    let n = normalize_or_zero((n_old * w + nq_world * wq) * inv);
    let r = (c.w * w + r_q * wq) * inv;
    return MergedSurfel(vec4<f32>(p, w + wq), n, vec4<f32>((c.xyz * w + cq * wq) * inv, r));
}

// Confidence of the measurement at pixel `texel`: a Gaussian over its distance from the
// principal point, normalised so the corner at distance |(cx, cy)| is 1 (Keller et al.
// 2013: the lens is worst at the border), or 1 when sigma is 0 (plain counts).
// cam = (fx, fy, cx, cy). Mirrors `cpu::pixel_confidence`.
fn pixel_confidence(cam: vec4<f32>, texel: vec2<u32>, sigma: f32) -> f32 {
    if sigma <= 0.0 {
        return 1.0;
    }
    let d = vec2<f32>(f32(texel.x) - cam.z, f32(texel.y) - cam.w) / length(cam.zw);
    return exp(-dot(d, d) / (2.0 * sigma * sigma));
}

// Used by render_splat and render_resolve.
// Mirrors `layout::render::RenderParams`.
struct RenderParams {
    t_world_to_cam: mat4x4<f32>,
    camera: Camera,
    surfel_count: u32,
    view: u32,
    splat_radius_m: f32,
    min_radius_px: f32,
    max_radius_px: f32,
    cull_backfaces: u32,
    near_m: f32,
    far_m: f32,
    weight_max: f32,
    background: u32,
    fill_gap_px: u32,
    _pad0: u32,
}
