//! Feature-based relocalisation: corners with binary descriptors and their 3-D points,
//! matched between a lost frame and a keyframe, and a rigid pose from the matches by
//! RANSAC over minimal 3-point samples (Arun/Umeyama, `geometry::align`).
//!
//! ICP from a keyframe's pose recovers only within ICP's reach (about 0.25 m and 12
//! degrees on ICL-NUIM). A frame after a longer jump still shows much of what a keyframe
//! saw: matching corners gives a pose from anywhere both views overlap (measured on
//! ICL-NUIM frame 140 against keyframes of frames 1..60, 0.7 m and 34 degrees apart: 110
//! to 170 RANSAC inliers, within about 1 degree and 2-4 cm of the truth), which ICP then
//! refines and the recovery health test checks, as for every relocalisation.
//!
//! The per-pixel work is two kernels with CPU twins: `keypoint_detect` (Harris corners with
//! valid depth, non-maximum suppressed) and `keypoint_describe` (256 box-mean comparisons
//! and the keypoint's camera-frame vertex). The host keeps the [`MAX_FEATURES`] strongest
//! corners, matches descriptors by Hamming distance with Lowe's ratio test, and runs
//! RANSAC with a fixed seed, so both backends and every run make the same choices.

use glam::{DMat4, DVec3};

use crate::layout::{Keypoint, KeypointParams, DESCRIPTOR_WORDS};
use crate::slam::backend::{Backend, ToDescribe};
use crate::Result;
use wgslam_core::seeded::SplitMix;

/// Corners kept per frame (the strongest).
pub const MAX_FEATURES: usize = 500;
/// Room for corner candidates before the strongest are chosen.
pub const KEYPOINT_CAPACITY: u32 = 8192;
/// Harris response a corner must exceed (grey levels `r + g + b`, 0..765, so responses
/// scale by 9² against 0..255 grey): on ICL-NUIM frame 5 at 320x240, 99 corners, enough
/// for the 26-35 RANSAC inliers the jumps here relocalise with.
pub const HARRIS_THRESHOLD: f32 = 1e9;
/// Binary tests per descriptor.
pub const DESCRIPTOR_TESTS: u32 = 256;
/// Offsets of the tests within this many pixels of the keypoint (a 25 x 25 patch at
/// 320x240, ORB's 31 x 31 at 640x480 scaled).
pub const PATCH_RADIUS: i32 = 12;
/// A match's Hamming distance must be below this ...
pub const MAX_HAMMING: u32 = 64;
/// ... and below this fraction of the second best's (Lowe's ratio test).
pub const RATIO: f64 = 0.8;
/// RANSAC: samples drawn, inlier distance (metres), fewest inliers for a pose.
pub const RANSAC_ITERATIONS: usize = 300;
pub const RANSAC_INLIER_M: f64 = 0.05;
pub const MIN_RANSAC_INLIERS: usize = 15;

/// A frame's features: descriptors and their points (camera frame, or world frame for a
/// keyframe's, see [`Features::to_world`]).
#[derive(Debug, Clone, Default)]
pub struct Features {
    pub points: Vec<DVec3>,
    pub descriptors: Vec<[u32; DESCRIPTOR_WORDS]>,
}

/// The descriptor's test pattern: [`DESCRIPTOR_TESTS`] pairs of offsets, uniform in the
/// patch (BRIEF's "G I" sampling), from a fixed seed.
pub fn pattern() -> Vec<[i32; 4]> {
    let mut rng = SplitMix(0xb41e_f0f0_2010_0001);
    let side = (2 * PATCH_RADIUS + 1) as usize;
    let mut offset = || rng.below(side as u64) as i32 - PATCH_RADIUS;
    (0..DESCRIPTOR_TESTS)
        .map(|_| [offset(), offset(), offset(), offset()])
        .collect()
}

/// The current frame's features (after `preprocess`): the strongest [`MAX_FEATURES`]
/// corners with valid vertices, strongest first (ties in raster order), points in the
/// camera frame.
pub fn extract<B: Backend + ?Sized>(
    backend: &mut B,
    width: u32,
    height: u32,
    pattern: &[[i32; 4]],
) -> Result<Features> {
    let mut params = KeypointParams {
        width,
        height,
        threshold: HARRIS_THRESHOLD,
        capacity: KEYPOINT_CAPACITY,
        count: 0,
        tests: pattern.len() as u32,
        _pad0: 0,
        _pad1: 0,
    };
    let (mut keypoints, _found) = backend.detect_keypoints(&params)?;
    keypoints.sort_by(|a: &Keypoint, b: &Keypoint| {
        b.score
            .total_cmp(&a.score)
            .then((a.v, a.u).cmp(&(b.v, b.u)))
    });
    keypoints.truncate(MAX_FEATURES);
    params.count = keypoints.len() as u32;
    let (descriptors, points) = backend.describe_keypoints(ToDescribe {
        params: &params,
        keypoints: &keypoints,
        pattern,
    })?;
    let mut f = Features::default();
    for (d, p) in descriptors.into_iter().zip(points) {
        if p[3] > 0.0 {
            f.points
                .push(DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64));
            f.descriptors.push(d);
        }
    }
    Ok(f)
}

