//! The layout contract of the render kernels: `RenderParams`, shared by `render_splat` and
//! `render_resolve`.
//!
//! `#[repr(C)]` + `bytemuck::Pod`, only scalars, a 4x4 matrix and the nested
//! `layout::Camera`, padded to 16 bytes; it mirrors `struct RenderParams` in
//! `shaders/common.wgsl`, which both render kernels are prefixed with (it points back
//! here). `tests/it/render/gpu.rs` checks its size and offsets against naga's layout of the
//! WGSL side.

use bytemuck::{Pod, Zeroable};

use crate::layout::{Camera, GpuMat4};

/// `RenderParams::view`: shade with the surfel colour (RGB 0..255).
pub const VIEW_COLOR: u32 = 0;
/// `RenderParams::view`: shade with the world-frame normal, `(n + 1) / 2` as RGB.
pub const VIEW_NORMALS: u32 = 1;
/// `RenderParams::view`: shade with `weight / weight_max` through a dark-blue-to-yellow ramp.
pub const VIEW_WEIGHT: u32 = 2;
/// `RenderParams::view`: shade with the camera depth, `near_m` (yellow) to `far_m` (dark blue).
pub const VIEW_DEPTH: u32 = 3;

/// Parameters of `render_splat` and `render_resolve` (mirrors `RenderParams` in WGSL).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct RenderParams {
    /// World to camera of the rendered view (camera: x right, y down when `fy > 0`, z ahead).
    pub t_world_to_cam: GpuMat4,
    /// Intrinsics and size of the output image, pixels (`fy` may be negative).
    pub camera: Camera,
    /// Number of surfels drawn (entries past it are ignored).
    pub surfel_count: u32,
    /// One of `VIEW_COLOR`, `VIEW_NORMALS`, `VIEW_WEIGHT`, `VIEW_DEPTH`.
    pub view: u32,
    /// World radius of a splat in metres; its pixel radius is `splat_radius_m * max(|fx|, |fy|) / z` (the camera's).
    pub splat_radius_m: f32,
    /// Pixel radius is clamped to `[min_radius_px, max_radius_px]`.
    pub min_radius_px: f32,
    pub max_radius_px: f32,
    /// 1: skip surfels whose normal faces away from the camera (`n_cam . p_cam > 0`).
    pub cull_backfaces: u32,
    /// Surfels with camera depth outside `(near_m, far_m]` (metres) are not drawn; the depth
    /// view maps this range to its colour ramp.
    pub near_m: f32,
    pub far_m: f32,
    /// Weight shown at the top of the weight ramp (the map's largest weight).
    pub weight_max: f32,
    /// Background colour, `r | g << 8 | b << 16 | 255 << 24`.
    pub background: u32,
    /// `render_resolve` fills an empty pixel from the nearer of two covered pixels at most
    /// this many pixels away on opposite sides (up/down or left/right) whose depths agree
    /// (the gaps between rows of surfels seen at a grazing angle); 0 fills nothing.
    pub fill_gap_px: u32,
    /// Padding to a multiple of 16 bytes (mirrors `_pad0` in WGSL).
    pub _pad0: u32,
}
