//! Trajectory evaluation with the TUM RGB-D benchmark's definitions: association by
//! stamp, rigid (Horn/Umeyama, no scale) alignment, absolute trajectory error (ATE) and
//! relative pose error (RPE).
//!
//! Inputs are `(stamp, t_cam_to_world)` lists (metres); stamps only need to be comparable
//! between the estimate and the ground truth (seconds, or frame indices for ICL-NUIM).
//! This module computes numbers; it does not read files or print reports.

use glam::{DMat4, DVec3};
use nalgebra::Matrix3;
use serde::Serialize;

use crate::dataset::tum::{associate as associate_stamps, nearest_within};
use crate::geometry::rigid;
use crate::geometry::se3;
use crate::{Error, Result};

/// Default association window, as in the TUM tools (`--max_difference 0.02`).
pub const DEFAULT_MAX_DT: f64 = 0.02;

/// Absolute trajectory error statistics over associated pose pairs (metres).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct AteStats {
    pub rmse_m: f64,
    pub mean_m: f64,
    pub median_m: f64,
    pub max_m: f64,
    /// Number of associated (estimate, ground truth) pairs.
    pub pairs: usize,
}

/// Relative pose error statistics over pose pairs `delta` frames apart.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct RpeStats {
    /// RMSE of the translation of the error transform, metres.
    pub trans_rmse_m: f64,
    /// RMSE of the rotation angle of the error transform, degrees.
    pub rot_rmse_deg: f64,
    /// Number of pose pairs that had ground truth at both ends.
    pub pairs: usize,
}

/// Greedy nearest-stamp association of estimate and ground truth (like the TUM
/// `associate.py`: pairs with `|dt| <= max_dt`, best first, each pose used once).
/// Returns `(est_index, gt_index)` sorted by estimate stamp.
pub fn associate(est: &[(f64, DMat4)], gt: &[(f64, DMat4)], max_dt: f64) -> Vec<(usize, usize)> {
    let a: Vec<f64> = est.iter().map(|p| p.0).collect();
    let b: Vec<f64> = gt.iter().map(|p| p.0).collect();
    associate_stamps(&a, &b, max_dt)
}

/// The rigid transform `t_est_to_gt` minimising `sum |t * est_i - gt_i|^2` (Horn/Umeyama
/// without scale, via SVD, with the reflection fix so the rotation has determinant +1).
/// Positions in metres, `est_positions[i]` paired with `gt_positions[i]`. With fewer than
/// three non-collinear points the rotation is not unique; one minimiser is returned.
pub fn align_rigid(est_positions: &[DVec3], gt_positions: &[DVec3]) -> Result<DMat4> {
    if est_positions.len() != gt_positions.len() || est_positions.is_empty() {
        return Err(Error::Argument(format!(
            "alignment needs equally many estimated and ground-truth positions, at least one \
             (got {} and {})",
            est_positions.len(),
            gt_positions.len()
        )));
    }
    let n = est_positions.len() as f64;
    let mu_e = est_positions.iter().copied().sum::<DVec3>() / n;
    let mu_g = gt_positions.iter().copied().sum::<DVec3>() / n;
    // Cross-covariance H = sum (e - mu_e)(g - mu_g)^T: the rotation maps e onto g.
    let mut h = Matrix3::<f64>::zeros();
    for (e, g) in est_positions.iter().zip(gt_positions) {
        let de = *e - mu_e;
        let dg = *g - mu_g;
        h += nalgebra::Vector3::new(de.x, de.y, de.z) * nalgebra::RowVector3::new(dg.x, dg.y, dg.z);
    }
    if !h.iter().all(|v| v.is_finite()) {
        return Err(Error::Numerical(
            "alignment input contains non-finite positions".into(),
        ));
    }
    // Fewer than three non-collinear points: svd_rotation still returns one minimiser.
    let (rot, _) = rigid::svd_rotation(&h)
        .ok_or_else(|| Error::Numerical("SVD of the alignment covariance failed".into()))?;
    Ok(se3::from_rt(rot, mu_g - rot * mu_e))
}

/// ATE with the default association window [`DEFAULT_MAX_DT`]; see [`ate_with`].
pub fn ate(est: &[(f64, DMat4)], gt: &[(f64, DMat4)], aligned: bool) -> Result<AteStats> {
    ate_with(est, gt, aligned, DEFAULT_MAX_DT)
}

/// The positions (metres) of the pose pairs [`associate`] finds within `max_dt`: the
/// estimate's and the ground truth's, in pair order (what [`ate_with`] aligns).
pub fn associated_positions(
    est: &[(f64, DMat4)],
    gt: &[(f64, DMat4)],
    max_dt: f64,
) -> (Vec<DVec3>, Vec<DVec3>) {
    associate(est, gt, max_dt)
        .iter()
        .map(|&(i, j)| (est[i].1.w_axis.truncate(), gt[j].1.w_axis.truncate()))
        .unzip()
}

