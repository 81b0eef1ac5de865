//! Rigid alignment of paired points for point-to-point ICP: the running sums of inlier
//! pairs ([`CrossCovariance`], reduced in parallel on the CPU or on the GPU) and the closed
//! form best rigid transform they determine (Arun / Umeyama, through
//! [`crate::geometry::rigid::rotation_from_cross_covariance`]).

use glam::{DMat3, DMat4, DVec3};
use nalgebra::Matrix3;

use crate::geometry::rigid::rotation_from_cross_covariance;
use crate::geometry::se3;

/// Sums over inlier pairs `(p, q)` (p: transformed source, q: target) that determine the
/// best rigid transform: the 3x3 cross-covariance and centroids, in f64.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct CrossCovariance {
    /// Number of pairs.
    pub count: usize,
    /// Sum of p (metres).
    pub sum_p: DVec3,
    /// Sum of q (metres).
    pub sum_q: DVec3,
    /// Sum of the outer products `p q^T` (m^2), `sum_pq[i][j] = sum p_i q_j`.
    pub sum_pq: [[f64; 3]; 3],
    /// Sum of squared pair distances `|p - q|^2` (m^2).
    pub sum_sq_dist: f64,
    /// Sum of `|p|^2` (m^2), for [`CrossCovariance::noise_floor`].
    pub sum_p_sq: f64,
    /// Sum of `|q|^2` (m^2), for [`CrossCovariance::noise_floor`].
    pub sum_q_sq: f64,
}

impl CrossCovariance {
    /// Adds one pair.
    pub fn add(&mut self, p: DVec3, q: DVec3) {
        self.count += 1;
        self.sum_p += p;
        self.sum_q += q;
        let (pa, qa) = (p.to_array(), q.to_array());
        for (i, row) in self.sum_pq.iter_mut().enumerate() {
            for (j, v) in row.iter_mut().enumerate() {
                *v += pa[i] * qa[j];
            }
        }
        self.sum_sq_dist += (p - q).length_squared();
        self.sum_p_sq += p.length_squared();
        self.sum_q_sq += q.length_squared();
    }

    /// Sum of two partial reductions.
    pub fn merge(mut self, o: &CrossCovariance) -> CrossCovariance {
        self.count += o.count;
        self.sum_p += o.sum_p;
        self.sum_q += o.sum_q;
        for i in 0..3 {
            for j in 0..3 {
                self.sum_pq[i][j] += o.sum_pq[i][j];
            }
        }
        self.sum_sq_dist += o.sum_sq_dist;
        self.sum_p_sq += o.sum_p_sq;
        self.sum_q_sq += o.sum_q_sq;
        self
    }

    /// The rigid transform `T` minimising `sum |T p - q|^2` (Arun 1987 / Umeyama 1991
    /// without scale), or `None` when fewer than 3 pairs or the p's lie on a line / point.
    pub fn solve(&self) -> Option<DMat4> {
        if self.count < 3 {
            return None;
        }
        let n = self.count as f64;
        let cp = self.sum_p / n;
        let cq = self.sum_q / n;
        let (cpa, cqa) = (cp.to_array(), cq.to_array());
        // Centred cross-covariance H = sum (p - cp)(q - cq)^T = sum p q^T - n cp cq^T.
        let h = Matrix3::from_fn(|i, j| self.sum_pq[i][j] - n * cpa[i] * cqa[j]);
        let r = rotation_from_cross_covariance(&h)?;
        Some(se3::from_rt(r, cq - r * cp))
    }

    /// Standard errors of an update solved from these pairs, as `(rotation radians,
    /// translation metres)`: `sigma / sqrt(n)` over the lever arm (RMS distance of the p's
    /// from their centroid) and `sigma / sqrt(n)`, where `sigma` is the RMS residual the
    /// best rigid fit `dT` leaves (`sum |dT p - q|^2 / n`: noise and pairing error, not
    /// the misalignment the update removes). Zero for fewer than 3 pairs.
    pub fn noise_floor(&self, dt: &DMat4) -> (f64, f64) {
        if self.count < 3 {
            return (0.0, 0.0);
        }
        let n = self.count as f64;
        let cp = self.sum_p / n;
        let cq = self.sum_q / n;
        let var_p = (self.sum_p_sq / n - cp.length_squared()).max(0.0);
        let var_q = (self.sum_q_sq / n - cq.length_squared()).max(0.0);
        // tr(R H) / n with H the centred cross-covariance: sum_ij R_ji H_ij.
        let r = DMat3::from_mat4(*dt);
        let (cpa, cqa) = (cp.to_array(), cq.to_array());
        let mut tr_rh = 0.0;
        for (i, row) in self.sum_pq.iter().enumerate() {
            for (j, s) in row.iter().enumerate() {
                let h = s / n - cpa[i] * cqa[j];
                tr_rh += r.col(i)[j] * h;
            }
        }
        let sigma = (var_p + var_q - 2.0 * tr_rh).max(0.0).sqrt();
        let se = sigma / n.sqrt();
        let spread = var_p.sqrt();
        (if spread > 0.0 { se / spread } else { 0.0 }, se)
    }

    /// These sums for points `p + a`, `q + a`, given sums over the shifted `p`, `q`
    /// (e.g. GPU partials accumulated relative to an anchor `a`, metres).
    pub fn unshifted(&self, a: DVec3) -> CrossCovariance {
        let n = self.count as f64;
        let (sp, sq, aa) = (self.sum_p.to_array(), self.sum_q.to_array(), a.to_array());
        let mut sum_pq = self.sum_pq;
        for (i, row) in sum_pq.iter_mut().enumerate() {
            for (j, v) in row.iter_mut().enumerate() {
                *v += sp[i] * aa[j] + aa[i] * sq[j] + n * aa[i] * aa[j];
            }
        }
        CrossCovariance {
            count: self.count,
            sum_p: self.sum_p + n * a,
            sum_q: self.sum_q + n * a,
            sum_pq,
            sum_sq_dist: self.sum_sq_dist,
            sum_p_sq: self.sum_p_sq + 2.0 * a.dot(self.sum_p) + n * a.length_squared(),
            sum_q_sq: self.sum_q_sq + 2.0 * a.dot(self.sum_q) + n * a.length_squared(),
        }
    }

    /// Root mean square pair distance (metres); NaN with no pairs.
    pub fn rmse(&self) -> f64 {
        (self.sum_sq_dist / self.count as f64).sqrt()
    }
}

/// Best rigid transform mapping `src[i]` onto `dst[i]` (least squares, Arun / Umeyama with
/// the reflection fix); `None` for fewer than 3 pairs or collinear `src`. Always a proper
/// rotation (det = +1), even for planar or mirrored inputs.
pub fn best_rigid_transform(src: &[[f64; 3]], dst: &[[f64; 3]]) -> Option<DMat4> {
    assert_eq!(src.len(), dst.len(), "best_rigid_transform: unpaired input");
    let mut acc = CrossCovariance::default();
    for (p, q) in src.iter().zip(dst) {
        acc.add(DVec3::from_array(*p), DVec3::from_array(*q));
    }
    acc.solve()
}
