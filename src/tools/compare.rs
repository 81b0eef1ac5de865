//! Runs two backends over the same frames in lockstep and measures how far apart they are,
//! stage by stage: the frame maps, the first ICP system, the pose, the surfel count and the
//! final map. Used by `wgslam compare` and by the parity tests.
//!
//! Each backend tracks on its own state (as it would in a real run), so differences may
//! grow over frames; the tolerances below are for that end-to-end situation.

use std::collections::HashMap;

use glam::DMat4;
use serde::Serialize;

use crate::dataset::Sequence;
use crate::layout::{ICP_COUNT_INDEX, ICP_SYSTEM_LEN};
use crate::slam::instrumented::Instrumented;
use crate::slam::map::SurfelMap;
use crate::slam::pipeline::{Backend, FrameMaps, Slam, SlamParams};
use crate::slam::solve::NormalEquations;
use crate::tools::run::packed_rgba;
use crate::{geometry::se3, Result};

/// Documented tolerances; `wgslam compare` exits non-zero beyond any of them.
pub mod tolerance {
    /// Vertex maps: the same f32 expression, but GPUs may fuse multiply-adds: a few ulps of
    /// a value of ~5 m is ~1e-6 m.
    pub const VERTEX_MAX_ABS_M: f64 = 1e-5;
    /// Normals: central differences of vertices that differ by ulps, then a normalisation.
    pub const NORMAL_MAX_DEG: f64 = 0.05;
    /// Pixels whose validity differs (a neighbour's depth jump exactly at the threshold).
    pub const VALIDITY_MISMATCH_MAX_FRACTION: f64 = 1e-3;
    /// Relative difference of AᵀA and Aᵀb (see `system_rel_diffs`): f32 partial sums over ~1e5 rows.
    pub const SYSTEM_REL_DIFF_MAX: f64 = 1e-3;
    /// Pose difference per frame (end to end, accumulated over the run).
    pub const POSE_MAX_MM: f64 = 0.1;
    pub const POSE_MAX_DEG: f64 = 0.01;
    /// Surfel counts: pixels at a filter boundary may be merged on one side, added on the other.
    pub const SURFEL_COUNT_REL_DIFF_MAX: f64 = 1e-3;
    /// Map points of one backend farther than this from every point of the other.
    pub const MAP_MATCH_RADIUS_M: f32 = 1e-3;
    /// Fraction of map points allowed to have no match within the radius, for short runs.
    pub const MAP_UNMATCHED_MAX_FRACTION: f64 = 1e-3;
    /// ...and per frame compared, for long ones: a surfel whose projection lands exactly
    /// on a pixel boundary may be moved to the neighbouring pixel by a fused multiply-add
    /// on one backend only, and then averages in a different frame point; such surfels
    /// accumulate over a run. Measured on ICL kt2 (320x240, both backends tracking):
    /// unmatched 0.017 % after 20 frames, 0.062 % after 50, 0.10 % after 100, 0.13 %
    /// after 150, 0.14 % after 200, while within 1 cm only 0.001 % are unmatched after 200
    /// (the maps are the same surface). 2e-5 per frame leaves 1.9x headroom at 100 frames.
    pub const MAP_UNMATCHED_MAX_FRACTION_PER_FRAME: f64 = 2e-5;

    /// The unmatched-fraction limit for a comparison over `frames` frames.
    pub fn map_unmatched_max_fraction(frames: usize) -> f64 {
        MAP_UNMATCHED_MAX_FRACTION.max(MAP_UNMATCHED_MAX_FRACTION_PER_FRAME * frames as f64)
    }
}

/// Differences of two frame maps.
#[derive(Debug, Clone, Default, Serialize)]
pub struct MapDiff {
    /// Largest |a - b| over pixels valid on both sides, metres: the unfiltered vertex maps
    /// and, when both ran the bilateral filter, the filtered ones.
    pub vertex_max_abs_m: f64,
    /// Largest normal angle over pixels valid on both sides, degrees.
    pub normal_max_deg: f64,
    /// Fraction of pixels valid on one side only (vertex or normal).
    pub validity_mismatch_fraction: f64,
}

/// Per-frame differences between backend A (reference) and B.
#[derive(Debug, Clone, Serialize)]
pub struct FrameDiff {
    pub index: usize,
    pub maps: MapDiff,
    /// Relative Frobenius difference of the first ICP iteration's AᵀA and Aᵀb (None on
    /// frames without tracking).
    pub system_rel_diff: Option<f64>,
    /// Inlier counts of the first ICP iteration (A, B).
    pub inliers: Option<(u64, u64)>,
    pub pose_diff_mm: f64,
    pub pose_diff_deg: f64,
    pub surfels: (usize, usize),
}

/// Order-independent comparison of two surfel maps.
#[derive(Debug, Clone, Serialize)]
pub struct SurfelMapDiff {
    pub surfels: (usize, usize),
    /// Fraction of A's points without a B point within the match radius (and vice versa).
    pub unmatched_a_fraction: f64,
    pub unmatched_b_fraction: f64,
    /// Mean distance to the nearest point of the other map over matched points, metres.
    pub mean_match_m: f64,
}

