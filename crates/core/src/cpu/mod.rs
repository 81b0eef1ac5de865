//! CPU twins of the WGSL kernels: pure functions over typed slices, no wgpu.
//!
//! `crates/core/src/cpu/<kernel>.rs` mirrors `shaders/<kernel>.wgsl` one to one: same arguments in the
//! shader's `@binding(i)` order and in the same packed representation (the frame's
//! `normal_depth` texels, the surfel map's three packed arrays of [`crate::layout::map::SurfelMap`]),
//! same loop structure, same helper names. This module holds the one Rust twin of every
//! helper in `shaders/common.wgsl`, each under the same name; kernel-local helpers live in
//! the kernel's file on both sides. The per-pixel maths is the same on both sides; only the
//! reductions differ (f64 sums here, f32 workgroup partials summed in f64 on the host for
//! the GPU).
//!
//! Textures become row-major slices: texel `(u, v)` of a `width`-wide map is element
//! `v * width + u`. A 64-bit key map (`atomic<u64>`, or `vec2<u32>` read low word first)
//! becomes a `u64` slice (a key kernel's key map, a [`key_writer::KeyMap`], is that or a
//! pass of the portable variant's words). The GPU's surfel map is a list of chunks
//! (`layout::MapChunk`), each three storage arrays; a twin of a kernel that walks the map
//! takes one chunk's `MapChunk` and arrays, as the shader does per dispatch (the CPU
//! backend binds its whole map as one chunk).
//!
//! The twins of the registry's rows (all 33 kernels, each row `bound`) are written in
//! `binding::twin!`: the same typed parameters, called in the one call shape
//! `fn(&mut [Binding])` that the CPU engine runs by the row ([`binding`]): the CPU
//! backend's, and for the renderer's and scan registration's (5 of them) over their
//! callers' pools (`crate::cpu_backend::run_call`).

pub mod arith;
pub mod bilateral_filter;
pub mod binding;
pub mod block_bounds;
pub mod compact_flags;
pub mod compact_scatter;
pub mod cross_covariance;
pub mod deform_surfels;
pub mod depth_to_vertex;
pub mod entries;
pub mod fern_encode;
pub mod fuse_add;
pub mod fuse_flags;
pub mod fuse_merge;
pub mod fuse_merge_chosen;
pub mod fuse_prune;
pub mod fuse_select;
pub mod icp_candidates;
pub mod icp_reduce;
pub mod icp_reduce_final;
pub mod intensity_pyramid;
pub mod invocations;
pub mod key_writer;
pub mod keypoint_describe;
pub mod keypoint_detect;
pub mod nn_brute;
pub mod nn_grid;
pub mod photo_reduce;
pub mod predict_model;
pub mod prefix_sum;
pub mod prefix_sum_blocks;
pub mod prefix_sum_reduce;
pub mod project_model;
pub mod pyramid_depth;
pub mod pyramid_model;
pub mod render_resolve;
pub mod render_splat;
pub mod vertex_to_normal;

pub use entries::{pixel_grid, system_grid, visible_surfels};
// What scan registration's hosts take from its twins' files (they run the kernels by
// their plan's calls and name none: `tests/it/kernel_places.rs`): the target's hashed grid
// and the sum of the cross-covariance partials.
pub use cross_covariance::decode as decode_scan_partials;
use std::sync::atomic::{AtomicU32, Ordering};

use glam::{Mat4, Vec3, Vec4};
pub use nn_grid::HashGrid;

use crate::layout::{
    f32_from_ordered, morton_2d, Camera, FuseParams, GpuMat4, MapChunk, APPEND_TILE_PX,
    BLOCK_SURFELS,
};

/// Margin, pixels, by which [`block_visible`]'s frustum is wider than the image (see
/// `CULL_MARGIN_PX` in common.wgsl for why 2). Mirrors `CULL_MARGIN_PX`.
pub const CULL_MARGIN_PX: f32 = 2.0;
/// Margin, metres, behind the camera for [`block_visible`]. Mirrors `CULL_NEAR_MARGIN_M`.
pub const CULL_NEAR_MARGIN_M: f32 = 0.001;

