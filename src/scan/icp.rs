//! Point-to-point ICP between two point clouds (Besl & McKay with random sampling and a
//! rejection radius), solved in closed form by Arun / Umeyama (SVD, reflection fix).
//!
//! Frames: the result `t_source_to_target` maps a point in SOURCE coordinates to TARGET
//! coordinates (`p_target = T * p_source`), metres. Nearest neighbours come from a
//! [`NearestNeighbours`] implementation: [`KdTreeTarget`] (kiddo) on the CPU; a GPU one
//! can plug in the same way. This is not point-to-plane ICP (see the dense-SLAM tracker).

use glam::{DMat4, DVec3};

use super::nn::{KdTreeTarget, NearestNeighbours};
use crate::geometry::align::CrossCovariance;
use crate::geometry::rigid::nearest_rotation;
use crate::geometry::se3;
use crate::{Error, Result};
use wgslam_core::seeded::SplitMix;

/// How many source points each iteration uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub enum Samples {
    /// Every source point, every iteration.
    All,
    /// A fresh random sample of this many points (without replacement) per iteration;
    /// all points when the source has fewer.
    Count(usize),
}

impl std::str::FromStr for Samples {
    type Err = String;
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        if s.eq_ignore_ascii_case("all") {
            return Ok(Samples::All);
        }
        match s.parse::<usize>() {
            Ok(0) | Err(_) => Err(format!("`{s}` is not `all` or a positive count")),
            Ok(n) => Ok(Samples::Count(n)),
        }
    }
}

/// Parameters of [`register`].
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct IcpParams {
    /// Iteration cap; reaching it without meeting `threshold` is [`IcpStatus::NotConverged`].
    pub max_iterations: usize,
    /// Source points per iteration.
    pub samples: Samples,
    /// Pairs farther apart than this (metres, after applying the estimate) are outliers.
    pub radius: f64,
    /// Coarse-to-fine: when set below `radius`, each time ICP converges at the current
    /// radius the radius is halved (not below this, metres) and ICP continues; converged
    /// means converged at this final radius. `None`: one fixed radius.
    pub final_radius: Option<f64>,
    /// Converged when an update rotates less than this (radians) AND translates less than
    /// this (metres). With random sampling (fewer samples than source points) each bound
    /// is raised by the update's sampling noise floor, see [`register_with`].
    pub threshold: f64,
    /// Seed of the sampling generator: equal seeds give equal results.
    pub seed: u64,
    /// Fewer inliers than this in an iteration stops with [`IcpStatus::TooFewInliers`]
    /// (at least 3 are always required by the closed-form solve).
    pub min_inliers: usize,
}

impl Default for IcpParams {
    fn default() -> Self {
        IcpParams {
            max_iterations: 50,
            samples: Samples::Count(1000),
            radius: 1.0,
            final_radius: None,
            threshold: 1e-5,
            seed: 0,
            min_inliers: 10,
        }
    }
}

/// How a registration ended. Only [`IcpStatus::Converged`] means the transform can be trusted.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub enum IcpStatus {
    /// An update fell below the threshold.
    Converged,
    /// `max_iterations` updates were made and the last was still above the threshold.
    NotConverged,
    /// An iteration found fewer inliers than needed; the estimate before it is returned.
    TooFewInliers { inliers: usize, needed: usize },
    /// The inliers do not fix a rotation (all on one line or one point); estimate before it.
    Degenerate { inliers: usize },
}

impl IcpStatus {
    /// True only for [`IcpStatus::Converged`].
    pub fn is_converged(&self) -> bool {
        matches!(self, IcpStatus::Converged)
    }
}

impl std::fmt::Display for IcpStatus {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            IcpStatus::Converged => write!(f, "converged"),
            IcpStatus::NotConverged => write!(f, "not converged (iteration cap reached)"),
            IcpStatus::TooFewInliers { inliers, needed } => {
                write!(f, "too few inliers ({inliers} < {needed})")
            }
            IcpStatus::Degenerate { inliers } => {
                write!(f, "degenerate inliers ({inliers} points on a line)")
            }
        }
    }
}

/// Correspondence statistics of one iteration, measured at the estimate BEFORE its update.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct IterationStats {
    /// Rejection radius used, metres.
    pub radius: f64,
    /// Source points queried.
    pub sampled: usize,
    /// Pairs within the rejection radius.
    pub inliers: usize,
    /// Root mean square inlier distance, metres (NaN with no inliers).
    pub rmse: f64,
    /// `(sampled - inliers) / sampled`.
    pub outlier_ratio: f64,
    /// Rotation angle of this iteration's update, radians (0 when no update was made).
    pub update_rotation: f64,
    /// Translation length of this iteration's update, metres.
    pub update_translation: f64,
}

