//! Order-independent comparison of two surfel maps: each point of one map matched with its
//! nearest point of the other within a radius, through a hash grid, queries in parallel;
//! each surfel explained by one of the other map's within the bounds of one fusion decision
//! taken the other way ([`MapBounds`]); and the maps' total weights.

use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};

use rayon::prelude::*;
use serde::Serialize;

use crate::layout::map::SurfelMap;

/// Order-independent comparison of two surfel maps.
#[derive(Debug, Clone, Serialize)]
pub struct SurfelMapDiff {
    pub surfels: (usize, usize),
    /// The match radius used, metres.
    pub match_radius_m: f32,
    /// Fraction of A's points without a B point within the match radius (and vice versa).
    pub unmatched_a_fraction: f64,
    pub unmatched_b_fraction: f64,
    /// Mean and largest distance to the nearest point of the other map over A's matched
    /// points, metres.
    pub mean_match_m: f64,
    pub max_match_m: f64,
    /// The bounds a surfel is explained within (see [`MapBounds`]).
    pub explain_radius_m: f32,
    pub explain_normal_deg: f32,
    /// Fraction of A's surfels with no B surfel within the explain radius whose normal is
    /// within the explain angle (and vice versa): surfels no knife-edge decision accounts
    /// for.
    pub unexplained_a_fraction: f64,
    pub unexplained_b_fraction: f64,
    /// Sum of the surfels' weights (the confidences fused), A and B.
    pub weight_sums: (f64, f64),
}

impl SurfelMapDiff {
    /// The larger of the two unmatched fractions.
    pub fn unmatched_fraction(&self) -> f64 {
        self.unmatched_a_fraction.max(self.unmatched_b_fraction)
    }

    /// The larger of the two unexplained fractions.
    pub fn unexplained_fraction(&self) -> f64 {
        self.unexplained_a_fraction.max(self.unexplained_b_fraction)
    }

    /// |ΣwA - ΣwB| / ΣwA.
    pub fn weight_sum_rel_diff(&self) -> f64 {
        let (a, b) = self.weight_sums;
        (a - b).abs() / a.max(f64::MIN_POSITIVE)
    }
}

/// How two maps are matched: `match_radius_m` for the position-only match (a surfel both
/// backends fused the same way differs by the pose and rounding differences only), and the
/// bounds within which a surfel is *explained* by one of the other map's when a fusion
/// decision went the other way: `explain_radius_m` (metres) apart and normals within
/// `explain_normal_deg`.
#[derive(Debug, Clone, Copy)]
pub struct MapBounds {
    pub match_radius_m: f32,
    pub explain_radius_m: f32,
    pub explain_normal_deg: f32,
}

/// Fraction of `a`'s surfels with no surfel of `b` within `radius` metres whose normal's
/// cosine with theirs is above `cos_normal`.
pub fn unexplained_fraction(a: &SurfelMap, b: &SurfelMap, radius: f32, cos_normal: f32) -> f64 {
    if a.is_empty() {
        return 0.0;
    }
    let grid = Grid::new(&b.position_weight, 2.0 * radius);
    let r2 = radius * radius;
    let unexplained = (0..a.len())
        .into_par_iter()
        .filter(|&i| {
            let (p, n) = (a.position_weight[i], a.normal(i));
            !grid.any_within_half_cell(&b.position_weight, &p, |j, d2| {
                let m = b.normal(j);
                d2 <= r2 && n[0] * m[0] + n[1] * m[1] + n[2] * m[2] > cos_normal
            })
        })
        .count();
    unexplained as f64 / a.len() as f64
}

/// How `a`'s points match `b`'s within a radius (see [`unmatched_fraction`]).
#[derive(Debug, Clone, Copy, Default)]
pub struct Matches {
    /// Fraction of `a`'s points with no point of `b` within the radius.
    pub unmatched_fraction: f64,
    /// Mean and largest distance to the nearest `b` point over the matched points, metres.
    pub mean_m: f64,
    pub max_m: f64,
}