/// A box corner decoded from `block_boxes` (xyz of one `[u32; 4]` entry). Mirrors
/// `decode_corner` in common.wgsl.
#[inline]
pub fn decode_corner(v: [u32; 4]) -> Vec3 {
    Vec3::new(
        f32_from_ordered(v[0]),
        f32_from_ordered(v[1]),
        f32_from_ordered(v[2]),
    )
}

/// False only when no point of the world-frame box `lo..hi` can project into the image
/// (filter 1): all 8 corners lie behind the camera or beyond one image edge (widened by
/// [`CULL_MARGIN_PX`]). Conservative, so culling never changes a kernel's output. `t` =
/// world to camera, `cam` = `(fx, fy, cx, cy)`. Mirrors `block_visible` in common.wgsl
/// (whose comment has the derivation).
pub fn block_visible(
    t: &GpuMat4,
    cam: [f32; 4],
    width: u32,
    height: u32,
    lo: Vec3,
    hi: Vec3,
) -> bool {
    let m = CULL_MARGIN_PX;
    let (mut behind, mut left, mut right, mut top, mut bottom) = (true, true, true, true, true);
    for k in 0..8u32 {
        let corner = Vec3::new(
            if k & 1 != 0 { hi.x } else { lo.x },
            if k & 2 != 0 { hi.y } else { lo.y },
            if k & 4 != 0 { hi.z } else { lo.z },
        );
        let p = transform_point(t, corner);
        behind = behind && p.z < -CULL_NEAR_MARGIN_M;
        left = left && cam[0] * p.x + (cam[2] + 0.5 + m) * p.z < 0.0;
        right = right && cam[0] * p.x + (cam[2] + 0.5 - width as f32 - m) * p.z > 0.0;
        top = top && cam[1] * p.y + (cam[3] + 0.5 + m) * p.z < 0.0;
        bottom = bottom && cam[1] * p.y + (cam[3] + 0.5 - height as f32 - m) * p.z > 0.0;
    }
    !(behind || left || right || top || bottom)
}

/// Blocks `chunk` spans and the end (map-wide index, exclusive) of its surfels when the map
/// holds `surfel_count`: the loop bounds every map-walking kernel starts with.
#[inline]
pub fn chunk_blocks(chunk: &MapChunk, surfel_count: u32) -> (u32, u32) {
    let end = surfel_count.min(chunk.base + chunk.slots);
    if end <= chunk.base {
        return (0, chunk.base);
    }
    ((end - chunk.base).div_ceil(BLOCK_SURFELS), end)
}

/// Huber weight of a residual `b` (metres in `icp_reduce`, intensity in `photo_reduce`): 1
/// within `delta`, `delta / |b|` beyond; 1 when `delta` is 0 (off). Mirrors `huber_weight`
/// in common.wgsl.
#[inline]
pub fn huber_weight(b: f32, delta: f32) -> f32 {
    if delta <= 0.0 || b.abs() <= delta {
        return 1.0;
    }
    delta / b.abs()
}

/// The invalid map entry. Mirrors `INVALID` in common.wgsl.
pub const INVALID: [f32; 4] = [0.0; 4];

/// `T p` for a point (w = 1). Mirrors `transform_point` in common.wgsl.
#[inline]
pub fn transform_point(t: &GpuMat4, p: Vec3) -> Vec3 {
    if arith::perturbed() {
        return arith::mat4_mul(t, p, 1.0);
    }
    (Mat4::from_cols_array_2d(t) * p.extend(1.0)).truncate()
}

/// `R n` for a direction (w = 0). Mirrors `transform_dir` in common.wgsl.
#[inline]
pub fn transform_dir(t: &GpuMat4, n: Vec3) -> Vec3 {
    if arith::perturbed() {
        return arith::mat4_mul(t, n, 0.0);
    }
    (Mat4::from_cols_array_2d(t) * n.extend(0.0)).truncate()
}

/// Filter 1: the pixel index (`v * width + u`) a camera-frame point projects to, or `None`
/// when it misses ([`project_to_texel`]). Mirrors `project_to_pixel` in common.wgsl (which
/// returns -1 for `None`).
#[inline]
pub fn project_to_pixel(cam: [f32; 4], width: u32, height: u32, p: Vec3) -> Option<usize> {
    let [u, v] = project_to_texel(cam, width, height, p)?;
    Some(v as usize * width as usize + u as usize)
}

