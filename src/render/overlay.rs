//! Before/after overlays of two ICP point clouds: the target in blue, the source moved by
//! an estimate in orange, drawn as one cloud with the CPU renderer.

use glam::{DMat4, DVec3};
use image::RgbImage;

use super::framing::framing_camera;
use super::{render_cpu, Cloud, RenderCamera, RenderSettings, View};
use crate::layout::gpu_mat4;
use crate::Result;

/// Colour of the source cloud in overlays (orange), RGB.
pub const SOURCE_RGB: [u8; 3] = [245, 130, 32];
/// Colour of the target cloud in overlays (blue), RGB.
pub const TARGET_RGB: [u8; 3] = [40, 110, 230];

/// Renders the before/after picture of two clouds: `target_pts` as they are and
/// `source_pts` moved by `t_source_to_target`, in [`TARGET_RGB`] and [`SOURCE_RGB`], from
/// `camera` (positions in the target frame, metres; `w` ignored). No back-face culling.
pub fn render_overlay(
    source_pts: &[[f32; 4]],
    target_pts: &[[f32; 4]],
    t_source_to_target: &DMat4,
    camera: &RenderCamera,
    settings: &RenderSettings,
) -> Result<RgbImage> {
    let (positions, colors) = overlay_cloud(source_pts, target_pts, t_source_to_target);
    let cloud = Cloud {
        positions: &positions,
        normals: None,
        colors: Some(&colors),
        weights: None,
    };
    render_cpu(&cloud, camera, View::Color, settings)
}

/// The merged overlay cloud: target points first, then the moved source points, with their
/// colours. Entries with `w <= 0` (invalid vertex-map pixels) are skipped.
pub fn overlay_cloud(
    source_pts: &[[f32; 4]],
    target_pts: &[[f32; 4]],
    t_source_to_target: &DMat4,
) -> (Vec<[f32; 4]>, Vec<[f32; 4]>) {
    let t = gpu_mat4(t_source_to_target);
    let mut positions = Vec::with_capacity(source_pts.len() + target_pts.len());
    let mut colors = Vec::with_capacity(positions.capacity());
    let rgb = |c: [u8; 3]| [c[0] as f32, c[1] as f32, c[2] as f32, 255.0];
    for p in target_pts.iter().filter(|p| p[3] > 0.0) {
        positions.push([p[0], p[1], p[2], 1.0]);
        colors.push(rgb(TARGET_RGB));
    }
    for p in source_pts.iter().filter(|p| p[3] > 0.0) {
        let q = crate::cpu::transform_point(&t, crate::cpu::xyz(*p));
        positions.push([q.x, q.y, q.z, 1.0]);
        colors.push(rgb(SOURCE_RGB));
    }
    (positions, colors)
}

/// A camera framing both clouds of an overlay (target frame), looking along `forward` with
/// `up` up. For an RGB-D pair, `forward = +z`, `up = -y` (or `+y` with `fy_negative` when
/// the dataset's `fy` is negative) shows them roughly as the target camera saw them.
pub fn overlay_camera(
    source_pts: &[[f32; 4]],
    target_pts: &[[f32; 4]],
    t_source_to_target: &DMat4,
    size: (u32, u32),
    forward: DVec3,
    up: DVec3,
    fy_negative: bool,
) -> Result<RenderCamera> {
    let (positions, _) = overlay_cloud(source_pts, target_pts, t_source_to_target);
    framing_camera(&positions, size.0, size.1, forward, up, fy_negative)
}
