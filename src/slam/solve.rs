//! Host side of one ICP iteration: decode the 29-float system, solve the 6x6 normal
//! equations in f64, and update the pose by left multiplication.
//!
//! The system comes from `cpu::icp_reduce` or the GPU's summed workgroup partials. An
//! under-determined system is refused ([`SolveError`]) so the caller keeps the previous pose
//! instead of jumping.
//!
//! Degenerate geometry (a single plane leaves two translations and one rotation free; a
//! corridor leaves the translation along it free): [`NormalEquations::solve_guarded`] with
//! a `min_eigen_ratio` holds the pose along every eigen-direction of AᵀA whose eigenvalue is
//! below that fraction of the largest, and solves only in the constrained subspace
//! (truncated eigen-solve, as in Zhang, Kaess and Singh, "On degeneracy of
//! optimization-based state estimation problems", ICRA 2016), instead of letting depth noise
//! pick the update along a direction nothing constrains. The number of held directions is
//! reported per iteration, so a degenerate frame is visible in `frames.json`. Without it
//! (the assignment profile) a system whose reciprocal condition is below
//! [`MIN_RECIPROCAL_CONDITION`] is refused as before. The measurements behind the robust
//! profile's ratio are in `slam::health`'s header.

use glam::DMat4;
use nalgebra::{Matrix6, Vector6};

use crate::geometry::se3;
use crate::layout::{ICP_ATB_OFFSET, ICP_COUNT_INDEX, ICP_RESIDUAL_INDEX, ICP_SYSTEM_LEN};

/// The decoded normal equations `AᵀA x = -Aᵀb` of one ICP iteration.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NormalEquations {
    /// `AᵀA`, symmetric.
    pub ata: Matrix6<f64>,
    /// `Aᵀb`.
    pub atb: Vector6<f64>,
    /// Correspondences that passed both filters.
    pub inliers: u64,
    /// Sum of squared point-to-plane residuals, m².
    pub residual_sq_sum: f64,
}

/// A solved increment and how well the system constrained it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Solved {
    /// The increment `x = (alpha, beta, gamma, tx, ty, tz)` (rad, m).
    pub x: se3::Twist,
    /// Smallest over largest eigenvalue of AᵀA (1: every direction equally constrained).
    pub eigen_ratio: f64,
    /// Eigen-directions held at zero update because their eigenvalue was below
    /// `min_eigen_ratio` times the largest (0 without degeneracy handling).
    pub held_directions: usize,
}

/// Why a system was refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SolveError {
    /// Fewer correspondences than [`MIN_INLIERS`].
    #[error("only {0} correspondences (need at least {MIN_INLIERS})")]
    TooFewInliers(u64),
    /// Smallest / largest eigenvalue of AᵀA below [`MIN_RECIPROCAL_CONDITION`].
    #[error("ill-conditioned system (reciprocal condition {0:.3e})")]
    IllConditioned(f64),
}

/// Fewer correspondences than this cannot constrain 6 degrees of freedom robustly.
pub const MIN_INLIERS: u64 = 100;
/// A reciprocal condition number below this means some motion is unobservable (e.g. a single
/// plane leaves in-plane translation free); the increment would be noise.
pub const MIN_RECIPROCAL_CONDITION: f64 = 1e-9;

impl NormalEquations {
    /// Decodes the 29-entry layout written by `accumulate` (21 upper-triangle entries of AᵀA
    /// row-major, 6 of Aᵀb, count, squared-residual sum).
    pub fn decode(sys: &[f64; ICP_SYSTEM_LEN]) -> Self {
        let mut ata = Matrix6::zeros();
        let mut k = 0;
        for r in 0..6 {
            for c in r..6 {
                ata[(r, c)] = sys[k];
                ata[(c, r)] = sys[k];
                k += 1;
            }
        }
        let atb = Vector6::from_fn(|r, _| sys[ICP_ATB_OFFSET + r]);
        NormalEquations {
            ata,
            atb,
            inliers: sys[ICP_COUNT_INDEX].round().max(0.0) as u64,
            residual_sq_sum: sys[ICP_RESIDUAL_INDEX],
        }
    }

    /// The RGB-D system: these (geometric) equations plus `photo`, the photometric ones,
    /// weighted by `lambda = weight σ_g² / σ_p²` (each term's mean squared residual), so
    /// that each term counts in units of its own noise and `weight` has no unit (see
    /// `params::IcpSettings::photometric_weight`); the result is in the geometric units
    /// (m²), its inliers both terms' and its residual the weighted sum. These equations
    /// unchanged when the weight is 0 or either term has no residual or too few rows.
    pub fn with_photometric(&self, photo: &NormalEquations, weight: f64) -> NormalEquations {
        let (sg, sp) = (self.mean_sq_residual(), photo.mean_sq_residual());
        if weight <= 0.0 || photo.inliers < MIN_INLIERS || sg <= 0.0 || sp <= 0.0 {
            return *self;
        }
        let lambda = weight * sg / sp;
        NormalEquations {
            ata: self.ata + photo.ata * lambda,
            atb: self.atb + photo.atb * lambda,
            inliers: self.inliers + photo.inliers,
            residual_sq_sum: self.residual_sq_sum + lambda * photo.residual_sq_sum,
        }
    }

