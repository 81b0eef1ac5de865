//! Virtual cameras that frame a cloud: a pinhole camera with a fixed field of view,
//! placed along a viewing direction at the distance that fits the cloud's robust bounds,
//! and the default viewpoint of a run's map (above and behind the trajectory's mean
//! heading). Poses are camera-to-world, metres; see the module header of `render` for the
//! sign of `fy`.

use glam::{DMat3, DMat4, DVec3};

use super::view::check_size;
use super::RenderCamera;
use crate::geometry::camera::Intrinsics;
use crate::geometry::se3;
use crate::{Error, Result};

/// Horizontal field of view of framing cameras, degrees.
pub const FRAMING_FOV_DEG: f64 = 60.0;
/// Elevation of the default viewpoint above the horizontal, degrees.
pub const DEFAULT_ELEVATION_DEG: f64 = 35.0;
/// Fraction of points ignored at each end of every axis when framing (stray surfels far
/// from the scene would otherwise shrink it to a dot).
pub const FRAMING_OUTLIER_FRACTION: f64 = 0.005;
/// Extra distance of a framing camera, as a fraction of the framed extent (a border).
pub const FRAMING_MARGIN: f64 = 0.08;

/// Intrinsics of a framing camera: `width` x `height`, [`FRAMING_FOV_DEG`] horizontally,
/// square pixels, `fy` negative when `fy_negative` (see [`look_rotation`]).
pub fn framing_intrinsics(width: u32, height: u32, fy_negative: bool) -> Intrinsics {
    let f = 0.5 * width as f64 / (0.5 * FRAMING_FOV_DEG.to_radians()).tan();
    Intrinsics {
        width,
        height,
        fx: f as f32,
        fy: if fy_negative { -f as f32 } else { f as f32 },
        cx: (width as f32 - 1.0) * 0.5,
        cy: (height as f32 - 1.0) * 0.5,
    }
}

/// Camera-to-world rotation of a camera looking along `forward` (camera z) with `up` up in
/// the image and x to the right. With `fy > 0` image up is camera -y; with `fy < 0` (the
/// ICL-NUIM convention) it is +y. Datasets differ in handedness, so a virtual camera takes
/// the sign of its dataset's `fy`: the other sign would show the scene mirrored.
/// `None` when the two directions are parallel or not finite.
pub fn look_rotation(forward: DVec3, up: DVec3, fy_negative: bool) -> Option<DMat3> {
    let z = forward.try_normalize()?;
    let up_ortho = (up - z * up.dot(z)).try_normalize()?;
    let y = if fy_negative { up_ortho } else { -up_ortho };
    let x = y.cross(z);
    Some(DMat3::from_cols(x, y, z))
}

/// Robust axis-aligned bounds of the finite points: the [`FRAMING_OUTLIER_FRACTION`] and
/// `1 - FRAMING_OUTLIER_FRACTION` quantiles per axis. `None` without finite points.
pub fn robust_bounds(positions: &[[f32; 4]]) -> Option<(DVec3, DVec3)> {
    let mut axes: [Vec<f32>; 3] = Default::default();
    for p in positions {
        if p[0].is_finite() && p[1].is_finite() && p[2].is_finite() {
            for (a, axis) in axes.iter_mut().enumerate() {
                axis.push(p[a]);
            }
        }
    }
    let n = axes[0].len();
    if n == 0 {
        return None;
    }
    let lo_i = ((n - 1) as f64 * FRAMING_OUTLIER_FRACTION).floor() as usize;
    let hi_i = ((n - 1) as f64 * (1.0 - FRAMING_OUTLIER_FRACTION)).ceil() as usize;
    let mut lo = [0.0f64; 3];
    let mut hi = [0.0f64; 3];
    for (a, axis) in axes.iter_mut().enumerate() {
        lo[a] = *axis.select_nth_unstable_by(lo_i, f32::total_cmp).1 as f64;
        hi[a] = *axis.select_nth_unstable_by(hi_i, f32::total_cmp).1 as f64;
    }
    Some((DVec3::from(lo), DVec3::from(hi)))
}