/// Outcome of [`register`].
#[derive(Debug, Clone, PartialEq)]
pub struct IcpResult {
    /// Maps SOURCE coordinates to TARGET coordinates (metres), column-major.
    pub t_source_to_target: DMat4,
    /// How it ended; check [`IcpStatus::is_converged`] before trusting the transform.
    pub status: IcpStatus,
    /// One entry per iteration run (including a final one that stopped without an update).
    pub iterations: Vec<IterationStats>,
    /// Correspondences of a fresh sample at the final transform (inlier RMSE, outlier ratio).
    pub final_stats: IterationStats,
}

impl IcpResult {
    /// Number of iterations run.
    pub fn iteration_count(&self) -> usize {
        self.iterations.len()
    }
}

/// Draws sample indices: a partial Fisher-Yates shuffle of `order` (kept between calls, so
/// each call is a fresh uniform sample without replacement); returns the first `k`.
fn draw_sample<'a>(order: &'a mut [u32], k: usize, rng: &mut SplitMix) -> &'a [u32] {
    let n = order.len();
    if k >= n {
        return order;
    }
    for i in 0..k {
        let j = i + rng.below_wide(n - i);
        order.swap(i, j);
    }
    &order[..k]
}

/// Standard errors an update may reach from sampling noise alone before it counts as
/// progress: the norm of a 3-vector of independent errors exceeds 3 sigma rarely.
const NOISE_FLOOR_SIGMAS: f64 = 3.0;

/// Registers `source` onto `target` with a KD-tree: see [`register_with`].
pub fn register(
    source: &[[f32; 3]],
    target: &[[f32; 3]],
    init_source_to_target: DMat4,
    params: &IcpParams,
) -> Result<IcpResult> {
    let nn = KdTreeTarget::new(target)?;
    register_with(source, &nn, init_source_to_target, params)
}

/// Point-to-point ICP of `source` (metres, source frame) against the target behind `nn`,
/// starting from `init_source_to_target`. Each iteration samples the source, transforms the
/// sample by the estimate, pairs each point with its nearest target point, rejects pairs
/// beyond `params.radius`, solves the inliers' best rigid update in closed form and composes
/// it on the left (`T <- dT * T`). Errors only on unusable input (empty clouds, bad
/// parameters); a registration that fails is reported in [`IcpResult::status`].
///
/// Convergence with random sampling: a fresh sample each iteration makes every update
/// jitter by about its standard error even at the optimum, so no fixed tiny threshold is
/// ever met. When sampling a strict subset, the threshold is therefore raised by the
/// update's noise floor: 3 standard errors, `sigma / sqrt(inliers)` metres for the
/// translation and `sigma / (sqrt(inliers) * spread)` radians for the rotation, `sigma`
/// being the RMS residual left after the update (see [`CrossCovariance::noise_floor`]) and
/// `spread` the RMS distance of the inlier source points from their centroid. With
/// [`Samples::All`] the sample never changes and the plain threshold applies.
pub fn register_with(
    source: &[[f32; 3]],
    nn: &dyn NearestNeighbours,
    init_source_to_target: DMat4,
    params: &IcpParams,
) -> Result<IcpResult> {
    check_inputs(source, nn, params)?;
    let k = match params.samples {
        Samples::All => source.len(),
        Samples::Count(n) => n.min(source.len()),
    };
    let needed = params.min_inliers.max(3);
    let final_radius = params
        .final_radius
        .unwrap_or(params.radius)
        .min(params.radius);
    let mut radius = params.radius;
    let subsampled = k < source.len();
    let mut rng = SplitMix::new(params.seed);
    let mut order: Vec<u32> = (0..source.len() as u32).collect();
    let mut queries = vec![[0f32; 3]; k];
    let mut pairs = vec![(0u32, 0f32); k];
    // A fresh sample, paired at the estimate `t` within `radius` (metres).
    let mut pair_sample = |t: &DMat4, radius: f64| {
        correspond(
            source,
            nn,
            t,
            draw_sample(&mut order, k, &mut rng),
            radius * radius,
            &mut queries,
            &mut pairs,
        )
    };
    let mut t = init_source_to_target;
    let mut iterations = Vec::new();
    let mut status = IcpStatus::NotConverged;

    for _ in 0..params.max_iterations {
        let acc = pair_sample(&t, radius)?;
        let mut stats = stats_of(&acc, k, radius);
        if acc.count < needed {
            iterations.push(stats);
            status = IcpStatus::TooFewInliers {
                inliers: acc.count,
                needed,
            };
            break;
        }
        let Some(dt) = acc.solve() else {
            iterations.push(stats);
            status = IcpStatus::Degenerate { inliers: acc.count };
            break;
        };
        t = dt * t;
        stats.update_rotation = se3::rotation_angle(&dt);
        stats.update_translation = se3::translation_norm(&dt);
        iterations.push(stats);
        let (floor_rot, floor_trans) = if subsampled {
            let (r, t) = acc.noise_floor(&dt);
            (NOISE_FLOOR_SIGMAS * r, NOISE_FLOOR_SIGMAS * t)
        } else {
            (0.0, 0.0)
        };
        if stats.update_rotation < params.threshold + floor_rot
            && stats.update_translation < params.threshold + floor_trans
        {
            if radius <= final_radius {
                status = IcpStatus::Converged;
                break;
            }
            radius = (radius * 0.5).max(final_radius);
        }
    }
    // Re-orthonormalise: hundreds of f64 products drift by ~1e-15, harmless but untidy.
    let (r, p) = se3::to_rt(&t);
    let t = se3::from_rt(nearest_rotation(r), p);
    let acc = pair_sample(&t, radius)?;
    Ok(IcpResult {
        t_source_to_target: t,
        status,
        iterations,
        final_stats: stats_of(&acc, k, radius),
    })
}