    /// Mean squared point-to-plane residual (m²), 0 without inliers.
    pub fn mean_sq_residual(&self) -> f64 {
        if self.inliers == 0 {
            0.0
        } else {
            self.residual_sq_sum / self.inliers as f64
        }
    }

    /// The squared length of the increment `x` in the metric of the pose's own
    /// uncertainty: `xᵀ (AᵀA) x / σ²`, with `σ²` the mean (weighted) squared residual, so
    /// the pose's covariance is `σ² (AᵀA)⁻¹`. It is also the drop of the summed squared
    /// residuals the step predicts, in units of one pixel's `σ²`. A step that only follows
    /// the noise of the correspondences is of the order of the 6 degrees of freedom
    /// (χ² with 6 degrees); a step towards a better pose is far above. Infinite for a
    /// non-zero step on a system without residual (noise-free data: never "within noise").
    pub fn step_chi2(&self, x: &se3::Twist) -> f64 {
        let x = Vector6::from_column_slice(x);
        let drop = x.dot(&(self.ata * x)).max(0.0);
        let sigma_sq = self.mean_sq_residual();
        if drop == 0.0 {
            0.0
        } else if sigma_sq > 0.0 {
            drop / sigma_sq
        } else {
            f64::INFINITY
        }
    }

    /// Solves `AᵀA x = -Aᵀb` for `x = (alpha, beta, gamma, tx, ty, tz)`.
    pub fn solve(&self) -> Result<se3::Twist, SolveError> {
        self.solve_guarded(0.0).map(|s| s.x)
    }

    /// [`NormalEquations::solve`], holding the pose along degenerate directions when
    /// `min_eigen_ratio > 0`: every eigen-direction of AᵀA whose eigenvalue is below
    /// `min_eigen_ratio` times the largest gets no update, and the rest is solved in the
    /// eigenbasis. A system with no such direction is solved by Cholesky exactly as
    /// without the guard. With `min_eigen_ratio == 0` a system whose reciprocal condition is
    /// below [`MIN_RECIPROCAL_CONDITION`] is refused.
    pub fn solve_guarded(&self, min_eigen_ratio: f64) -> Result<Solved, SolveError> {
        if self.inliers < MIN_INLIERS {
            return Err(SolveError::TooFewInliers(self.inliers));
        }
        let eig = self.ata.symmetric_eigen();
        let (lo, hi) = eig
            .eigenvalues
            .iter()
            .fold((f64::INFINITY, 0.0f64), |(lo, hi), &e| {
                (lo.min(e), hi.max(e))
            });
        let rcond = if hi > 0.0 { lo / hi } else { 0.0 };
        // NaN (a broken system) is refused as well, with or without the guard.
        if rcond.is_nan() || hi <= 0.0 {
            return Err(SolveError::IllConditioned(rcond));
        }
        if min_eigen_ratio > 0.0 && rcond < min_eigen_ratio {
            // x = sum over the constrained directions v of v (v . -Aᵀb) / lambda.
            let mut x = Vector6::zeros();
            let mut held = 0;
            for (i, &lambda) in eig.eigenvalues.iter().enumerate() {
                if lambda < min_eigen_ratio * hi {
                    held += 1;
                    continue;
                }
                let v = eig.eigenvectors.column(i);
                x += v * (v.dot(&(-self.atb)) / lambda);
            }
            return Ok(Solved {
                x: [x[0], x[1], x[2], x[3], x[4], x[5]],
                eigen_ratio: rcond,
                held_directions: held,
            });
        }
        if rcond < MIN_RECIPROCAL_CONDITION {
            return Err(SolveError::IllConditioned(rcond));
        }
        let chol = self
            .ata
            .cholesky()
            .ok_or(SolveError::IllConditioned(rcond))?;
        let x = chol.solve(&(-self.atb));
        Ok(Solved {
            x: [x[0], x[1], x[2], x[3], x[4], x[5]],
            eigen_ratio: rcond,
            held_directions: 0,
        })
    }
}