/// Absolute trajectory error: associates poses by stamp (within `max_dt`), optionally
/// aligns the estimated positions to the ground truth with [`align_rigid`], and returns
/// statistics of the per-pair position distances (metres). Errors when nothing associates.
pub fn ate_with(
    est: &[(f64, DMat4)],
    gt: &[(f64, DMat4)],
    aligned: bool,
    max_dt: f64,
) -> Result<AteStats> {
    let (e, g) = associated_positions(est, gt, max_dt);
    if e.is_empty() {
        return Err(no_pairs(est, gt, max_dt));
    }
    let t = if aligned {
        align_rigid(&e, &g)?
    } else {
        DMat4::IDENTITY
    };
    let d: Vec<f64> = e
        .iter()
        .zip(&g)
        .map(|(e, g)| (t.transform_point3(*e) - *g).length())
        .collect();
    if d.iter().any(|x| !x.is_finite()) {
        return Err(Error::Numerical(
            "ATE is not finite: the positions are too large for the alignment (read \
             trajectories keep coordinates within 1e9 m)"
                .into(),
        ));
    }
    let n = d.len() as f64;
    let rmse_m = (d.iter().map(|x| x * x).sum::<f64>() / n).sqrt();
    let mean_m = d.iter().sum::<f64>() / n;
    let max_m = d.iter().copied().fold(0.0, f64::max);
    let k = d.len();
    let median_m = crate::stats::median(&d);
    Ok(AteStats {
        rmse_m,
        mean_m,
        median_m,
        max_m,
        pairs: k,
    })
}

/// RPE with the default association window [`DEFAULT_MAX_DT`]; see [`rpe_with`].
pub fn rpe(est: &[(f64, DMat4)], gt: &[(f64, DMat4)], delta_frames: usize) -> Result<RpeStats> {
    rpe_with(est, gt, delta_frames, DEFAULT_MAX_DT)
}

/// Relative pose error over estimate pairs `(i, i + delta_frames)` (positions in the
/// estimate sorted by stamp). Each end takes the ground-truth pose nearest in stamp; a pair
/// is skipped when either end has none within `max_dt`. With estimate poses `P` and ground
/// truth `Q`, the error is `E = (Q_i^-1 Q_j)^-1 (P_i^-1 P_j)`; its translation norm (metres)
/// and rotation angle (degrees) are reduced to RMSEs. Needs no alignment.
pub fn rpe_with(
    est: &[(f64, DMat4)],
    gt: &[(f64, DMat4)],
    delta_frames: usize,
    max_dt: f64,
) -> Result<RpeStats> {
    if delta_frames == 0 {
        return Err(Error::Argument("RPE delta must be at least 1 frame".into()));
    }
    if est.len() <= delta_frames {
        return Err(Error::Argument(format!(
            "RPE over {delta_frames} frame(s) needs at least {} estimated poses; the estimate \
             has {}",
            delta_frames + 1,
            est.len()
        )));
    }
    let mut est_sorted: Vec<&(f64, DMat4)> = est.iter().collect();
    est_sorted.sort_by(|a, b| a.0.total_cmp(&b.0));
    // Pairs are consecutive poses by stamp: with repeated stamps their order, and so every
    // pair, would be arbitrary (all stamps equal made 22 "pairs" of one pose).
    if let Some(w) = est_sorted.windows(2).find(|w| w[0].0 == w[1].0) {
        let repeats = est_sorted.windows(2).filter(|w| w[0].0 == w[1].0).count();
        return Err(Error::Argument(format!(
            "the estimate repeats stamps ({repeats} poses share a stamp with the one before, \
             e.g. {}); RPE pairs poses in stamp order, so stamps must be distinct",
            w[0].0
        )));
    }
    let mut gt_sorted: Vec<&(f64, DMat4)> = gt.iter().collect();
    gt_sorted.sort_by(|a, b| a.0.total_cmp(&b.0));
    let gt_stamps: Vec<f64> = gt_sorted.iter().map(|p| p.0).collect();

    let (mut sum_t2, mut sum_r2, mut pairs) = (0.0, 0.0, 0usize);
    for i in 0..est_sorted.len().saturating_sub(delta_frames) {
        let (si, pi) = est_sorted[i];
        let (sj, pj) = est_sorted[i + delta_frames];
        let (Some(gi), Some(gj)) = (
            nearest_within(&gt_stamps, *si, max_dt),
            nearest_within(&gt_stamps, *sj, max_dt),
        ) else {
            continue;
        };
        let (qi, qj) = (gt_sorted[gi].1, gt_sorted[gj].1);
        let rel_gt = se3::inverse_rigid(&qi) * qj;
        let rel_est = se3::inverse_rigid(pi) * *pj;
        let e = se3::inverse_rigid(&rel_gt) * rel_est;
        sum_t2 += se3::translation_norm(&e).powi(2);
        sum_r2 += se3::rotation_angle(&e).powi(2);
        pairs += 1;
    }
    if pairs == 0 {
        return Err(no_pairs(est, gt, max_dt));
    }
    let n = pairs as f64;
    Ok(RpeStats {
        trans_rmse_m: (sum_t2 / n).sqrt(),
        rot_rmse_deg: (sum_r2 / n).sqrt().to_degrees(),
        pairs,
    })
}

fn no_pairs(est: &[(f64, DMat4)], gt: &[(f64, DMat4)], max_dt: f64) -> Error {
    let range = |t: &[(f64, DMat4)]| {
        let lo = t.iter().map(|p| p.0).fold(f64::INFINITY, f64::min);
        let hi = t.iter().map(|p| p.0).fold(f64::NEG_INFINITY, f64::max);
        format!("{} poses, stamps {lo}..{hi}", t.len())
    };
    Error::Argument(format!(
        "no estimated pose has a ground-truth pose within {max_dt} of its stamp (estimate: {}; \
         ground truth: {}); are these the right files?",
        range(est),
        range(gt)
    ))
}
