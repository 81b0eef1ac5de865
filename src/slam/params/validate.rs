//! The checks behind [`SlamParams::validate`] (`valid.rs`): every value's range, and the
//! rules between sections, each written once.

use super::*;
use crate::{Error, Result};

impl SlamParams {
    /// Every check of [`SlamParams::validate`], which is the only caller: the parameters
    /// are checked once, when they become [`ValidParams`](super::ValidParams).
    pub(super) fn check(&self) -> Result<()> {
        check_input(&self.input)?;
        if let Some(b) = &self.bilateral {
            check_bilateral(b)?;
        }
        check_icp(&self.icp)?;
        check_gates(&self.normals, &self.icp, &self.fusion)?;
        if let Some(h) = &self.health {
            check_health(h)?;
        }
        if let Some(r) = &self.relocalisation {
            check_relocalisation(r)?;
        }
        if let Some(l) = &self.loop_closure {
            // Loop closure searches the relocalisation keyframes.
            if self.health.is_none() || self.relocalisation.is_none() {
                return fail(
                    "`loop_closure.enabled` needs the keyframe database: `health.enabled` and \
                     `relocalisation.enabled` must be true"
                        .into(),
                );
            }
            check_loop_closure(l)?;
        }
        if let Some(r) = &self.fusion.unstable_removal {
            check_unstable_removal(r)?;
        }
        Ok(())
    }
}

/// An [`Error::Argument`] with `msg`.
fn fail(msg: String) -> Result<()> {
    Err(Error::Argument(msg))
}

/// Finite and above zero.
fn positive(v: f64) -> bool {
    v.is_finite() && v > 0.0
}

/// Finite and not negative (0 turns the setting off).
fn off_or_positive(v: f64) -> bool {
    v.is_finite() && v >= 0.0
}

/// The input section: the downsampling, the depth scale and the depth range.
fn check_input(i: &InputSettings) -> Result<()> {
    check_downsample(i.downsample)?;
    check_depth_scale(i.depth_scale)?;
    if !(i.min_depth_m.is_finite()
        && i.min_depth_m >= 0.0
        && i.max_depth_m.is_finite()
        && i.max_depth_m > i.min_depth_m)
    {
        return fail(format!(
            "`input.min_depth_m` {} and `input.max_depth_m` {} must be a range 0 <= min < max",
            i.min_depth_m, i.max_depth_m
        ));
    }
    Ok(())
}

/// The downsampling (`input.downsample`): the one check of its range, also
/// [`ValidParams::with_downsample`](super::ValidParams::with_downsample)'s.
pub(super) fn check_downsample(downsample: u32) -> Result<()> {
    if downsample == 0 || downsample > MAX_DOWNSAMPLE {
        return fail(format!(
            "`input.downsample` {downsample} must be between 1 and {MAX_DOWNSAMPLE}"
        ));
    }
    Ok(())
}

/// The raw depth units per metre (`input.depth_scale`): the one check of its range, also
/// [`ValidParams::with_depth_scale`](super::ValidParams::with_depth_scale)'s.
pub(super) fn check_depth_scale(depth_scale: f32) -> Result<()> {
    if !positive(depth_scale as f64) {
        return fail(format!(
            "`input.depth_scale` {depth_scale} must be a positive number of raw depth units \
             per metre"
        ));
    }
    Ok(())
}

/// The bilateral filter, when it runs: its window and its sigmas.
fn check_bilateral(b: &BilateralSettings) -> Result<()> {
    if b.radius_px > MAX_BILATERAL_RADIUS {
        return fail(format!(
            "`bilateral.radius_px` {} must be at most {MAX_BILATERAL_RADIUS}",
            b.radius_px
        ));
    }
    if !positive(b.sigma_space_px as f64) {
        return fail(format!(
            "`bilateral.sigma_space_px` {} must be a positive number",
            b.sigma_space_px
        ));
    }
    let (depth, z2) = (b.sigma_depth_m, b.sigma_depth_per_m2);
    if !(depth >= 0.0 && z2 >= 0.0 && depth + z2 > 0.0 && (depth + z2).is_finite()) {
        return fail(format!(
            "`bilateral.sigma_depth_m` {depth} and `bilateral.sigma_depth_per_m2` {z2} \
             must be non-negative numbers, not both zero"
        ));
    }
    Ok(())
}