/// Filter 1 as a texel: the pixel `(u, v)` a camera-frame point projects to, rounding to
/// the nearest pixel centre, or `None` when it is behind the camera (`z <= 0`) or outside
/// the image. `cam` = `(fx, fy, cx, cy)`. Mirrors `project_to_texel` in common.wgsl (which
/// returns `(-1, -1)` for `None`).
#[inline]
pub fn project_to_texel(cam: [f32; 4], width: u32, height: u32, p: Vec3) -> Option<[u32; 2]> {
    if p.z <= 0.0 {
        return None;
    }
    let u = (arith::div(cam[0] * p.x, p.z) + cam[2] + 0.5).floor();
    let v = (arith::div(cam[1] * p.y, p.z) + cam[3] + 0.5).floor();
    if u < 0.0 || v < 0.0 || u >= width as f32 || v >= height as f32 {
        return None;
    }
    Some([u as u32, v as u32])
}

/// The camera's `(fx, fy, cx, cy)`, pixels: the `cam` the helpers here take. Mirrors
/// `camera_intrinsics` in common.wgsl.
#[inline]
pub fn camera_intrinsics(c: &Camera) -> [f32; 4] {
    [c.fx, c.fy, c.cx, c.cy]
}

/// The camera-frame point (metres) of pixel `texel = (u, v)` at depth `z` (metres),
/// `((u - cx) z / fx, (v - cy) z / fy, z)` with `cam` = `(fx, fy, cx, cy)` as given (a
/// negative `fy` stays negative). `depth_to_vertex` makes the vertex map with it, and every
/// twin that rebuilds a vertex from a `normal_depth` texel calls it again, so the bits
/// match. Mirrors `back_project` in common.wgsl.
#[inline]
pub fn back_project(cam: [f32; 4], texel: [u32; 2], z: f32) -> Vec3 {
    let x = arith::div((texel[0] as f32 - cam[2]) * z, cam[0]);
    let y = arith::div((texel[1] as f32 - cam[3]) * z, cam[1]);
    Vec3::new(x, y, z)
}

/// Position of pixel `texel = (u, v)` in append order (tiles of [`APPEND_TILE_PX`] in Morton
/// order, pixels row-major inside a tile): the index of its entry in `fuse_flags`' flags and
/// their prefix sum, arrays of `layout::append_slots(width, height)`. Mirrors
/// `append_index` in common.wgsl.
#[inline]
pub fn append_index(texel: [u32; 2]) -> usize {
    let tile = [texel[0] / APPEND_TILE_PX, texel[1] / APPEND_TILE_PX];
    let inside = [texel[0] % APPEND_TILE_PX, texel[1] % APPEND_TILE_PX];
    (morton_2d(tile[0], tile[1]) * (APPEND_TILE_PX * APPEND_TILE_PX)
        + inside[1] * APPEND_TILE_PX
        + inside[0]) as usize
}

/// The world-frame unit normal stored as bits in a `normal_frame` entry's xyz (the shaders'
/// `bitcast<vec3<f32>>(normal_frame[i].xyz)`).
#[inline]
pub fn normal_of(nf: [u32; 4]) -> Vec3 {
    Vec3::new(
        f32::from_bits(nf[0]),
        f32::from_bits(nf[1]),
        f32::from_bits(nf[2]),
    )
}

/// Best-candidate fusion's depth gate (metres) for a surfel of weight `weight`: from
/// `dist_m` for a surfel seen once (weight 1 or less) towards `dist_confident_m`
/// as its weight grows, `dist_confident_m + (dist_m - dist_confident_m) /
/// max(weight, 1)`; exactly `dist_m` when the two are equal. Mirrors
/// `fuse_depth_gate` in common.wgsl.
#[inline]
pub fn fuse_depth_gate(params: &FuseParams, weight: f32) -> f32 {
    params.dist_confident_m + arith::div(params.dist_m - params.dist_confident_m, weight.max(1.0))
}