/// Matches each of `a`'s points with its nearest point of `b` within `radius` metres
/// (through a `Grid` of `b`, queries in parallel).
pub fn unmatched_fraction(a: &SurfelMap, b: &SurfelMap, radius: f32) -> Matches {
    let grid = Grid::new(&b.position_weight, 2.0 * radius);
    let nearest: Vec<f32> = a
        .position_weight
        .par_iter()
        .map(|p| grid.nearest_within_half_cell(&b.position_weight, p))
        .collect();
    let (mut unmatched, mut sum, mut max, mut matched) = (0usize, 0.0f64, 0.0f64, 0usize);
    for d in nearest {
        if d <= radius {
            matched += 1;
            sum += d as f64;
            max = max.max(d as f64);
        } else {
            unmatched += 1;
        }
    }
    Matches {
        unmatched_fraction: unmatched as f64 / a.len().max(1) as f64,
        mean_m: sum / matched.max(1) as f64,
        max_m: max,
    }
}

/// Points bucketed by a uniform grid of cubic cells: their indices sorted by cell, and
/// each occupied cell's range of that order.
struct Grid {
    cell_m: f32,
    order: Vec<u32>,
    ranges: HashMap<u64, (u32, u32), BuildHasherDefault<CellHasher>>,
}

impl Grid {
    fn new(points: &[[f32; 4]], cell_m: f32) -> Grid {
        let mut keyed: Vec<(u64, u32)> = points
            .iter()
            .enumerate()
            .map(|(i, p)| (Self::key(Self::cell(cell_m, p).map(|c| c as i32)), i as u32))
            .collect();
        keyed.sort_unstable();
        let mut ranges = HashMap::with_capacity_and_hasher(keyed.len(), Default::default());
        let mut start = 0;
        for (i, k) in keyed.iter().enumerate() {
            if keyed.get(i + 1).map(|n| n.0) != Some(k.0) {
                ranges.insert(k.0, (start as u32, i as u32 + 1));
                start = i + 1;
            }
        }
        Grid {
            cell_m,
            order: keyed.into_iter().map(|(_, i)| i).collect(),
            ranges,
        }
    }

    /// Cell coordinates of `p` (fractional: the integer part is the cell).
    fn cell(cell_m: f32, p: &[f32; 4]) -> [f32; 3] {
        [p[0] / cell_m, p[1] / cell_m, p[2] / cell_m].map(f32::floor)
    }

    /// One key per cell: 21 bits per coordinate (wrapping, so far-apart cells may share a
    /// key; that only adds candidates, whose distances are computed exactly).
    fn key(c: [i32; 3]) -> u64 {
        let bits = |x: i32| (x as u32 & 0x1f_ffff) as u64;
        bits(c[0]) | bits(c[1]) << 21 | bits(c[2]) << 42
    }

    /// True when some point `j` within half a cell of `p` has `accept(j, squared
    /// distance)` (the 8 cells of [`Self::nearest_within_half_cell`]).
    fn any_within_half_cell(
        &self,
        points: &[[f32; 4]],
        p: &[f32; 4],
        accept: impl Fn(usize, f32) -> bool,
    ) -> bool {
        self.cells_near(p).into_iter().any(|key| {
            self.ranges.get(&key).is_some_and(|&(from, to)| {
                self.order[from as usize..to as usize].iter().any(|&j| {
                    let q = points[j as usize];
                    let d2 = (p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2);
                    accept(j as usize, d2)
                })
            })
        })
    }

    /// Per axis, the cells a ball of half a cell around `p` may overlap: `p`'s own, then
    /// the neighbour on its nearer side.
    fn cells_per_axis(&self, p: &[f32; 4]) -> [[i32; 2]; 3] {
        std::array::from_fn(|a| {
            let c = p[a] / self.cell_m;
            let own = c.floor();
            let other = if c - own < 0.5 { own - 1.0 } else { own + 1.0 };
            [own as i32, other as i32]
        })
    }