/// The ICP schedule, its convergence and noise stops and the photometric term.
fn check_icp(icp: &IcpSettings) -> Result<()> {
    let s = &icp.level_iters;
    if s.is_empty()
        || s.len() > MAX_ICP_LEVELS
        || s.iter().any(|&n| n == 0 || n > MAX_ICP_ITERS_PER_LEVEL)
    {
        return fail(format!(
            "`icp.level_iters` {s:?}: want 1 to {MAX_ICP_LEVELS} iteration counts, coarse \
             to fine, each 1 to {MAX_ICP_ITERS_PER_LEVEL} (e.g. 10,5,4)"
        ));
    }
    if icp.pyramid.radius_px > MAX_BILATERAL_RADIUS {
        return fail(format!(
            "`icp.pyramid.radius_px` {} must be at most {MAX_BILATERAL_RADIUS}",
            icp.pyramid.radius_px
        ));
    }
    if !(positive(icp.min_increment) && icp.min_increment >= MIN_ICP_MIN_INCREMENT) {
        return fail(format!(
            "`icp.min_increment` {} must be at least {MIN_ICP_MIN_INCREMENT:e} (smaller \
             changes of a pose are below f64 resolution)",
            icp.min_increment
        ));
    }
    if !(icp.photometric_weight.is_finite() && icp.photometric_weight >= 0.0) {
        return fail(format!(
            "`icp.photometric_weight` {} must be a non-negative number",
            icp.photometric_weight
        ));
    }
    let levels = icp.level_iters.len();
    let photo = &icp.photometric_levels;
    if photo.is_empty() || photo.iter().any(|&l| l >= levels) {
        return fail(format!(
            "`icp.photometric_levels` {photo:?}: want one or more pyramid levels below \
             {levels} (0: the full maps; `icp.level_iters` has {levels}); for no \
             photometric term use `icp.tracking = \"geometric\"`"
        ));
    }
    if !(icp.stop_chi2.is_finite() && icp.stop_chi2 >= 0.0) {
        return fail(format!(
            "`icp.stop_chi2` {} must be a non-negative number (0: off)",
            icp.stop_chi2
        ));
    }
    let bar = icp.photometric_stop_chi2;
    if !(bar.is_finite() && bar >= 0.0) {
        return fail(format!(
            "`icp.photometric_stop_chi2` {bar} must be a non-negative number (0: as \
             `icp.stop_chi2`)"
        ));
    }
    Ok(())
}

/// The association gates and weights of the normals, ICP and fusion.
fn check_gates(normals: &NormalSettings, icp: &IcpSettings, f: &FusionSettings) -> Result<()> {
    for (flag, v) in [
        ("`normals.max_depth_jump_m`", normals.max_depth_jump_m),
        (
            "`icp.pyramid.max_depth_diff_per_m2`",
            icp.pyramid.max_depth_diff_per_m2,
        ),
        ("`icp.dist_m`", icp.dist_m),
        ("`icp.normal_deg`", icp.normal_deg),
        ("`fusion.dist_m`", f.dist_m),
        ("`fusion.normal_deg`", f.normal_deg),
    ] {
        if !positive(v as f64) {
            return fail(format!("{flag} {v} must be positive"));
        }
    }
    let full_res = icp.full_res_normal_deg;
    if !(full_res == 0.0 || positive(full_res as f64)) {
        return fail(format!(
            "`icp.full_res_normal_deg` {full_res} must be positive, or 0 for `icp.normal_deg`'s"
        ));
    }
    let retry = icp.full_res_retry_normal_deg;
    if !(retry == 0.0 || positive(retry as f64)) {
        return fail(format!(
            "`icp.full_res_retry_normal_deg` {retry} must be positive, or 0 for no second attempt"
        ));
    }
    for (flag, v) in [
        ("`icp.huber_m`", icp.huber_m),
        ("`fusion.confidence_sigma`", f.confidence_sigma),
        ("`fusion.prune_scale`", f.prune_scale),
        ("`fusion.dist_confident_m`", f.dist_confident_m),
    ] {
        if !off_or_positive(v as f64) {
            return fail(format!("{flag} {v} must be 0 (off) or positive"));
        }
    }
    if !(icp.degenerate_eigen_ratio.is_finite() && (0.0..1.0).contains(&icp.degenerate_eigen_ratio))
    {
        return fail(format!(
            "`icp.degenerate_eigen_ratio` {} must be 0 (off) or a fraction below 1",
            icp.degenerate_eigen_ratio
        ));
    }
    Ok(())
}