/// Filter 2 of best-candidate association (`fuse_select`, `fuse_flags`): how far surfel
/// centre `p_cam` (camera frame, metres; unit normal `n_cam`, `radius_m`) lies off the ray
/// of pixel `texel`, whose measurement `nd` is its camera-frame normal with the depth in w
/// (valid). `None` when a gate fails: the distance along the ray is `dist_m` or more, the
/// distance off the ray `radius_m` or more (the disc misses the ray), or the normals'
/// cosine is `cos_normal` or less. Mirrors `candidate_off_ray` in common.wgsl (negative for
/// `None`).
#[allow(clippy::too_many_arguments)] // the shader function's parameters, in order
#[inline]
pub fn candidate_off_ray(
    cam: [f32; 4],
    texel: [u32; 2],
    nd: [f32; 4],
    p_cam: Vec3,
    n_cam: Vec3,
    radius_m: f32,
    dist_m: f32,
    cos_normal: f32,
) -> Option<f32> {
    let q = back_project(cam, texel, nd[3]);
    let ray = arith::div3(q, arith::length(q));
    let d = p_cam - q;
    let along = arith::dot(d, ray);
    let off_ray = arith::length(d - ray * along);
    if along.abs() >= arith::depth_gate(dist_m)
        || off_ray >= radius_m
        || arith::dot(n_cam, xyz(nd)) <= cos_normal
    {
        return None;
    }
    Some(off_ray)
}

/// xyz of a `vec4` map entry. Mirrors `xyz` in common.wgsl.
#[inline]
pub fn xyz(v: [f32; 4]) -> Vec3 {
    Vec3::new(v[0], v[1], v[2])
}

/// Intensity (0..1) of an RGB colour (0..255): ITU-R BT.601 luma over 255, the
/// photometric term's unit (`photo_reduce`, `predict_model`). Mirrors `intensity_of` in
/// common.wgsl.
#[inline]
pub fn intensity_of(rgb: [f32; 4]) -> f32 {
    (0.299 * rgb[0] + 0.587 * rgb[1] + 0.114 * rgb[2]) / 255.0
}

/// A map entry is valid when its `w` is positive (vertex maps use w = 1 / 0,
/// `normal_depth` the depth / 0). Mirrors `is_valid` in common.wgsl.
#[inline]
pub fn is_valid(v: [f32; 4]) -> bool {
    v[3] > 0.0
}

/// Packs a valid point or direction into a map entry (w = 1). Mirrors `valid_entry` in
/// common.wgsl.
#[inline]
pub fn valid_entry(p: Vec3) -> [f32; 4] {
    Vec4::new(p.x, p.y, p.z, 1.0).to_array()
}

/// The high word of an index-map key: the complement of a camera depth's bits (metres,
/// > 0), larger = nearer, never 0. Mirrors `depth_key` in common.wgsl.
#[inline]
pub fn depth_key(z_cam: f32) -> u32 {
    !z_cam.to_bits()
}

/// One pass of the portable kernels' two-pass maximum of the 64-bit key `(high, index)` at
/// pixel `pix` of a map of `(low, high)` u32 word pairs (the little-endian layout of the
/// 64-bit keys): pass 0 raises the high word; pass 1 raises the low word to `index` if
/// `high` is the pixel's high word. After pass 0 over every surfel and then pass 1 over
/// every surfel, each pair equals the maximum 64-bit key ([`pack_depth_index`]) bit for
/// bit. Mirrors `keep_nearer` in `shaders/key_writer.wgsl` without `KEY_64`.
/// The words are atomics, as the shader's, so that many threads may raise one map: pass
/// 1 reads only high words, which pass 0 finished.
#[inline]
pub fn keep_nearer(map: &[AtomicU32], pix: usize, high: u32, index: u32, key_pass: u32) {
    if key_pass == 0 {
        map[2 * pix + 1].fetch_max(high, Ordering::Relaxed);
    } else if map[2 * pix + 1].load(Ordering::Relaxed) == high {
        map[2 * pix].fetch_max(index, Ordering::Relaxed);
    }
}

/// Packs a camera depth (metres, > 0) and a surfel index into an index-map key:
/// `(!bits(z_cam) as u64) << 32 | surfel`. The larger key is the nearer surfel (for positive
/// floats the bit pattern grows with the value, so its complement shrinks), ties go to the
/// larger index, and 0 means no surfel. Mirrors `pack_depth_index` in common.wgsl.
#[inline]
pub fn pack_depth_index(z_cam: f32, surfel: u32) -> u64 {
    (depth_key(z_cam) as u64) << 32 | surfel as u64
}

