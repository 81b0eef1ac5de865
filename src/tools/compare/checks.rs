//! The bounds a [`Mode`] checks a comparison against, and the checks that name each bound a
//! frame (or the final map) exceeds. The bounds' values and their reasons live in
//! [`tolerance`]; this module only applies them.

use super::{count_rel_diff, tolerance, FrameDiff, MapBounds, Mode, SurfelMapDiff};
use crate::slam::params::SlamParams;

/// The bounds a mode checks each frame (and the map) against; the frame-map bounds are
/// the same in both modes and stay in [`tolerance`].
pub(super) struct Limits {
    system_rel_diff: f64,
    pose_mm: f64,
    pose_deg: f64,
    surfel_count_rel_diff: f64,
    map_match_radius_m: f32,
    map_unmatched_fraction: f64,
    /// Fusion's gates, which bound how far a surfel moves when one decision goes the other
    /// way (see [`tolerance::MAP_UNEXPLAINED_MAX_FRACTION`]).
    map_explain_radius_m: f32,
    map_explain_normal_deg: f32,
    map_unexplained_fraction: f64,
    map_weight_sum_rel_diff: f64,
}

impl Limits {
    /// The map comparison's bounds.
    pub(super) fn map_bounds(&self) -> MapBounds {
        MapBounds {
            match_radius_m: self.map_match_radius_m,
            explain_radius_m: self.map_explain_radius_m,
            explain_normal_deg: self.map_explain_normal_deg,
        }
    }

    /// The bounds of `mode` over a run of `frames` frames with `params`.
    pub(super) fn of(mode: Mode, frames: usize, params: &SlamParams) -> Limits {
        use tolerance::*;
        let fusion = &params.fusion;
        let explain = |l: Limits| Limits {
            map_explain_radius_m: fusion.dist_m + MAP_MATCH_RADIUS_M,
            map_explain_normal_deg: fusion.normal_deg.min(180.0),
            ..l
        };
        explain(match mode {
            Mode::Lockstep { .. } => Limits {
                system_rel_diff: lockstep::SYSTEM_REL_DIFF_MAX,
                pose_mm: lockstep::POSE_MAX_MM,
                pose_deg: lockstep::POSE_MAX_DEG,
                surfel_count_rel_diff: lockstep::SURFEL_COUNT_REL_DIFF_MAX,
                map_match_radius_m: MAP_MATCH_RADIUS_M,
                map_unmatched_fraction: lockstep::MAP_UNMATCHED_MAX_FRACTION,
                map_explain_radius_m: 0.0,
                map_explain_normal_deg: 0.0,
                map_unexplained_fraction: MAP_UNEXPLAINED_MAX_FRACTION,
                map_weight_sum_rel_diff: lockstep::MAP_WEIGHT_SUM_REL_DIFF_MAX,
            },
            Mode::Free => Limits {
                system_rel_diff: SYSTEM_REL_DIFF_MAX,
                pose_mm: pose_max_mm(frames),
                pose_deg: pose_max_deg(frames),
                surfel_count_rel_diff: SURFEL_COUNT_REL_DIFF_MAX,
                map_match_radius_m: MAP_MATCH_RADIUS_M,
                map_unmatched_fraction: map_unmatched_max_fraction(frames),
                map_explain_radius_m: 0.0,
                map_explain_normal_deg: 0.0,
                map_unexplained_fraction: MAP_UNEXPLAINED_MAX_FRACTION,
                map_weight_sum_rel_diff: MAP_WEIGHT_SUM_REL_DIFF_MAX,
            },
        })
    }
}

/// "x% / y% of points unmatched within r mm".
fn describe_unmatched(m: &SurfelMapDiff) -> String {
    format!(
        "{:.4}% / {:.4}% of points unmatched within {} mm",
        m.unmatched_a_fraction * 100.0,
        m.unmatched_b_fraction * 100.0,
        m.match_radius_m * 1e3
    )
}