/// One ICP iteration's statistics, as the frame report (`frames.json`), the tracking
/// health test and loop verification read them.
#[derive(Debug, Clone, Copy, Default, serde::Serialize)]
pub struct IcpIteration {
    /// Pyramid level the iteration ran at (0 = the full maps).
    pub level: usize,
    /// Correspondences that passed both filters.
    pub inliers: u64,
    /// Mean squared point-to-plane residual before the update, m².
    pub mean_sq_residual: f64,
    /// RGB-D tracking's photometric term at this iteration, before the update (level 0
    /// with `tracking = "rgbd"`, else `None`); `inliers` and `mean_sq_residual` are the
    /// geometric term's.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub photometric: Option<PhotometricTerm>,
    /// Smallest over largest eigenvalue of AᵀA; `None` when the system was refused.
    pub eigen_ratio: Option<f64>,
    /// Eigen-directions the guarded solve held (degenerate geometry).
    pub held_directions: usize,
    /// The solved increment's rotation (rad) and translation (m) norms
    /// ([`increment_size`]); `None` when the system was refused.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub increment: Option<(f64, f64)>,
    /// The increment's length in the pose's own noise ([`NormalEquations::step_chi2`]);
    /// `None` when the system was refused.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub step_chi2: Option<f64>,
    /// On the last iteration of a pyramid level: why the level stopped there.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub stop: Option<LevelStop>,
}

/// The photometric term of one RGB-D iteration ([`IcpIteration::photometric`]).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct PhotometricTerm {
    /// Model pixels that passed every gate of `photo_reduce`.
    pub inliers: u64,
    /// Their RMS (Huber-weighted) intensity residual, intensity units (0..1).
    pub rms: f64,
}

impl PhotometricTerm {
    /// The record of decoded photometric equations.
    pub fn of(photo: &NormalEquations) -> Self {
        PhotometricTerm {
            inliers: photo.inliers,
            rms: photo.mean_sq_residual().sqrt(),
        }
    }
}

/// Why ICP stopped iterating at a pyramid level (`frames.json`: the level's last
/// iteration's `stop`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum LevelStop {
    /// The increment was below `icp.min_increment` in rotation and translation.
    MinIncrement,
    /// The increment was within the pose's own noise (`icp.stop_chi2`).
    WithinNoise,
    /// The increment undid most of the previous one: the correspondences flip between two
    /// sets (`icp.stop_on_reversal`); the pose is left between the two.
    Reversal,
    /// The level's budget of iterations ran out.
    Budget,
    /// The system was refused; the last good pose is kept.
    Refused,
}

/// Left-multiplicative update `T <- exp(x) T` of a world-to-camera pose.
pub fn update_pose(t_world_to_cam: &DMat4, x: &se3::Twist) -> DMat4 {
    se3::exp(x) * *t_world_to_cam
}

