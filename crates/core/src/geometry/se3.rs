//! Rigid transforms in SE(3): exponential and logarithm maps, and conversions.
//!
//! Poses are `glam::DMat4` (f64, column-major, homogeneous) and are named for what they map:
//! `t_cam_to_world` takes a point in camera coordinates (metres) to world coordinates.
//! A twist `x = (alpha, beta, gamma, tx, ty, tz)` is rotation (radians, axis-angle) first,
//! then translation (metres), matching the ICP unknown vector.

use glam::{DMat3, DMat4, DQuat, DVec3};

/// 6-vector twist: `[alpha, beta, gamma, tx, ty, tz]` (radians, metres).
pub type Twist = [f64; 6];

/// Skew-symmetric matrix `[w]x` with `[w]x v = w x v`.
pub fn hat(w: DVec3) -> DMat3 {
    DMat3::from_cols(
        DVec3::new(0.0, w.z, -w.y),
        DVec3::new(-w.z, 0.0, w.x),
        DVec3::new(w.y, -w.x, 0.0),
    )
}

/// SE(3) exponential of a twist `(w, v)`: rotation `exp([w]x)` and translation `V v`.
pub fn exp(x: &Twist) -> DMat4 {
    let w = DVec3::new(x[0], x[1], x[2]);
    let v = DVec3::new(x[3], x[4], x[5]);
    let theta = w.length();
    let k = hat(w);
    let k2 = k * k;
    // Taylor expansions below 1e-8 rad keep full f64 precision.
    let (a, b, c) = if theta < 1e-8 {
        (
            1.0 - theta * theta / 6.0,
            0.5 - theta * theta / 24.0,
            1.0 / 6.0,
        )
    } else {
        let t2 = theta * theta;
        (
            theta.sin() / theta,
            (1.0 - theta.cos()) / t2,
            (theta - theta.sin()) / (t2 * theta),
        )
    };
    let r = DMat3::IDENTITY + k * a + k2 * b;
    let vm = DMat3::IDENTITY + k * b + k2 * c;
    from_rt(r, vm * v)
}

/// SE(3) logarithm: the twist whose [`exp`] is `t` (rotation angle in [0, pi]).
pub fn log(t: &DMat4) -> Twist {
    let (r, p) = to_rt(t);
    let mut q = DQuat::from_mat3(&r).normalize();
    if q.w < 0.0 {
        q = -q;
    }
    // Rotation vector 2 atan2(|v|, w) v/|v|, which stays accurate for tiny angles.
    let v = DVec3::new(q.x, q.y, q.z);
    let s = v.length();
    let w = if s < 1e-12 {
        v * (2.0 / q.w)
    } else {
        v * (2.0 * s.atan2(q.w) / s)
    };
    let theta = w.length();
    let k = hat(w);
    let k2 = k * k;
    let vinv = if theta < 1e-8 {
        DMat3::IDENTITY - k * 0.5 + k2 * (1.0 / 12.0)
    } else {
        let half = 0.5 * theta;
        let coef = (1.0 - half * half.cos() / half.sin()) / (theta * theta);
        DMat3::IDENTITY - k * 0.5 + k2 * coef
    };
    let v = vinv * p;
    [w.x, w.y, w.z, v.x, v.y, v.z]
}

/// Builds a homogeneous transform from rotation `r` and translation `t`.
pub fn from_rt(r: DMat3, t: DVec3) -> DMat4 {
    DMat4::from_cols(
        r.x_axis.extend(0.0),
        r.y_axis.extend(0.0),
        r.z_axis.extend(0.0),
        t.extend(1.0),
    )
}

/// Splits a homogeneous transform into rotation and translation.
pub fn to_rt(t: &DMat4) -> (DMat3, DVec3) {
    (DMat3::from_mat4(*t), t.w_axis.truncate())
}

/// Inverse of a rigid transform (uses the transpose of the rotation).
pub fn inverse_rigid(t: &DMat4) -> DMat4 {
    let (r, p) = to_rt(t);
    let rt = r.transpose();
    from_rt(rt, -(rt * p))
}

/// Transform from TUM fields: translation (metres) and unit quaternion `(qx, qy, qz, qw)`.
pub fn from_tum(t: [f64; 3], q: [f64; 4]) -> DMat4 {
    let quat = DQuat::from_xyzw(q[0], q[1], q[2], q[3]).normalize();
    from_rt(DMat3::from_quat(quat), DVec3::from_array(t))
}

/// TUM fields `(t, q)` of a transform, quaternion `(qx, qy, qz, qw)` with `qw >= 0`.
pub fn to_tum(t: &DMat4) -> ([f64; 3], [f64; 4]) {
    let (r, p) = to_rt(t);
    let mut q = DQuat::from_mat3(&r).normalize();
    if q.w < 0.0 {
        q = -q;
    }
    (p.to_array(), [q.x, q.y, q.z, q.w])
}