/// A camera of `width` x `height` looking along `forward` (with `up` up in the image) that
/// frames the robust bounds of `positions` (taken in the view's own axes): centred on them,
/// and as close as it can be while each point inside them stays in the picture. `fy_negative`:
/// the sign convention of the data's camera (see [`look_rotation`]).
pub fn framing_camera(
    positions: &[[f32; 4]],
    width: u32,
    height: u32,
    forward: DVec3,
    up: DVec3,
    fy_negative: bool,
) -> Result<RenderCamera> {
    check_size(width, height)?;
    let rot = look_rotation(forward, up, fy_negative)
        .ok_or_else(|| Error::Argument("view direction and up direction are parallel".into()))?;
    let k = framing_intrinsics(width, height, fy_negative);
    // Work in view-aligned coordinates (q = Rᵀ p: x right, y along the image's vertical, z
    // ahead), where framing is a 2-D fit.
    let rot_t = rot.transpose();
    let view_pts: Vec<[f32; 4]> = positions
        .iter()
        .map(|p| {
            let q = rot_t * DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64);
            [q.x as f32, q.y as f32, q.z as f32, 1.0]
        })
        .collect();
    let (lo, hi) = robust_bounds(&view_pts)
        .ok_or_else(|| Error::Argument("the cloud has no finite point to frame".into()))?;
    let (cx, cy) = ((lo.x + hi.x) * 0.5, (lo.y + hi.y) * 0.5);
    let tan_x = 0.5 * width as f64 / k.fx as f64;
    let tan_y = 0.5 * height as f64 / k.fy.abs() as f64;
    // The camera sits on the line through (cx, cy) along z, as far forward as it can while
    // every point inside the robust bounds stays in the picture.
    let inside = |q: &DVec3| q.cmpge(lo).all() && q.cmple(hi).all();
    let z_cam = view_pts
        .iter()
        .map(|q| DVec3::new(q[0] as f64, q[1] as f64, q[2] as f64))
        .filter(inside)
        .map(|q| q.z - ((q.x - cx).abs() / tan_x).max((q.y - cy).abs() / tan_y))
        .fold(f64::INFINITY, f64::min);
    // A small margin around the picture, and never closer than 5 cm to the nearest point.
    let margin = FRAMING_MARGIN * (hi - lo).max_element().max(0.05);
    let z_cam = z_cam.min(lo.z - 0.05) - margin;
    let eye = rot * DVec3::new(cx, cy, z_cam);
    Ok(RenderCamera {
        t_cam_to_world: se3::from_rt(rot, eye),
        intrinsics: k,
    })
}

/// The default viewpoint on a map: looking down at [`DEFAULT_ELEVATION_DEG`] with `up` as
/// the world's up direction, along `heading` (a horizontal direction; any direction is
/// projected onto the horizontal plane), framing the whole map. `fy_negative`: the sign
/// convention of the data's camera (see [`look_rotation`]).
pub fn default_camera(
    positions: &[[f32; 4]],
    width: u32,
    height: u32,
    up: DVec3,
    heading: DVec3,
    fy_negative: bool,
) -> Result<RenderCamera> {
    let up = up
        .try_normalize()
        .ok_or_else(|| Error::Argument("the up direction is zero".into()))?;
    let mut h = heading - up * heading.dot(up);
    if h.length() < 1e-9 {
        // Any horizontal direction will do; pick one from the world axes.
        h = up.any_orthonormal_vector();
    }
    let h = h.normalize();
    let e = DEFAULT_ELEVATION_DEG.to_radians();
    let forward = h * e.cos() - up * e.sin();
    framing_camera(positions, width, height, forward, up, fy_negative)
}

/// Up and heading of a trajectory's cameras (`t_cam_to_world` with the dataset intrinsics'
/// sign of `fy`): the mean image-up direction and the mean viewing direction, for
/// [`default_camera`]. `None` for an empty trajectory or when the means cancel out.
pub fn trajectory_view_hint(poses: &[DMat4], fy: f32) -> Option<(DVec3, DVec3)> {
    // Image up is camera -y when fy > 0 (v grows downwards), +y when fy < 0.
    let up_cam = if fy < 0.0 { DVec3::Y } else { DVec3::NEG_Y };
    let mut up = DVec3::ZERO;
    let mut fwd = DVec3::ZERO;
    for t in poses {
        up += t.transform_vector3(up_cam);
        fwd += t.transform_vector3(DVec3::Z);
    }
    Some((up.try_normalize()?, fwd.try_normalize()?))
}