/// Pushes a line per bound `d` exceeds, naming the frame and the stage. `compacts`: the
/// profile removes unstable surfels (otherwise the count after the frame is the fused one).
pub(super) fn check_frame(
    d: &FrameDiff,
    limits: &Limits,
    compacts: bool,
    best_candidate: bool,
    violations: &mut Vec<String>,
) {
    use tolerance::*;
    let i = d.index;
    let mut check = |ok: bool, stage: &str, what: String| {
        if !ok {
            violations.push(format!("frame {i}: {stage}: {what}"));
        }
    };
    check(
        d.maps.vertex_max_abs_m <= VERTEX_MAX_ABS_M,
        "preprocess",
        format!("vertex difference {:.3e} m", d.maps.vertex_max_abs_m),
    );
    check(
        d.maps.normal_max_deg <= NORMAL_MAX_DEG,
        "preprocess",
        format!("normal difference {:.4} deg", d.maps.normal_max_deg),
    );
    check(
        d.maps.validity_mismatch_fraction <= VALIDITY_MISMATCH_MAX_FRACTION,
        "preprocess",
        format!(
            "validity differs on {:.4}% of pixels",
            d.maps.validity_mismatch_fraction * 100.0
        ),
    );
    if let Some(r) = d.system_rel_diff {
        check(
            r <= limits.system_rel_diff,
            "first ICP system",
            format!("relative difference {r:.3e}"),
        );
    }
    let (mm, deg) = (d.pose_diff_mm, d.pose_diff_deg);
    check(
        mm <= limits.pose_mm && deg <= limits.pose_deg,
        "pose after ICP",
        format!("difference {mm:.5} mm, {deg:.6} deg"),
    );
    if let Some((ca, cb)) = d.fused_surfels {
        check(
            count_rel_diff((ca, cb)) <= limits.surfel_count_rel_diff,
            "fusion",
            match d
                .fusion
                .as_ref()
                .and_then(|k| k.first_difference(best_candidate))
            {
                Some(first) => {
                    format!("surfel counts {ca} vs {cb}; first kernel to differ: {first}")
                }
                None => format!("surfel counts {ca} vs {cb}"),
            },
        );
    }
    if compacts || d.fused_surfels.is_none() {
        let (ca, cb) = d.surfels;
        check(
            count_rel_diff((ca, cb)) <= limits.surfel_count_rel_diff,
            if compacts { "compaction" } else { "surfels" },
            format!("surfel counts {ca} vs {cb}"),
        );
    }
    if let Some(c) = &d.decisions {
        check(
            c.within(FUSION_CLEAR_FLIPS_MAX),
            "fusion decisions",
            format!(
                "{} of {} pixels decided the other way clear of the knife edge (largest \
                 margin {:.2e} of the gate); first: {}",
                c.clear_flips,
                c.differing_pixels,
                c.worst_relative_margin,
                c.first.as_deref().unwrap_or("-")
            ),
        );
    }
    if let Some(m) = &d.map {
        check_map(m, limits, &mut |ok, what| {
            check(ok, "map after the frame", what)
        });
    }
}

/// Calls `check(ok, what)` for each bound of a map comparison: every surfel explained by one
/// of the other map's (within fusion's gates), the total weights, and the fraction without
/// a partner within the match radius (the knife-edge decisions).
pub(super) fn check_map(m: &SurfelMapDiff, limits: &Limits, check: &mut dyn FnMut(bool, String)) {
    check(
        m.unexplained_fraction() <= limits.map_unexplained_fraction,
        format!(
            "{:.4}% / {:.4}% of surfels with no surfel of the other map within {} mm and {} deg \
             (limit {:.4}%)",
            m.unexplained_a_fraction * 100.0,
            m.unexplained_b_fraction * 100.0,
            m.explain_radius_m * 1e3,
            m.explain_normal_deg,
            limits.map_unexplained_fraction * 100.0
        ),
    );
    check(
        m.weight_sum_rel_diff() <= limits.map_weight_sum_rel_diff,
        format!(
            "total weights {:.1} vs {:.1}: relative difference {:.2e} (limit {:.1e})",
            m.weight_sums.0,
            m.weight_sums.1,
            m.weight_sum_rel_diff(),
            limits.map_weight_sum_rel_diff
        ),
    );
    check(
        m.unmatched_fraction() <= limits.map_unmatched_fraction,
        format!(
            "{} (limit {:.4}%)",
            describe_unmatched(m),
            limits.map_unmatched_fraction * 100.0
        ),
    );
}