/// The tracking-health thresholds, when the tests run.
fn check_health(h: &HealthSettings) -> Result<()> {
    if !(0.0..=1.0).contains(&h.min_inlier_fraction) {
        return fail(format!(
            "`health.min_inlier_fraction` {} must be a fraction between 0 and 1",
            h.min_inlier_fraction
        ));
    }
    for (flag, v) in [
        ("`health.max_residual_ratio`", h.max_residual_ratio),
        ("`health.max_motion_ratio`", h.max_motion_ratio),
        ("`health.motion_floor_m`", h.motion_floor_m),
        ("`health.motion_floor_deg`", h.motion_floor_deg),
    ] {
        if !positive(v) {
            return fail(format!("{flag} {v} must be positive"));
        }
    }
    Ok(())
}

/// The keyframe database and its ferns, when relocalisation runs.
fn check_relocalisation(r: &RelocalisationSettings) -> Result<()> {
    if r.ferns == 0 || r.ferns > MAX_FERNS {
        return fail(format!(
            "`relocalisation.ferns` {} must be between 1 and {MAX_FERNS}",
            r.ferns
        ));
    }
    for (key, v) in [
        ("`relocalisation.candidates`", r.candidates),
        ("`relocalisation.max_keyframes`", r.max_keyframes),
    ] {
        if v == 0 {
            return fail(format!("{key} must be at least 1"));
        }
    }
    Ok(())
}

/// Loop closure's search, verification and bend settings, when it runs.
fn check_loop_closure(l: &LoopSettings) -> Result<()> {
    for (key, v) in [
        ("`loop_closure.search_every_frames`", l.search_every_frames),
        ("`loop_closure.node_stride`", l.node_stride),
        (
            "`loop_closure.confirm_within_searches`",
            l.confirm_within_searches,
        ),
    ] {
        if v == 0 {
            return fail(format!("{key} must be at least 1"));
        }
    }
    if l.verify_iterations == 0 {
        return fail("`loop_closure.verify_iterations` must be at least 1".into());
    }
    for (key, v) in [
        ("`loop_closure.min_inlier_fraction`", l.min_inlier_fraction),
        ("`loop_closure.max_rms_m`", l.max_rms_m),
        ("`loop_closure.max_correction_m`", l.max_correction_m),
        ("`loop_closure.max_correction_deg`", l.max_correction_deg),
        ("`loop_closure.loop_weight`", l.loop_weight),
        ("`loop_closure.max_left_fraction`", l.max_left_fraction),
        ("`loop_closure.other_edge_slack_m`", l.other_edge_slack_m),
        ("`loop_closure.confirm_agreement_m`", l.confirm_agreement_m),
        (
            "`loop_closure.confirm_agreement_deg`",
            l.confirm_agreement_deg,
        ),
    ] {
        if !positive(v) {
            return fail(format!("{key} {v} must be positive"));
        }
    }
    Ok(())
}

