//! CPU twins of the WGSL kernels: pure functions over typed slices, no wgpu.
//!
//! `src/cpu/<kernel>.rs` mirrors `shaders/<kernel>.wgsl` one to one: same arguments in the
//! shader's `@binding(i)` order and in the same packed representation (the frame's
//! `normal_depth` texels, the surfel map's three packed arrays of [`crate::slam::map::SurfelMap`]),
//! same loop structure, same helper names. This module holds the one Rust twin of every
//! helper in `shaders/common.wgsl`, each under the same name; kernel-local helpers live in
//! the kernel's file on both sides. The per-pixel maths is the same on both sides; only the
//! reductions differ (f64 sums here, f32 workgroup partials summed in f64 on the host for
//! the GPU).
//!
//! Textures become row-major slices: texel `(u, v)` of a `width`-wide map is element
//! `v * width + u`, and surfel `i` of a map texture is element `i` ([`surfel_texel`]).

pub mod bilateral_filter;
pub mod compact_flags;
pub mod compact_scatter;
pub mod cross_covariance;
pub mod depth_to_vertex;
pub mod fuse_add;
pub mod fuse_flags;
pub mod fuse_merge;
pub mod fuse_select;
pub mod icp_reduce;
pub mod icp_reduce_final;
pub mod nn_brute;
pub mod nn_grid;
pub mod predict_model;
pub mod prefix_sum;
pub mod project_model;
pub mod pyramid_depth;
pub mod pyramid_model;
pub mod render_resolve;
pub mod render_splat;
pub mod vertex_to_normal;

use glam::{Mat4, Vec3, Vec4};

use crate::layout::GpuMat4;

/// The element of surfel `i` in a packed map array. The GPU stores surfel `i` at texel
/// `(i % MAP_TEXTURE_WIDTH, i / MAP_TEXTURE_WIDTH)` of each map texture; read back
/// row-major, that texel is element `i`. Mirrors `surfel_texel` in common.wgsl.
#[inline]
pub fn surfel_texel(i: u32) -> usize {
    i as usize
}

/// The invalid map entry. Mirrors `INVALID` in common.wgsl.
pub const INVALID: [f32; 4] = [0.0; 4];

/// `T p` for a point (w = 1). Mirrors `transform_point` in common.wgsl.
#[inline]
pub fn transform_point(t: &GpuMat4, p: Vec3) -> Vec3 {
    (Mat4::from_cols_array_2d(t) * p.extend(1.0)).truncate()
}

/// `R n` for a direction (w = 0). Mirrors `transform_dir` in common.wgsl.
#[inline]
pub fn transform_dir(t: &GpuMat4, n: Vec3) -> Vec3 {
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
    let u = (cam[0] * p.x / p.z + cam[2] + 0.5).floor();
    let v = (cam[1] * p.y / p.z + cam[3] + 0.5).floor();
    if u < 0.0 || v < 0.0 || u >= width as f32 || v >= height as f32 {
        return None;
    }
    Some([u as u32, v as u32])
}

/// The camera-frame point (metres) of pixel `texel = (u, v)` at depth `z` (metres),
/// `((u - cx) z / fx, (v - cy) z / fy, z)` with `cam` = `(fx, fy, cx, cy)` as given (a
/// negative `fy` stays negative). `depth_to_vertex` makes the vertex map with it, and every
/// twin that rebuilds a vertex from a `normal_depth` texel calls it again, so the bits
/// match. Mirrors `back_project` in common.wgsl.
#[inline]
pub fn back_project(cam: [f32; 4], texel: [u32; 2], z: f32) -> Vec3 {
    let x = (texel[0] as f32 - cam[2]) * z / cam[0];
    let y = (texel[1] as f32 - cam[3]) * z / cam[1];
    Vec3::new(x, y, z)
}

/// xyz of a `vec4` map entry. Mirrors `xyz` in common.wgsl.
#[inline]
pub fn xyz(v: [f32; 4]) -> Vec3 {
    Vec3::new(v[0], v[1], v[2])
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

/// Packs a camera depth (metres, > 0) and a surfel index into an index-map key:
/// `(!bits(z_cam) as u64) << 32 | surfel`. The larger key is the nearer surfel (for positive
/// floats the bit pattern grows with the value, so its complement shrinks), ties go to the
/// larger index, and 0 means no surfel. Mirrors `pack_depth_index` in common.wgsl.
#[inline]
pub fn pack_depth_index(z_cam: f32, surfel: u32) -> u64 {
    ((!z_cam.to_bits()) as u64) << 32 | surfel as u64
}

/// Radius (metres) of the disc a pixel's measurement covers (camera frame `q_cam`,
/// `n_cam`; `focal_px` = fx). Mirrors `surfel_radius` in common.wgsl, which says why.
#[inline]
pub fn surfel_radius(focal_px: f32, q_cam: Vec3, n_cam: Vec3) -> f32 {
    let footprint = std::f32::consts::SQRT_2 * q_cam.z / focal_px;
    let cos_view = n_cam.dot(q_cam).abs() / q_cam.length();
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
