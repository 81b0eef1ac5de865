//! The picture files `wgslam run` and `wgslam icp --out` write: map renders from the
//! default viewpoint and from the last camera, and before/after ICP overlays.
//!
//! Thin glue over [`super`]: it picks viewpoints and file names and writes PNGs; it draws
//! nothing itself and computes no metric.

use std::path::{Path, PathBuf};

use glam::{DMat4, DVec3};

use super::{
    default_camera, framing_camera, render_overlay, trajectory_view_hint, write_png, MapCloud,
    RenderBackend, RenderCamera, RenderSettings, View, DEFAULT_SIZE,
};
use crate::geometry::camera::Intrinsics;
use crate::layout::map::SurfelMap;
use crate::{Error, Result};

/// Up and heading for the default view of a map without a trajectory: up is `up`, the
/// heading is against the mean surfel normal (surfels face the cameras that saw them, so
/// this looks the way the cameras looked), or any horizontal direction without normals.
pub fn map_view_hint(normals: Option<&[[f32; 4]]>, up: DVec3) -> (DVec3, DVec3) {
    let mean = normals
        .map(|ns| {
            ns.iter()
                .filter(|n| n[0].is_finite() && n[1].is_finite() && n[2].is_finite())
                .fold(DVec3::ZERO, |acc, n| {
                    acc + DVec3::new(n[0] as f64, n[1] as f64, n[2] as f64)
                })
        })
        .unwrap_or(DVec3::ZERO);
    (up, -mean)
}

/// Writes the map renders of a run into `out_dir` and returns their paths:
/// The default viewpoint of `map_*.png`: a camera of `size` framing the whole map, looking
/// down along the cameras' mean heading (`trajectory`: `t_cam_to_world` poses; the sign of
/// `intrinsics.fy` fixes the handedness, as in [`write_map_renders`]).
pub fn overview_camera(
    map: &SurfelMap,
    trajectory: &[(f64, DMat4)],
    intrinsics: &Intrinsics,
    size: (u32, u32),
) -> Result<RenderCamera> {
    let fy_negative = intrinsics.fy < 0.0;
    let poses: Vec<DMat4> = trajectory.iter().map(|(_, t)| *t).collect();
    let image_up = if fy_negative { DVec3::Y } else { DVec3::NEG_Y };
    let (up, heading) = trajectory_view_hint(&poses, intrinsics.fy)
        .unwrap_or_else(|| map_view_hint(MapCloud::new(map).cloud().normals, image_up));
    default_camera(
        &map.position_weight,
        size.0,
        size.1,
        up,
        heading,
        fy_negative,
    )
}

/// `map_color.png` and `map_normals.png` from the default viewpoint (framing the whole map,
/// looking down along the cameras' mean heading), and `last_camera_color.png` and
/// `last_camera_normals.png` from the last pose of `trajectory` with the run's
/// `intrinsics` (`t_cam_to_world` poses, metres; `intrinsics` of the tracked images, whose
/// `fy` sign also fixes the handedness of the default view). `size`: of the default view.
pub fn write_map_renders(
    backend: &RenderBackend,
    out_dir: &Path,
    map: &SurfelMap,
    trajectory: &[(f64, DMat4)],
    intrinsics: &Intrinsics,
    size: (u32, u32),
) -> Result<Vec<PathBuf>> {
    if map.is_empty() {
        return Err(Error::Argument(
            "the map is empty: nothing to render".into(),
        ));
    }
    let map_cloud = MapCloud::new(map);
    let cloud = map_cloud.cloud();
    let settings = RenderSettings::default();
    let overview = overview_camera(map, trajectory, intrinsics, size)?;
    let mut cameras = vec![("map", overview)];
    if let Some((_, last)) = trajectory.last() {
        cameras.push((
            "last_camera",
            RenderCamera {
                t_cam_to_world: *last,
                intrinsics: *intrinsics,
            },
        ));
    }
    let mut written = Vec::new();
    for (name, camera) in &cameras {
        for view in [View::Color, View::Normals] {
            let path = out_dir.join(format!("{name}_{}.png", view.name()));
            write_png(&path, &backend.render(&cloud, camera, view, &settings)?)?;
            written.push(path);
        }
    }
    Ok(written)
}

/// Where an overlay is seen from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum OverlayViewpoint {
    /// Roughly the target camera's own view (looking along +z of the target frame), backed
    /// off to frame both clouds; `fy_negative` is the dataset's convention (ICL-NUIM: true).
    Camera { fy_negative: bool },
    /// Straight down onto the plane normal to `up` (LiDAR scans: `up = +z`).
    TopDown { up: DVec3 },
}

/// Writes `icp_before.png` (source moved by `t_initial`) and `icp_after.png` (moved by
/// `t_estimate`) into `out_dir`: target in blue, source in orange, both from the same
/// camera framing the target and both placements of the source. Points are in their own
/// frames (metres, `w <= 0` skipped); poses are source to target. Returns the two paths.
pub fn write_icp_overlays(
    out_dir: &Path,
    source_pts: &[[f32; 4]],
    target_pts: &[[f32; 4]],
    t_initial: &DMat4,
    t_estimate: &DMat4,
    viewpoint: OverlayViewpoint,
) -> Result<[PathBuf; 2]> {
    let (forward, up, fy_negative) = match viewpoint {
        OverlayViewpoint::Camera { fy_negative } => (
            DVec3::Z,
            if fy_negative { DVec3::Y } else { DVec3::NEG_Y },
            fy_negative,
        ),
        OverlayViewpoint::TopDown { up } => (-up, up.any_orthonormal_vector(), false),
    };
    // Frame everything either picture shows: the target and both placements of the source.
    let (before, _) = super::overlay_cloud(source_pts, target_pts, t_initial);
    let (after, _) = super::overlay_cloud(source_pts, &[], t_estimate);
    let all: Vec<[f32; 4]> = before.into_iter().chain(after).collect();
    let camera = framing_camera(
        &all,
        DEFAULT_SIZE.0,
        DEFAULT_SIZE.1,
        forward,
        up,
        fy_negative,
    )?;
    let settings = RenderSettings {
        cull_backfaces: false,
        // Sparse clouds (LiDAR) seen from afar: at least a 3-pixel cross per point.
        min_radius_px: 1.0,
        // Two clouds whose alignment is judged point by point: no filling between them.
        fill_gap_px: 0,
        ..RenderSettings::default()
    };
    let paths = [
        out_dir.join("icp_before.png"),
        out_dir.join("icp_after.png"),
    ];
    for (path, t) in paths.iter().zip([t_initial, t_estimate]) {
        let img = render_overlay(source_pts, target_pts, t, &camera, &settings)?;
        write_png(path, &img)?;
    }
    Ok(paths)
}