/// Size of an increment for the convergence test: rotation (rad) and translation (m) norms.
pub fn increment_size(x: &se3::Twist) -> (f64, f64) {
    let r = (x[0] * x[0] + x[1] * x[1] + x[2] * x[2]).sqrt();
    let t = (x[3] * x[3] + x[4] * x[4] + x[5] * x[5]).sqrt();
    (r, t)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cpu::icp_reduce::accumulate;

    /// Seeded xorshift32 noise, uniform in [-0.5, 0.5).
    fn noise_from(mut seed: u32) -> impl FnMut() -> f32 {
        move || {
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            seed as f32 / u32::MAX as f32 - 0.5
        }
    }

    /// A well-posed system built from known rows is solved to the exact increment.
    #[test]
    fn solves_consistent_system() {
        let x_true = [0.01, -0.02, 0.005, 0.03, -0.01, 0.02];
        let mut sys = [0.0; ICP_SYSTEM_LEN];
        // Deterministic, well-spread rows; b chosen so that A x_true + b = 0.
        for i in 0..200 {
            let f = i as f32;
            let a = [
                (f * 0.37).sin(),
                (f * 0.71).cos(),
                (f * 1.13).sin(),
                (f * 0.53).cos(),
                (f * 0.91).sin(),
                (f * 1.37).cos(),
            ];
            let b = -(0..6).map(|k| a[k] as f64 * x_true[k]).sum::<f64>() as f32;
            accumulate(&mut sys, &a, b);
        }
        let x = NormalEquations::decode(&sys).solve().unwrap();
        for k in 0..6 {
            // f32 rows: b carries ~1e-8 relative rounding.
            assert!(
                (x[k] - x_true[k]).abs() < 1e-6,
                "x[{k}] {} vs {}",
                x[k],
                x_true[k]
            );
        }
    }

    /// A planar scene (all normals equal) leaves in-plane motion free: refused.
    #[test]
    fn refuses_singular_system() {
        let mut sys = [0.0; ICP_SYSTEM_LEN];
        for i in 0..500 {
            let p = glam::Vec3::new((i % 20) as f32 * 0.1, (i / 20) as f32 * 0.1, 2.0);
            let n = glam::Vec3::Z;
            let pxn = p.cross(n);
            accumulate(&mut sys, &[pxn.x, pxn.y, pxn.z, n.x, n.y, n.z], 0.01);
        }
        let eq = NormalEquations::decode(&sys);
        assert!(matches!(eq.solve(), Err(SolveError::IllConditioned(_))));
        let few = NormalEquations::decode(&[0.0; ICP_SYSTEM_LEN]);
        assert_eq!(few.solve(), Err(SolveError::TooFewInliers(0)));
    }

    /// The guard on a plane seen with noisy normals: the three free directions (in-plane
    /// translation, rotation about the normal) get no update, the three constrained ones
    /// are solved; the unguarded solve invents a large in-plane step from the same noise.
    #[test]
    fn guard_holds_the_free_directions_of_a_plane() {
        let mut sys = [0.0; ICP_SYSTEM_LEN];
        let mut noise = noise_from(7);
        for i in 0..2000 {
            let p = glam::Vec3::new(
                (i % 40) as f32 * 0.05 - 1.0,
                (i / 40) as f32 * 0.04 - 1.0,
                2.0,
            );
            // Normals tilted by about 0.01 rad of noise, residuals of about 1 mm.
            let n = glam::Vec3::new(0.01 * noise(), 0.01 * noise(), 1.0).normalize();
            let pxn = p.cross(n);
            accumulate(
                &mut sys,
                &[pxn.x, pxn.y, pxn.z, n.x, n.y, n.z],
                0.002 * noise(),
            );
        }
        let eq = NormalEquations::decode(&sys);
        // The held eigen-directions are the free axes up to the normals' 0.01 rad tilt, so
        // the constrained update leaks into them by about that fraction of its (sub-mm) size.
        const HELD_LEAK: f64 = 1e-5;
        // The unguarded in-plane step: about 5 mm from this noise (Aᵀb ~ 1e-4 over an
        // eigenvalue ~ 0.02); a tenth of it still shows it is invented.
        const INVENTED_STEP_M: f64 = 5e-4;
        let guarded = eq.solve_guarded(1e-3).unwrap();
        assert_eq!(guarded.held_directions, 3, "{guarded:?}");
        let (gamma, tx, ty) = (guarded.x[2], guarded.x[3], guarded.x[4]);
        assert!(
            gamma.abs().max(tx.abs()).max(ty.abs()) < HELD_LEAK,
            "{guarded:?}"
        );
        let free = eq.solve_guarded(0.0).unwrap().x;
        assert!(
            free[3].abs().max(free[4].abs()) > INVENTED_STEP_M,
            "unguarded {free:?}"
        );
    }

    /// The noise stop statistic: a system whose residuals are pure noise (no pose error)
    /// gives a step of χ² about 6 (6 degrees of freedom), one with a real 1 mm offset a
    /// step far above; noise-free residuals with an offset are never "within noise".
    #[test]
    fn step_chi2_separates_noise_from_a_real_offset() {
        let mut noise = noise_from(11);
        let rows: Vec<[f32; 6]> = (0..5000)
            .map(|i| {
                let f = i as f32;
                let n = glam::Vec3::new((f * 0.37).sin(), (f * 0.71).cos(), 2.0).normalize();
                let p = glam::Vec3::new((f * 0.13).cos(), (f * 0.29).sin(), 2.0);
                let pxn = p.cross(n);
                [pxn.x, pxn.y, pxn.z, n.x, n.y, n.z]
            })
            .collect();
        // Uniform noise of +-1 mm, and the same plus a 1 mm offset along every normal's z.
        let offsets = [0.0f32, 1e-3];
        let chi2: Vec<f64> = offsets
            .iter()
            .map(|&offset| {
                let mut sys = [0.0; ICP_SYSTEM_LEN];
                for a in &rows {
                    accumulate(&mut sys, a, 2e-3 * noise() + offset * a[5]);
                }
                let eq = NormalEquations::decode(&sys);
                eq.step_chi2(&eq.solve().unwrap())
            })
            .collect();
        // χ²(6) exceeds 30 with probability below 1e-4.
        const NOISE_CHI2_MAX: f64 = 30.0;
        assert!(chi2[0] < NOISE_CHI2_MAX, "pure noise: {}", chi2[0]);
        // A 1 mm offset seen by 5000 rows of 0.6 mm noise: thousands.
        assert!(chi2[1] > 100.0 * NOISE_CHI2_MAX, "offset: {}", chi2[1]);
        let mut exact = [0.0; ICP_SYSTEM_LEN];
        accumulate(&mut exact, &[0.0, 0.0, 0.0, 0.0, 0.0, 1.0], 0.0);
        let eq = NormalEquations::decode(&exact);
        assert_eq!(eq.step_chi2(&[0.0; 6]), 0.0);
        assert_eq!(
            eq.step_chi2(&[0.0, 0.0, 0.0, 0.0, 0.0, 1e-6]),
            f64::INFINITY
        );
    }
}
