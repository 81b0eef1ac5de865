//! An orbit camera for interactive viewers (the browser page, `src/web`): a user's turn,
//! tilt, zoom and pan applied to a base camera (one that frames the map, e.g.
//! [`super::outputs::overview_camera`]) around a target point the base camera looks at.
//!
//! Not a camera controller: no inertia, limits or input handling; the page maps mouse and
//! touch to these numbers.

use glam::{DMat4, DQuat, DVec3};

use super::RenderCamera;

/// What the user did to the view, relative to the base camera.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Orbit {
    /// Turn around the base camera's image-up axis through the target, radians.
    pub yaw_rad: f64,
    /// Tilt around the base camera's image-right axis through the target, radians.
    pub pitch_rad: f64,
    /// Distance to the target as a multiple of the base camera's (> 0; below 1 is closer).
    pub zoom: f64,
    /// Shift of camera and target along the turned camera's image right and image up, in
    /// units of the camera's distance to the target.
    pub pan: [f64; 2],
}

impl Default for Orbit {
    fn default() -> Self {
        Orbit {
            yaw_rad: 0.0,
            pitch_rad: 0.0,
            zoom: 1.0,
            pan: [0.0, 0.0],
        }
    }
}

impl Orbit {
    /// The base camera moved by this orbit around `target` (world frame, metres): position
    /// and orientation turned together, so a target on the base camera's optical axis stays
    /// on the new one's. `base` has `fy > 0` (camera x right, y down, z ahead). A
    /// non-positive or non-finite zoom counts as 1.
    pub fn apply(&self, base: &RenderCamera, target: DVec3) -> RenderCamera {
        let t = base.t_cam_to_world;
        let right = t.x_axis.truncate();
        let up = -t.y_axis.truncate();
        let position = t.w_axis.truncate();
        let turn = DQuat::from_axis_angle(up, self.yaw_rad)
            * DQuat::from_axis_angle(right, self.pitch_rad);
        let zoom = if self.zoom.is_finite() && self.zoom > 0.0 {
            self.zoom
        } else {
            1.0
        };
        let offset = (position - target) * zoom;
        let distance = offset.length();
        let pan = turn * (right * self.pan[0] + up * self.pan[1]) * distance;
        let (_, rotation, _) = t.to_scale_rotation_translation();
        let t_cam_to_world =
            DMat4::from_rotation_translation(turn * rotation, target + pan + turn * offset);
        RenderCamera {
            t_cam_to_world,
            intrinsics: base.intrinsics,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::camera::Intrinsics;

    /// Rounding of a few f64 rotations: far below anything a pixel shows.
    const POSE_EPS: f64 = 1e-9;

    fn base() -> (RenderCamera, DVec3) {
        // At (0, 0, -2) looking along +z at the origin, image y down (world -y up).
        let t = DMat4::from_translation(DVec3::new(0.0, 0.0, -2.0));
        let cam = RenderCamera {
            t_cam_to_world: t,
            intrinsics: Intrinsics::ICL_NUIM,
        };
        (cam, DVec3::ZERO)
    }

    #[test]
    fn no_orbit_is_the_base_camera() {
        let (cam, target) = base();
        let out = Orbit::default().apply(&cam, target);
        assert!(out.t_cam_to_world.abs_diff_eq(cam.t_cam_to_world, POSE_EPS));
    }

    #[test]
    fn turning_keeps_the_target_ahead_at_the_same_distance() {
        let (cam, target) = base();
        let orbit = Orbit {
            yaw_rad: 0.7,
            pitch_rad: -0.3,
            zoom: 0.5,
            pan: [0.0, 0.0],
        };
        let out = orbit.apply(&cam, target).t_cam_to_world;
        let position = out.w_axis.truncate();
        assert!((position.length() - 1.0).abs() < POSE_EPS, "{position}");
        // The target in the new camera's frame lies on its optical axis (+z), 1 m ahead.
        let in_cam = out.inverse().transform_point3(target);
        assert!(
            in_cam.abs_diff_eq(DVec3::new(0.0, 0.0, 1.0), POSE_EPS),
            "{in_cam}"
        );
        // A quarter turn of yaw puts the camera on the x axis.
        let quarter = Orbit {
            yaw_rad: std::f64::consts::FRAC_PI_2,
            ..Orbit::default()
        };
        let p = quarter.apply(&cam, target).t_cam_to_world.w_axis.truncate();
        assert!(
            (p.x.abs() - 2.0).abs() < POSE_EPS && p.z.abs() < POSE_EPS,
            "{p}"
        );
    }

    #[test]
    fn panning_moves_along_the_image_axes() {
        let (cam, target) = base();
        let orbit = Orbit {
            pan: [0.5, 0.25],
            ..Orbit::default()
        };
        let p = orbit.apply(&cam, target).t_cam_to_world.w_axis.truncate();
        // Right is +x, image up is -y; units of the 2 m distance.
        assert!(p.abs_diff_eq(DVec3::new(1.0, -0.5, -2.0), POSE_EPS), "{p}");
    }
}