/// Checks that both clouds have points, the source fewer than 2^32, and that the radii
/// and the threshold are usable.
fn check_inputs(source: &[[f32; 3]], nn: &dyn NearestNeighbours, params: &IcpParams) -> Result<()> {
    if source.is_empty() {
        return Err(Error::Argument("source cloud is empty".into()));
    }
    if nn.points().is_empty() {
        return Err(Error::Argument("target cloud is empty".into()));
    }
    if !params.radius.is_finite() || params.radius <= 0.0 {
        return Err(Error::Argument(format!(
            "rejection radius must be a positive number of metres, got {}",
            params.radius
        )));
    }
    if params.threshold.is_nan() || params.threshold < 0.0 {
        return Err(Error::Argument(format!(
            "threshold must be >= 0, got {}",
            params.threshold
        )));
    }
    if u32::try_from(source.len()).is_err() {
        return Err(Error::Argument("source has more than 2^32 points".into()));
    }
    if let Some(f) = params.final_radius {
        if !f.is_finite() || f <= 0.0 {
            return Err(Error::Argument(format!(
                "final radius must be a positive number of metres, got {f}"
            )));
        }
    }
    Ok(())
}

fn stats_of(acc: &CrossCovariance, sampled: usize, radius: f64) -> IterationStats {
    IterationStats {
        radius,
        sampled,
        inliers: acc.count,
        rmse: acc.rmse(),
        outlier_ratio: (sampled - acc.count) as f64 / sampled as f64,
        update_rotation: 0.0,
        update_translation: 0.0,
    }
}