/// `v / |v|`, or zero when `|v|` is zero. Mirrors `normalize_or_zero` in common.wgsl.
#[inline]
pub fn normalize_or_zero(v: Vec3) -> Vec3 {
    arith::normalize_or_zero(v)
}

/// A surfel after merging one measurement into it. Mirrors `MergedSurfel` in common.wgsl.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MergedSurfel {
    /// World position (metres) and the new weight.
    pub position_weight: [f32; 4],
    /// World unit normal (zero if the average cancelled).
    pub normal: Vec3,
    /// RGB 0..255 and radius (metres).
    pub color: [f32; 4],
}

/// Fusion's merge (Keller et al. 2013, Sec. 4.2): the confidence-weighted averages
/// `(w x + wq x_q) / (w + wq)` of position, normal (renormalised), colour and radius, and
/// the weight `w + wq`, of a surfel (`pw`: world position + weight; `n_old`: world normal;
/// `c`: RGB + radius) and a measurement (`q_world`, `nq_world`: world frame; `cq`: RGB;
/// `wq`: its confidence; `r_q`: its radius, metres). Mirrors `merged_surfel` in
/// common.wgsl; `fuse_merge` and `fuse_merge_chosen` share it.
#[allow(clippy::too_many_arguments)] // the shader function's arguments, in order
#[inline]
pub fn merged_surfel(
    pw: [f32; 4],
    n_old: Vec3,
    c: [f32; 4],
    q_world: Vec3,
    nq_world: Vec3,
    cq: Vec3,
    wq: f32,
    r_q: f32,
) -> MergedSurfel {
    if arith::merge_skipped(pw) {
        return MergedSurfel {
            position_weight: pw,
            normal: n_old,
            color: c,
        };
    }
    let w = pw[3];
    let inv = arith::div(1.0, w + wq);
    let p = (xyz(pw) * w + q_world * wq) * inv;
    let n = normalize_or_zero((n_old * w + nq_world * wq) * inv);
    let r = (c[3] * w + r_q * wq) * inv;
    let rgb = (xyz(c) * w + cq * wq) * inv;
    MergedSurfel {
        position_weight: [p.x, p.y, p.z, w + wq],
        normal: n,
        color: [rgb.x, rgb.y, rgb.z, r],
    }
}

/// Radius (metres) of the disc a pixel's measurement covers (camera frame `q_cam`,
/// `n_cam`; `focal_px` = fx). Mirrors `surfel_radius` in common.wgsl, which says why.
#[inline]
pub fn surfel_radius(focal_px: f32, q_cam: Vec3, n_cam: Vec3) -> f32 {
    let footprint = arith::div(std::f32::consts::SQRT_2 * q_cam.z, focal_px);
    let cos_view = arith::div(arith::dot(n_cam, q_cam).abs(), arith::length(q_cam));
    footprint / cos_view.max(0.5)
}

/// Confidence of the measurement at pixel `texel` (1 at the principal point, a Gaussian
/// of standard deviation `sigma` over the distance normalised to 1 at the corners; 1
/// everywhere when `sigma` is 0). Mirrors `pixel_confidence` in common.wgsl.
#[inline]
pub fn pixel_confidence(cam: [f32; 4], texel: [u32; 2], sigma: f32) -> f32 {
    if sigma <= 0.0 {
        return 1.0;
    }
    let d = glam::Vec2::new(texel[0] as f32 - cam[2], texel[1] as f32 - cam[3])
        / glam::Vec2::new(cam[2], cam[3]).length();
    (-d.dot(d) / (2.0 * sigma * sigma)).exp()
}

/// True when `(d, i)` beats `(best_d, best_i)`: closer, or as close with a lower index
/// (scan nearest neighbours). Mirrors `scan_closer` in common.wgsl.
#[inline]
pub fn scan_closer(d: f32, i: u32, best_d: f32, best_i: u32) -> bool {
    d < best_d || (d == best_d && i < best_i)
}

/// Squared distance of the xyz parts, written out as the shader does (`x*x + y*y + z*z` of
/// the difference). Mirrors `scan_dist_sq` in common.wgsl.
#[inline]
pub fn scan_dist_sq(a: [f32; 4], b: [f32; 4]) -> f32 {
    let (dx, dy, dz) = (a[0] - b[0], a[1] - b[1], a[2] - b[2]);
    dx * dx + dy * dy + dz * dz
}
