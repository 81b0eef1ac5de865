//! CPU twins of the WGSL kernels: pure functions over typed slices, no wgpu.
//!
//! `src/cpu/<kernel>.rs` mirrors `shaders/<kernel>.wgsl` one to one: same arguments in the
//! shader's `@binding(i)` order, same loop structure, same helper names (the helpers shared
//! by several kernels live here and in `shaders/common.wgsl`). The per-pixel maths is the
//! same on both sides; only the reductions differ (f64 sums here, f32 workgroup partials
//! summed in f64 on the host for the GPU).

pub mod cross_covariance;
pub mod depth_to_vertex;
pub mod fuse_add;
pub mod fuse_merge;
pub mod icp_reduce;
pub mod nn_brute;
pub mod nn_grid;
pub mod predict_model;
pub mod project_model;
pub mod render_resolve;
pub mod render_splat;
pub mod vertex_to_normal;

use glam::{Mat4, Vec3, Vec4};

use crate::layout::GpuMat4;

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

/// Filter 1: the pixel index a camera-frame point projects to, rounding to the nearest
/// pixel centre, or `None` when it is behind the camera (`z <= 0`) or outside the image.
/// Mirrors `project_to_pixel` in common.wgsl (which returns -1 for `None`).
#[inline]
pub fn project_to_pixel(cam: [f32; 4], width: u32, height: u32, p: Vec3) -> Option<usize> {
    if p.z <= 0.0 {
        return None;
    }
    let u = (cam[0] * p.x / p.z + cam[2] + 0.5).floor();
    let v = (cam[1] * p.y / p.z + cam[3] + 0.5).floor();
    if u < 0.0 || v < 0.0 || u >= width as f32 || v >= height as f32 {
        return None;
    }
    Some(v as usize * width as usize + u as usize)
}

/// xyz of a `vec4` map entry.
#[inline]
pub fn xyz(v: [f32; 4]) -> Vec3 {
    Vec3::new(v[0], v[1], v[2])
}

/// A map entry is valid when its `w` is positive (vertex and normal maps use w = 1 / 0).
#[inline]
pub fn is_valid(v: [f32; 4]) -> bool {
    v[3] > 0.0
}

/// Packs a valid point or direction back into a map entry (w = 1).
#[inline]
pub fn valid_entry(p: Vec3) -> [f32; 4] {
    Vec4::new(p.x, p.y, p.z, 1.0).to_array()
}

/// The invalid map entry.
pub const INVALID: [f32; 4] = [0.0; 4];