/// Transforms the sampled source points by `t`, finds their nearest target points and
/// reduces the inliers (squared distance <= `radius_sq`) into a [`CrossCovariance`].
fn correspond(
    source: &[[f32; 3]],
    nn: &dyn NearestNeighbours,
    t: &DMat4,
    sample: &[u32],
    radius_sq: f64,
    queries: &mut [[f32; 3]],
    pairs: &mut [(u32, f32)],
) -> Result<CrossCovariance> {
    let transform = |i: u32| {
        let s = source[i as usize];
        t.transform_point3(DVec3::new(s[0] as f64, s[1] as f64, s[2] as f64))
    };
    for (q, &i) in queries.iter_mut().zip(sample) {
        *q = transform(i).as_vec3().to_array();
    }
    if let Some(acc) = nn.reduce_pairs(queries, radius_sq)? {
        return Ok(acc);
    }
    nn.nearest(queries, pairs)?;
    let target = nn.points();
    let mut acc = CrossCovariance::default();
    for (&i, &(j, d2)) in sample.iter().zip(pairs.iter()) {
        if (d2 as f64) <= radius_sq {
            let q = target[j as usize];
            acc.add(
                transform(i),
                DVec3::new(q[0] as f64, q[1] as f64, q[2] as f64),
            );
        }
    }
    Ok(acc)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// f64 sums of a few hundred products of unit-size numbers.
    const SUM_TOL: f64 = 1e-9;

    fn cloud() -> Vec<DVec3> {
        (0..200)
            .map(|i| {
                let a = i as f64 * 0.37;
                DVec3::new(a.cos() * 2.0, (a * 1.3).sin(), 0.01 * i as f64)
            })
            .collect()
    }

    #[test]
    fn noise_floor_is_zero_for_exact_pairs_and_scales_with_noise() {
        let t = se3::exp(&[0.1, -0.2, 0.05, 0.3, 0.1, -0.2]);
        let mut exact = CrossCovariance::default();
        let mut noisy = CrossCovariance::default();
        let mut rng = SplitMix::new(1);
        for p in cloud() {
            let q = t.transform_point3(p);
            exact.add(p, q);
            // Uniform noise in [-5, 5] mm per axis: sigma = 10 mm / sqrt(12) per axis.
            let e = DVec3::new(
                rng.below_wide(1001) as f64 - 500.0,
                rng.below_wide(1001) as f64 - 500.0,
                rng.below_wide(1001) as f64 - 500.0,
            ) * 1e-5;
            noisy.add(p, q + e);
        }
        let dt = exact.solve().unwrap();
        let (r, p) = pose_of(&(se3::inverse_rigid(&t) * dt));
        assert!(r < SUM_TOL && p < SUM_TOL);
        let (fr, ft) = exact.noise_floor(&dt);
        // sigma^2 = var_p + var_q - 2 tr(RH) cancels to rounding: sqrt of ~1e-15.
        assert!(fr < 1e-7 && ft < 1e-7, "{fr} {ft}");
        let dn = noisy.solve().unwrap();
        let (_, ft) = noisy.noise_floor(&dn);
        let expected = (3.0f64).sqrt() * 0.01 / 12f64.sqrt() / (200f64).sqrt();
        assert!((ft / expected - 1.0).abs() < 0.2, "{ft} vs {expected}");
    }

    fn pose_of(t: &DMat4) -> (f64, f64) {
        (se3::rotation_angle(t), se3::translation_norm(t))
    }

    #[test]
    fn merge_equals_sequential_sum() {
        let pts = cloud();
        let mut all = CrossCovariance::default();
        let (mut a, mut b) = (CrossCovariance::default(), CrossCovariance::default());
        for (i, p) in pts.iter().enumerate() {
            let q = *p * 0.5 + DVec3::X;
            all.add(*p, q);
            if i % 2 == 0 {
                a.add(*p, q)
            } else {
                b.add(*p, q)
            }
        }
        let m = a.merge(&b);
        assert_eq!(m.count, all.count);
        assert!((m.sum_sq_dist - all.sum_sq_dist).abs() < SUM_TOL);
        assert!((m.sum_pq[1][2] - all.sum_pq[1][2]).abs() < SUM_TOL);
    }

    #[test]
    fn unshifted_recovers_sums_of_original_points() {
        let a = DVec3::new(10.0, -20.0, 5.0);
        let (mut direct, mut shifted) = (CrossCovariance::default(), CrossCovariance::default());
        for p in cloud() {
            let q = p * 0.9 + DVec3::Y;
            direct.add(p + a, q + a);
            shifted.add(p, q);
        }
        let u = shifted.unshifted(a);
        // Sums reach ~1e4 (coordinates ~20 m, 200 points): f64 keeps ~1e-12 relative.
        let close = |x: f64, y: f64| (x - y).abs() <= 1e-9 * x.abs().max(1.0);
        assert!(close(u.sum_p_sq, direct.sum_p_sq) && close(u.sum_q_sq, direct.sum_q_sq));
        assert!(close(u.sum_sq_dist, direct.sum_sq_dist));
        for i in 0..3 {
            for j in 0..3 {
                assert!(close(u.sum_pq[i][j], direct.sum_pq[i][j]), "{i}{j}");
            }
        }
        assert!((u.sum_p - direct.sum_p).length() < 1e-9);
    }

    #[test]
    fn sample_draws_are_distinct_and_seeded() {
        let mut order: Vec<u32> = (0..100).collect();
        let mut rng = SplitMix::new(5);
        let s1 = draw_sample(&mut order, 30, &mut rng).to_vec();
        let mut sorted = s1.clone();
        sorted.sort();
        sorted.dedup();
        assert_eq!(sorted.len(), 30);
        let mut order2: Vec<u32> = (0..100).collect();
        let s2 = draw_sample(&mut order2, 30, &mut SplitMix::new(5)).to_vec();
        assert_eq!(s1, s2);
        assert_eq!(draw_sample(&mut order, 500, &mut rng).len(), 100);
    }
}