/// The whole comparison.
#[derive(Debug, Clone, Serialize)]
pub struct Comparison {
    pub backends: (String, String),
    pub frames: Vec<FrameDiff>,
    pub map: SurfelMapDiff,
    /// Every tolerance exceeded, in words (empty when the backends agree).
    pub violations: Vec<String>,
}

/// Compares two frame maps (vertex, normal) pixel by pixel.
pub fn diff_frame_maps(a: &FrameMaps, b: &FrameMaps) -> MapDiff {
    let mut d = MapDiff::default();
    let mut mismatched = 0usize;
    let n = a.vertex.len().max(1);
    let (normal_a, normal_b) = (a.normal_map(), b.normal_map());
    for i in 0..a.vertex.len() {
        let (va, vb) = (a.vertex[i], b.vertex[i]);
        let (na, nb) = (normal_a[i], normal_b[i]);
        if (va[3] > 0.0) != (vb[3] > 0.0) || (na[3] > 0.0) != (nb[3] > 0.0) {
            mismatched += 1;
        }
        if va[3] > 0.0 && vb[3] > 0.0 {
            for k in 0..3 {
                d.vertex_max_abs_m = d.vertex_max_abs_m.max((va[k] - vb[k]).abs() as f64);
            }
        }
        if na[3] > 0.0 && nb[3] > 0.0 {
            // atan2(|a x b|, a . b): accurate near 0, where acos(dot) has a ~0.03 deg floor
            // for f32 unit vectors.
            let a = glam::DVec3::new(na[0] as f64, na[1] as f64, na[2] as f64);
            let b = glam::DVec3::new(nb[0] as f64, nb[1] as f64, nb[2] as f64);
            let angle = a.cross(b).length().atan2(a.dot(b));
            d.normal_max_deg = d.normal_max_deg.max(angle.to_degrees());
        }
    }
    if a.filtered_vertex.len() == b.filtered_vertex.len() {
        for (fa, fb) in a.filtered_vertex.iter().zip(&b.filtered_vertex) {
            if fa[3] > 0.0 && fb[3] > 0.0 {
                for k in 0..3 {
                    d.vertex_max_abs_m = d.vertex_max_abs_m.max((fa[k] - fb[k]).abs() as f64);
                }
            }
        }
    }
    d.validity_mismatch_fraction = mismatched as f64 / n as f64;
    d
}

/// Relative differences of two 29-entry systems, `(AᵀA, Aᵀb)`, `a` the reference: AᵀA's
/// Frobenius difference over its norm; Aᵀb's difference over the Cauchy-Schwarz bound of
/// its terms, `sqrt(trace(AᵀA) Σb²)`, not over itself, because Aᵀb nearly cancels near the
/// optimum (a tiny denominator would make rounding look like a disagreement).
pub fn system_rel_diffs(a: &[f64; ICP_SYSTEM_LEN], b: &[f64; ICP_SYSTEM_LEN]) -> (f64, f64) {
    let (ea, eb) = (NormalEquations::decode(a), NormalEquations::decode(b));
    let h = (ea.ata - eb.ata).norm() / ea.ata.norm().max(f64::MIN_POSITIVE);
    let bound = (ea.ata.trace() * ea.residual_sq_sum).sqrt();
    let g = (ea.atb - eb.atb).norm() / bound.max(f64::MIN_POSITIVE);
    (h, g)
}

/// The larger of [`system_rel_diffs`]' two.
pub fn system_rel_diff(a: &[f64; ICP_SYSTEM_LEN], b: &[f64; ICP_SYSTEM_LEN]) -> f64 {
    let (h, g) = system_rel_diffs(a, b);
    h.max(g)
}

/// Fraction of `a`'s points with no point of `b` within `radius` metres, and the mean
/// distance of the matched ones. A uniform hash grid with cells of `radius`.
pub fn unmatched_fraction(a: &SurfelMap, b: &SurfelMap, radius: f32) -> (f64, f64) {
    let cell = |p: &[f32; 4]| {
        (
            (p[0] / radius).floor() as i32,
            (p[1] / radius).floor() as i32,
            (p[2] / radius).floor() as i32,
        )
    };
    let mut grid: HashMap<(i32, i32, i32), Vec<u32>> = HashMap::new();
    for (i, p) in b.position_weight.iter().enumerate() {
        grid.entry(cell(p)).or_default().push(i as u32);
    }
    let (mut unmatched, mut sum, mut matched) = (0usize, 0.0f64, 0usize);
    for p in &a.position_weight {
        let c = cell(p);
        let mut best = f32::INFINITY;
        for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    if let Some(ids) = grid.get(&(c.0 + dx, c.1 + dy, c.2 + dz)) {
                        for &j in ids {
                            let q = b.position_weight[j as usize];
                            let d2 = (p[0] - q[0]).powi(2)
                                + (p[1] - q[1]).powi(2)
                                + (p[2] - q[2]).powi(2);
                            best = best.min(d2);
                        }
                    }
                }
            }
        }
        if best.sqrt() <= radius {
            matched += 1;
            sum += best.sqrt() as f64;
        } else {
            unmatched += 1;
        }
    }
    (
        unmatched as f64 / a.len().max(1) as f64,
        sum / matched.max(1) as f64,
    )
}