/// Rotation angle of a transform's rotation part, in radians, in [0, pi]: atan2 of the
/// sine (half the length of the axis vector of `R - Rᵀ`) and the cosine (`(trace - 1) / 2`),
/// which stays exact near 0 where `acos` of the cosine alone turns rounding in the trace
/// into ~1e-8 rad (an identity composed of a pose and its inverse read as 2e-6 degrees).
pub fn rotation_angle(t: &DMat4) -> f64 {
    let (r, _) = to_rt(t);
    let cos = (r.x_axis.x + r.y_axis.y + r.z_axis.z - 1.0) * 0.5;
    let axis = glam::DVec3::new(
        r.y_axis.z - r.z_axis.y,
        r.z_axis.x - r.x_axis.z,
        r.x_axis.y - r.y_axis.x,
    );
    (axis.length() * 0.5).atan2(cos)
}

/// Translation length of a transform, in metres.
pub fn translation_norm(t: &DMat4) -> f64 {
    t.w_axis.truncate().length()
}

/// Translation (metres) and rotation (degrees) of the change between two world-to-camera
/// poses, `t_to * t_from⁻¹`. The angle is `acos` of the trace, as tracking health and loop
/// closure have always measured it (not [`rotation_angle`]: changing it would move their
/// thresholds' decisions by rounding).
pub fn pose_change(t_from: &DMat4, t_to: &DMat4) -> (f64, f64) {
    let delta = *t_to * inverse_rigid(t_from);
    let translation = delta.w_axis.truncate().length();
    let trace = delta.x_axis.x + delta.y_axis.y + delta.z_axis.z;
    let angle = ((trace - 1.0) / 2.0).clamp(-1.0, 1.0).acos();
    (translation, angle.to_degrees())
}

/// The matrix as four rows (row-major), for JSON reports that people read.
pub fn to_rows(t: &DMat4) -> [[f64; 4]; 4] {
    let r = |i| t.row(i).to_array();
    [r(0), r(1), r(2), r(3)]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// f64 round trips of exp/log lose only a few ulps per operation.
    const ROUND_TRIP_TOL: f64 = 1e-10;

    #[test]
    fn pose_change_reads_translation_and_angle() {
        let a = exp(&[0.1, 0.2, -0.3, 1.0, 2.0, 3.0]);
        let d = exp(&[0.0, 0.0, 0.2, 0.3, 0.4, 0.0]);
        let (m, deg) = pose_change(&a, &(d * a));
        assert!((m - 0.5).abs() < 0.1, "{m}");
        assert!((deg - 0.2f64.to_degrees()).abs() < 1e-9, "{deg}");
    }

    #[test]
    fn rotation_angle_from_tiny_to_half_turn() {
        for theta in [1e-9, 1e-4, 0.3, 1.5, 3.0] {
            let axis = glam::DVec3::new(1.0, -2.0, 0.5).normalize() * theta;
            let t = exp(&[axis.x, axis.y, axis.z, 0.1, 0.2, 0.3]);
            let got = rotation_angle(&t);
            assert!(
                (got - theta).abs() <= ROUND_TRIP_TOL * theta.max(1.0),
                "{theta} -> {got}"
            );
        }
        let t = exp(&[0.2, -0.4, 0.1, 1.0, 2.0, 3.0]);
        assert!(rotation_angle(&(inverse_rigid(&t) * t)) < 1e-15);
    }

    #[test]
    fn exp_log_round_trip() {
        let cases: [Twist; 5] = [
            [0.0; 6],
            [0.1, -0.2, 0.3, 1.0, 2.0, -3.0],
            [1e-10, 0.0, -1e-10, 1e-3, 0.0, 0.0],
            [2.0, 1.0, -0.5, 0.1, 0.2, 0.3],
            [0.0, 3.0, 0.0, 0.0, 0.0, 1.0],
        ];
        for x in cases {
            let y = log(&exp(&x));
            for i in 0..6 {
                assert!((x[i] - y[i]).abs() < ROUND_TRIP_TOL, "{x:?} -> {y:?}");
            }
        }
    }

    #[test]
    fn exp_matches_small_angle_first_order() {
        let x = [1e-4, -2e-4, 3e-4, 0.01, 0.02, 0.03];
        let t = exp(&x);
        let (r, _) = to_rt(&t);
        let approx = DMat3::IDENTITY + hat(DVec3::new(x[0], x[1], x[2]));
        // Second-order terms are ~|w|^2 = 1.4e-7.
        assert!((r - approx).to_cols_array().iter().all(|d| d.abs() < 2e-7));
    }

    #[test]
    fn tum_round_trip_and_inverse() {
        let t = exp(&[0.3, 0.2, -0.1, 1.0, -2.0, 0.5]);
        let (p, q) = to_tum(&t);
        let back = from_tum(p, q);
        assert!((back - t).to_cols_array().iter().all(|d| d.abs() < 1e-12));
        let id = inverse_rigid(&t) * t;
        assert!((id - DMat4::IDENTITY)
            .to_cols_array()
            .iter()
            .all(|d| d.abs() < 1e-12));
        assert!((rotation_angle(&exp(&[0.0, 0.0, 0.7, 0.0, 0.0, 0.0])) - 0.7).abs() < 1e-12);
    }
}
