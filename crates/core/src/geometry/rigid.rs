//! The rotation step of rigid alignment (Arun 1987 / Horn / Umeyama 1991 without scale):
//! the one SVD with the reflection fix that both trajectory alignment and point-to-point
//! ICP use (`eval` and `scan` in the `wgslam` package above).
//!
//! Convention: for pairs `(p_i, q_i)` with centroids `cp`, `cq`, the cross-covariance is
//! `H = sum (p_i - cp)(q_i - cq)^T`; the rotation maximising `trace(R H)` (equivalently
//! minimising `sum |R (p_i - cp) - (q_i - cq)|^2`) maps the p's onto the q's, and the
//! translation is `cq - R cp`. This module does not accumulate `H`; callers do (centred
//! sums in `eval`, running sums in `geometry::align::CrossCovariance`).

use glam::DMat3;
use nalgebra::{Matrix3, Vector3};

/// Second over first singular value below which the centred p's are a line or a point
/// and the rotation about that line is undetermined. f64 rounding sits near 1e-16; real
/// near-collinear sets (a single scan line) sit well above 1e-9.
pub const DEGENERATE_SINGULAR_RATIO: f64 = 1e-9;

/// Rotation `R` maximising `trace(R H)`, with `H`'s singular values (descending).
///
/// With `H = U S V^T`, `R = V diag(1, 1, d) U^T`, `d = sign(det(V U^T))`: when the plain
/// solution is a reflection, the axis of the smallest singular value is flipped, so `R` is
/// always a proper rotation. When `H` has rank below 2, `R` is one of many maximisers (use
/// [`rotation_from_cross_covariance`] to refuse that case). `None` only when the SVD
/// does not produce its factors.
pub fn svd_rotation(h: &Matrix3<f64>) -> Option<(DMat3, Vector3<f64>)> {
    // `SVD::new` sorts singular values in descending order, so the last one is smallest.
    let svd = nalgebra::SVD::new(*h, true, true);
    let (u, v_t) = (svd.u?, svd.v_t?);
    let v = v_t.transpose();
    let d = (v * u.transpose()).determinant().signum();
    let r = v * Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, d)) * u.transpose();
    Some((to_glam(&r), svd.singular_values))
}

/// [`svd_rotation`], or `None` when `H` is not finite or its rank is below 2 (the p's lie
/// on a line or a point: the rotation about that line is undetermined).
pub fn rotation_from_cross_covariance(h: &Matrix3<f64>) -> Option<DMat3> {
    let (r, s) = svd_rotation(h)?;
    if s[0].is_nan() || s[0] <= 0.0 || s[1] <= DEGENERATE_SINGULAR_RATIO * s[0] {
        return None;
    }
    Some(r)
}

/// The rotation closest to `m` in the Frobenius norm (for cleaning rounded matrices), or
/// `m` itself when it is too degenerate to have one.
pub fn nearest_rotation(m: DMat3) -> DMat3 {
    let c = m.to_cols_array();
    // H^T = M means R = V U^T of H = U S V^T equals the polar factor of M.
    let h = Matrix3::new(c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7], c[8]);
    rotation_from_cross_covariance(&h).unwrap_or(m)
}

/// nalgebra and glam are both column-major: copy column by column.
fn to_glam(r: &Matrix3<f64>) -> DMat3 {
    DMat3::from_cols_array(&[
        r[(0, 0)],
        r[(1, 0)],
        r[(2, 0)],
        r[(0, 1)],
        r[(1, 1)],
        r[(2, 1)],
        r[(0, 2)],
        r[(1, 2)],
        r[(2, 2)],
    ])
}