/// Pose difference of two camera-to-world poses: translation (mm) and rotation (degrees).
pub fn pose_diff(a: &DMat4, b: &DMat4) -> (f64, f64) {
    let e = se3::inverse_rigid(a) * *b;
    (
        se3::translation_norm(&e) * 1e3,
        se3::rotation_angle(&e).to_degrees(),
    )
}

/// Runs `a` (the reference) and `b` over frames `first..=last` and compares them.
pub fn compare<A: Backend, B: Backend>(
    a: A,
    b: B,
    seq: &Sequence,
    first: usize,
    last: usize,
    params: SlamParams,
) -> Result<Comparison> {
    use tolerance::*;
    let names = (a.name().to_string(), b.name().to_string());
    let mut sa = Slam::for_sequence(Instrumented::recording(a), seq, params.clone());
    let mut sb = Slam::for_sequence(Instrumented::recording(b), seq, params);
    let mut frames = Vec::new();
    let mut violations = Vec::new();
    for i in first..=last {
        let raw = seq.load(i)?;
        let rgba = packed_rgba(&raw);
        let gt = seq.frames[i].gt_cam_to_world;
        let ra = sa.process(i as u32, &raw.depth, &rgba, gt.as_ref())?;
        let rb = sb.process(i as u32, &raw.depth, &rgba, gt.as_ref())?;
        let maps = diff_frame_maps(&sa.backend.download_frame()?, &sb.backend.download_frame()?);
        let (first_a, first_b) = (
            sa.backend.frame_systems.first(),
            sb.backend.frame_systems.first(),
        );
        let (system_rel_diff, inliers) = match (first_a, first_b) {
            (Some(x), Some(y)) => (
                Some(system_rel_diff(x, y)),
                Some((x[ICP_COUNT_INDEX] as u64, y[ICP_COUNT_INDEX] as u64)),
            ),
            _ => (None, None),
        };
        let (mm, deg) = pose_diff(&ra.t_cam_to_world, &rb.t_cam_to_world);
        let d = FrameDiff {
            index: i,
            maps,
            system_rel_diff,
            inliers,
            pose_diff_mm: mm,
            pose_diff_deg: deg,
            surfels: (ra.surfels, rb.surfels),
        };
        let mut check = |ok: bool, what: String| {
            if !ok {
                violations.push(format!("frame {i}: {what}"));
            }
        };
        check(
            d.maps.vertex_max_abs_m <= VERTEX_MAX_ABS_M,
            format!("vertex difference {:.3e} m", d.maps.vertex_max_abs_m),
        );
        check(
            d.maps.normal_max_deg <= NORMAL_MAX_DEG,
            format!("normal difference {:.4} deg", d.maps.normal_max_deg),
        );
        check(
            d.maps.validity_mismatch_fraction <= VALIDITY_MISMATCH_MAX_FRACTION,
            format!(
                "validity differs on {:.4}% of pixels",
                d.maps.validity_mismatch_fraction * 100.0
            ),
        );
        if let Some(r) = d.system_rel_diff {
            check(
                r <= SYSTEM_REL_DIFF_MAX,
                format!("ICP system relative difference {r:.3e}"),
            );
        }
        check(
            mm <= POSE_MAX_MM && deg <= POSE_MAX_DEG,
            format!("pose difference {mm:.4} mm, {deg:.5} deg"),
        );
        let (ca, cb) = d.surfels;
        let rel = (ca as f64 - cb as f64).abs() / ca.max(1) as f64;
        check(
            rel <= SURFEL_COUNT_REL_DIFF_MAX,
            format!("surfel counts {ca} vs {cb}"),
        );
        frames.push(d);
    }
    let (ma, mb) = (sa.backend.download_map()?, sb.backend.download_map()?);
    let (ua, mean) = unmatched_fraction(&ma, &mb, MAP_MATCH_RADIUS_M);
    let (ub, _) = unmatched_fraction(&mb, &ma, MAP_MATCH_RADIUS_M);
    let unmatched_max = map_unmatched_max_fraction(frames.len());
    if ua > unmatched_max || ub > unmatched_max {
        violations.push(format!(
            "final map: {:.4}% / {:.4}% of points unmatched within {} mm (limit {:.4}% for {} \
             frames)",
            ua * 100.0,
            ub * 100.0,
            MAP_MATCH_RADIUS_M * 1e3,
            unmatched_max * 100.0,
            frames.len()
        ));
    }
    Ok(Comparison {
        backends: names,
        frames,
        map: SurfelMapDiff {
            surfels: (ma.len(), mb.len()),
            unmatched_a_fraction: ua,
            unmatched_b_fraction: ub,
            mean_match_m: mean,
        },
        violations,
    })
}