    /// Keys of the 8 cells a ball of half a cell around `p` may overlap.
    fn cells_near(&self, p: &[f32; 4]) -> [u64; 8] {
        let [cx, cy, cz] = self.cells_per_axis(p);
        std::array::from_fn(|k| Self::key([cx[k & 1], cy[(k >> 1) & 1], cz[k >> 2]]))
    }

    /// Distance from `p` to its nearest point, exact when it is at most half a cell (else
    /// a larger value or infinity): a ball of half a cell overlaps at most two cells per
    /// axis, `p`'s own and the neighbour on its nearer side, so 8 cells are searched.
    fn nearest_within_half_cell(&self, points: &[[f32; 4]], p: &[f32; 4]) -> f32 {
        let [cx, cy, cz] = self.cells_per_axis(p);
        let mut best = f32::INFINITY;
        for x in cx {
            for y in cy {
                for z in cz {
                    let Some(&(from, to)) = self.ranges.get(&Self::key([x, y, z])) else {
                        continue;
                    };
                    for &j in &self.order[from as usize..to as usize] {
                        let q = points[j as usize];
                        let d2 =
                            (p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2);
                        best = best.min(d2);
                    }
                }
            }
        }
        best.sqrt()
    }
}

/// A multiplicative hash for [`Grid`]'s u64 cell keys (the standard SipHash made the map
/// comparison several times slower; no attacker chooses these keys).
#[derive(Default)]
struct CellHasher(u64);

impl Hasher for CellHasher {
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.write_u64(b as u64);
        }
    }
    fn write_u64(&mut self, x: u64) {
        // MurmurHash3's 64-bit finaliser: every key bit moves every hash bit (the table
        // indexes by the low bits, which a plain multiply fills from the key's low bits only).
        let mut h = self.0 ^ x;
        h = (h ^ (h >> 33)).wrapping_mul(0xff51_afd7_ed55_8ccd);
        h = (h ^ (h >> 33)).wrapping_mul(0xc4ce_b9fe_1a85_ec53);
        self.0 = h ^ (h >> 33);
    }
    fn finish(&self) -> u64 {
        self.0
    }
}

/// Compares two maps both ways within `radius` metres (explained within the same radius
/// and any normal: see [`diff_surfel_maps_within`] for the fusion-aware bounds).
pub fn diff_surfel_maps(a: &SurfelMap, b: &SurfelMap, radius: f32) -> SurfelMapDiff {
    diff_surfel_maps_within(
        a,
        b,
        &MapBounds {
            match_radius_m: radius,
            explain_radius_m: radius,
            explain_normal_deg: 180.0,
        },
    )
}

/// Compares two maps both ways within `bounds`.
pub fn diff_surfel_maps_within(a: &SurfelMap, b: &SurfelMap, bounds: &MapBounds) -> SurfelMapDiff {
    let radius = bounds.match_radius_m;
    let (ab, ba) = (
        unmatched_fraction(a, b, radius),
        unmatched_fraction(b, a, radius),
    );
    let cos = bounds.explain_normal_deg.to_radians().cos();
    let cos = if bounds.explain_normal_deg >= 180.0 {
        -2.0
    } else {
        cos
    };
    let r = bounds.explain_radius_m;
    let weight_sum = |m: &SurfelMap| m.position_weight.iter().map(|p| p[3] as f64).sum::<f64>();
    SurfelMapDiff {
        surfels: (a.len(), b.len()),
        match_radius_m: radius,
        unmatched_a_fraction: ab.unmatched_fraction,
        unmatched_b_fraction: ba.unmatched_fraction,
        mean_match_m: ab.mean_m,
        max_match_m: ab.max_m,
        explain_radius_m: r,
        explain_normal_deg: bounds.explain_normal_deg,
        unexplained_a_fraction: unexplained_fraction(a, b, r, cos),
        unexplained_b_fraction: unexplained_fraction(b, a, r, cos),
        weight_sums: (weight_sum(a), weight_sum(b)),
    }
}