impl Features {
    /// The same features with points moved by `t` (a keyframe's camera to world).
    pub fn to_world(&self, t_cam_to_world: &DMat4) -> Features {
        Features {
            points: self
                .points
                .iter()
                .map(|p| t_cam_to_world.transform_point3(*p))
                .collect(),
            descriptors: self.descriptors.clone(),
        }
    }

    /// Number of features.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// True without features.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }
}

fn hamming(a: &[u32; DESCRIPTOR_WORDS], b: &[u32; DESCRIPTOR_WORDS]) -> u32 {
    a.iter().zip(b).map(|(x, y)| (x ^ y).count_ones()).sum()
}

/// Pairs `(query index, keyframe index)` whose descriptors match: nearest by Hamming
/// distance, below [`MAX_HAMMING`] and [`RATIO`] times the second nearest.
pub fn matches(query: &Features, keyframe: &Features) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    for (i, q) in query.descriptors.iter().enumerate() {
        let (mut best, mut second, mut at) = (u32::MAX, u32::MAX, 0);
        for (j, k) in keyframe.descriptors.iter().enumerate() {
            let d = hamming(q, k);
            if d < best {
                (second, best, at) = (best, d, j);
            } else if d < second {
                second = d;
            }
        }
        if best < MAX_HAMMING && (best as f64) < RATIO * second as f64 {
            out.push((i, at));
        }
    }
    out
}

/// The camera-to-world pose that maps `query`'s camera-frame points onto `keyframe`'s
/// world-frame points, by RANSAC over the descriptor matches, refined on the inliers;
/// with its inlier count, or `None` below [`MIN_RANSAC_INLIERS`].
pub fn estimate_pose(query: &Features, keyframe: &Features) -> Option<(DMat4, usize)> {
    let pairs = matches(query, keyframe);
    if pairs.len() < MIN_RANSAC_INLIERS {
        return None;
    }
    let src: Vec<DVec3> = pairs.iter().map(|&(i, _)| query.points[i]).collect();
    let dst: Vec<DVec3> = pairs.iter().map(|&(_, j)| keyframe.points[j]).collect();
    let inliers_of = |t: &DMat4| -> Vec<usize> {
        (0..src.len())
            .filter(|&k| t.transform_point3(src[k]).distance(dst[k]) < RANSAC_INLIER_M)
            .collect()
    };
    let fit = |idx: &[usize]| {
        let a: Vec<[f64; 3]> = idx.iter().map(|&k| src[k].to_array()).collect();
        let b: Vec<[f64; 3]> = idx.iter().map(|&k| dst[k].to_array()).collect();
        crate::geometry::align::best_rigid_transform(&a, &b)
    };
    let mut rng = SplitMix(0x5a4c_ac01_2016_0001);
    let mut best: Vec<usize> = Vec::new();
    for _ in 0..RANSAC_ITERATIONS {
        let n = src.len() as u64;
        let s = [rng.below(n), rng.below(n), rng.below(n)].map(|k| k as usize);
        if s[0] == s[1] || s[1] == s[2] || s[0] == s[2] {
            continue;
        }
        let Some(t) = fit(&s) else { continue };
        let inliers = inliers_of(&t);
        if inliers.len() > best.len() {
            best = inliers;
        }
    }
    if best.len() < MIN_RANSAC_INLIERS {
        return None;
    }
    let t = fit(&best)?;
    let n = inliers_of(&t).len();
    (n >= MIN_RANSAC_INLIERS).then_some((t, n))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::se3;

    /// Features at known points with distinct descriptors, seen from a pose 0.7 m and 30
    /// degrees away, with a third of the matches wrong: RANSAC recovers the pose.
    #[test]
    fn ransac_recovers_a_far_pose_through_outliers() {
        let mut rng = SplitMix(3);
        let mut unit = || rng.unit_f64();
        let t_cam_to_world = se3::exp(&[0.1, 0.5, -0.05, 0.5, 0.1, -0.45]);
        let (mut query, mut keyframe) = (Features::default(), Features::default());
        for k in 0..120u32 {
            let p_cam = DVec3::new(unit() * 4.0 - 2.0, unit() * 3.0 - 1.5, 1.0 + unit() * 3.0);
            let d = [k.wrapping_mul(2_654_435_761); DESCRIPTOR_WORDS];
            query.points.push(p_cam);
            query.descriptors.push(d);
            // A third of the keyframe's points are elsewhere: wrong matches.
            let wrong = k % 3 == 0;
            let p_world = t_cam_to_world.transform_point3(p_cam)
                + if wrong {
                    DVec3::new(0.5, -0.3, 0.2)
                } else {
                    DVec3::ZERO
                };
            keyframe.points.push(p_world);
            keyframe.descriptors.push(d);
        }
        let (t, n) = estimate_pose(&query, &keyframe).expect("a pose");
        assert_eq!(n, 80);
        assert!(t.abs_diff_eq(t_cam_to_world, 1e-9), "{t:?}");
    }

    /// The pattern is repeatable and inside the patch.
    #[test]
    fn pattern_is_fixed_and_in_the_patch() {
        let p = pattern();
        assert_eq!(p, pattern());
        assert_eq!(p.len(), DESCRIPTOR_TESTS as usize);
        assert!(p.iter().flatten().all(|o| o.abs() <= PATCH_RADIUS));
    }
}