/// The removal of unstable surfels, when it runs.
fn check_unstable_removal(r: &UnstableRemoval) -> Result<()> {
    if !off_or_positive(r.stable_weight as f64) {
        return fail(format!(
            "`fusion.unstable_removal.stable_weight` {} must be 0 (off) or positive",
            r.stable_weight
        ));
    }
    if r.every_frames == 0 {
        return fail("`fusion.unstable_removal.every_frames` must be at least 1".into());
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn both_profiles_are_valid() {
        for profile in [Profile::Assignment, Profile::Robust] {
            SlamParams::profile(profile).validate().unwrap();
        }
    }

    /// Each value out of its range is refused, the error naming the option that sets it.
    #[test]
    fn each_out_of_range_value_names_its_option() {
        fn bilateral(p: &mut SlamParams, f: fn(&mut BilateralSettings)) {
            let mut b = BilateralSettings::default();
            f(&mut b);
            p.bilateral = Some(b);
        }
        fn removal(p: &mut SlamParams, f: fn(&mut UnstableRemoval)) {
            let mut r = UnstableRemoval::default();
            f(&mut r);
            p.fusion.unstable_removal = Some(r);
        }
        type Spoil = fn(&mut SlamParams);
        let cases: [(&str, Spoil); 34] = [
            ("`icp.level_iters`", |p| {
                p.icp.level_iters = vec![MAX_ICP_ITERS_PER_LEVEL + 1]
            }),
            ("`icp.min_increment`", |p| p.icp.min_increment = 1e-300),
            ("`input.downsample`", |p| p.input.downsample = 0),
            ("`input.downsample`", |p| {
                p.input.downsample = MAX_DOWNSAMPLE + 1
            }),
            ("`input.depth_scale`", |p| p.input.depth_scale = 0.0),
            ("`input.min_depth_m`", |p| p.input.min_depth_m = -0.1),
            ("`input.max_depth_m`", |p| p.input.max_depth_m = 0.05),
            ("`input.max_depth_m`", |p| {
                p.input.max_depth_m = f32::INFINITY
            }),
            ("`normals.max_depth_jump_m`", |p| {
                p.normals.max_depth_jump_m = 0.0
            }),
            ("`bilateral.radius_px`", |p| {
                bilateral(p, |b| b.radius_px = MAX_BILATERAL_RADIUS + 1)
            }),
            ("`bilateral.sigma_space_px`", |p| {
                bilateral(p, |b| b.sigma_space_px = 0.0)
            }),
            ("`bilateral.sigma_depth_m`", |p| {
                bilateral(p, |b| b.sigma_depth_m = -0.01)
            }),
            ("`bilateral.sigma_depth_per_m2`", |p| {
                bilateral(p, |b| b.sigma_depth_per_m2 = 0.0)
            }),
            ("`icp.dist_m`", |p| p.icp.dist_m = 0.0),
            ("`icp.full_res_normal_deg`", |p| {
                p.icp.full_res_normal_deg = -30.0
            }),
            ("`icp.full_res_retry_normal_deg`", |p| {
                p.icp.full_res_retry_normal_deg = f32::NAN
            }),
            ("`icp.normal_deg`", |p| p.icp.normal_deg = -20.0),
            ("`icp.huber_m`", |p| p.icp.huber_m = -0.02),
            ("`icp.level_iters`", |p| p.icp.level_iters = vec![]),
            ("`icp.level_iters`", |p| p.icp.level_iters = vec![10, 0, 4]),
            ("`icp.level_iters`", |p| {
                p.icp.level_iters = vec![1; MAX_ICP_LEVELS + 1]
            }),
            ("`icp.min_increment`", |p| p.icp.min_increment = 0.0),
            ("`icp.pyramid.max_depth_diff_per_m2`", |p| {
                p.icp.pyramid.max_depth_diff_per_m2 = f32::NAN
            }),
            ("`fusion.dist_m`", |p| p.fusion.dist_m = -0.05),
            ("`fusion.normal_deg`", |p| {
                p.fusion.normal_deg = f32::INFINITY
            }),
            ("`fusion.confidence_sigma`", |p| {
                p.fusion.confidence_sigma = -1.0
            }),
            ("`fusion.prune_scale`", |p| p.fusion.prune_scale = f32::NAN),
            ("`fusion.unstable_removal.stable_weight`", |p| {
                removal(p, |r| r.stable_weight = -1.0)
            }),
            ("`fusion.unstable_removal.every_frames`", |p| {
                removal(p, |r| r.every_frames = 0)
            }),
            ("`fusion.dist_m`", |p| p.fusion.dist_m = 0.0),
            ("`icp.photometric_levels`", |p| {
                p.icp.photometric_levels = vec![]
            }),
            // A level the schedule does not have (the assignment's one, the robust three).
            ("`icp.photometric_levels`", |p| {
                p.icp.photometric_levels = vec![0, p.icp.level_iters.len()]
            }),
            ("`icp.photometric_stop_chi2`", |p| {
                p.icp.photometric_stop_chi2 = -1.0
            }),
            ("`icp.photometric_stop_chi2`", |p| {
                p.icp.photometric_stop_chi2 = f64::NAN
            }),
        ];
        for profile in [Profile::Assignment, Profile::Robust] {
            for (option, spoil) in cases {
                let mut p = SlamParams::profile(profile);
                spoil(&mut p);
                match p.validate() {
                    Err(Error::Argument(why)) => {
                        assert!(why.contains(option), "{option}: {why}")
                    }
                    other => panic!("{option} ({profile:?}): {other:?}"),
                }
            }
        }
    }

    /// The edges of each range are accepted: zero where it means off, the largest sizes.
    #[test]
    fn range_edges_are_accepted() {
        let mut p = SlamParams::profile(Profile::Robust);
        p.input.downsample = MAX_DOWNSAMPLE;
        p.input.min_depth_m = 0.0;
        p.icp.huber_m = 0.0;
        p.icp.normal_deg = 180.0;
        p.icp.level_iters = vec![1; MAX_ICP_LEVELS];
        p.fusion.confidence_sigma = 0.0;
        p.fusion.prune_scale = 0.0;
        p.bilateral = Some(BilateralSettings {
            radius_px: MAX_BILATERAL_RADIUS,
            ..BilateralSettings::default()
        });
        p.validate().unwrap();
    }
}
