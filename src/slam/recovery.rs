//! Recovery after tracking failed: the relocalisation keyframe database
//! (`slam::keyframes`: fern codes of frames that tracked well, with their features,
//! `slam::features`), the start poses it proposes for a lost frame, and the ICP attempts
//! from them ([`Recovery::relocalise`]). After every fused frame [`Recovery::offer`] encodes
//! its fern code (which loop closure reuses) and keeps it as a keyframe when it is new.
//!
//! A lost frame tries, in order: the pose that matching its features with those of the
//! most fern-alike keyframes gave (the keyframe with most RANSAC inliers), then the poses
//! of the most fern-alike keyframes themselves; the first attempt that passes the health
//! test is accepted (see `docs/tracking-health.md`).

use glam::DMat4;

use crate::geometry::se3;
use crate::slam::backend::Backend;
use crate::slam::features::{self, Features};
use crate::slam::keyframes::{KeyframeDatabase, Match};
use crate::slam::params::RelocalisationSettings;
use crate::slam::report::RelocalisationAttempt;
use crate::slam::tracker::{Attempt, Icp, Start, Tracker};
use crate::Result;

/// Keyframes whose features a lost frame is matched against: the most fern-alike ones.
pub const FEATURE_KEYFRAMES: usize = 30;
/// ICP from the features' pose must end within this of it (metres, degrees): RANSAC's
/// poses were measured within 1-5 cm and about 1 degree of the truth on ICL-NUIM, ICP's
/// basin is about 0.25 m / 12 degrees, so a result farther away went somewhere else.
pub const FEATURE_ICP_AGREEMENT_M: f64 = 0.10;
pub const FEATURE_ICP_AGREEMENT_DEG: f64 = 5.0;

/// The keyframe database and what relocalisation needs besides it.
#[derive(Debug, Clone)]
pub struct Recovery {
    keyframes: KeyframeDatabase,
    settings: RelocalisationSettings,
    /// The keypoint descriptors' test pattern (`slam::features::pattern`).
    pattern: Vec<[i32; 4]>,
    /// Width and height of the level-0 maps (the downsampled image), pixels.
    size: [u32; 2],
}

/// A start pose for a lost frame, and where it came from.
struct Proposal {
    keyframe: Match,
    /// RANSAC inliers when the pose came from matching features, else `None` (the
    /// keyframe's own pose).
    feature_inliers: Option<usize>,
    /// World to camera.
    t_world_to_cam: DMat4,
}

/// What relocalising a lost frame gave.
#[derive(Default)]
pub struct Relocalisation {
    /// The attempt that passed and its keyframe's frame; `None` when none passed.
    pub accepted: Option<(Attempt, u32)>,
    /// Every attempt made, in order.
    pub tried: Vec<RelocalisationAttempt>,
}

/// A fused frame's fern code (one per fern) and whether it became a keyframe.
pub struct Offered {
    pub codes: Vec<u32>,
    pub keyframe: bool,
}

impl Recovery {
    /// An empty database for level-0 maps of `size` (width, height) pixels.
    pub fn new(settings: &RelocalisationSettings, size: [u32; 2]) -> Self {
        Recovery {
            keyframes: KeyframeDatabase::new(settings),
            settings: settings.clone(),
            pattern: features::pattern(),
            size,
        }
    }

    /// The keyframe database.
    pub fn keyframes(&self) -> &KeyframeDatabase {
        &self.keyframes
    }

    /// The keyframe database, to move its keyframes with a loop closure.
    pub fn keyframes_mut(&mut self) -> &mut KeyframeDatabase {
        &mut self.keyframes
    }

    /// The current frame's fern code (`fern_encode` over the backend's level-0 maps).
    fn encode<B: Backend>(&self, backend: &mut B) -> Result<Vec<u32>> {
        let db = &self.keyframes;
        backend.encode_ferns(&db.params(self.size[0], self.size[1]), db.ferns())
    }

    /// The current frame's features (`slam::features::extract`), camera frame.
    fn features<B: Backend>(&self, backend: &mut B) -> Result<Features> {
        features::extract(backend, self.size[0], self.size[1], &self.pattern)
    }

    /// After a failed attempt: ICP (`icp`, judged by `tracker`'s health test) from each
    /// start pose the database proposes, in order, until one passes. The attempt from the
    /// features' pose must also end near it ([`FEATURE_ICP_AGREEMENT_M`],
    /// [`FEATURE_ICP_AGREEMENT_DEG`]).
    pub fn relocalise<B: Backend>(
        &self,
        icp: &mut Icp<'_, B>,
        tracker: &Tracker,
    ) -> Result<Relocalisation> {
        let mut tried = Vec::new();
        for p in self.proposals(icp.backend)? {
            let start = match p.feature_inliers {
                Some(_) => Start::from_features(p.t_world_to_cam),
                None => Start::from_keyframe(p.t_world_to_cam),
            };
            let mut att = tracker.attempt(icp, start)?;
            if p.feature_inliers.is_some() && att.verdict.is_ok() {
                // Two independent estimates that agree: the features' pose (from anywhere
                // the views overlap) and ICP's from it (dense, against the map).
                att.verdict = features_agree(&p.t_world_to_cam, &att.t_world_to_cam);
            }
            tried.push(RelocalisationAttempt {
                keyframe: p.keyframe,
                feature_inliers: p.feature_inliers,
                health: att.health,
                rejected: att.verdict.clone().err(),
            });
            if att.verdict.is_ok() {
                let accepted = Some((att, p.keyframe.frame_id));
                return Ok(Relocalisation { accepted, tried });
            }
        }
        Ok(Relocalisation {
            accepted: None,
            tried,
        })
    }

    /// The start poses for the current (lost) frame, in the order to try them: the pose
    /// from the keyframe whose features give the most RANSAC inliers (among the
    /// [`FEATURE_KEYFRAMES`] most fern-alike), then the poses of the
    /// [`RelocalisationSettings::candidates`] most fern-alike keyframes at least
    /// [`RelocalisationSettings::min_similarity`] alike. None without keyframes.
    fn proposals<B: Backend>(&self, backend: &mut B) -> Result<Vec<Proposal>> {
        let db = &self.keyframes;
        if db.is_empty() {
            return Ok(vec![]);
        }
        let codes = self.encode(backend)?;
        let query = self.features(backend)?;
        let best = db
            .nearest(&codes, FEATURE_KEYFRAMES)
            .into_iter()
            .filter_map(|m| {
                let kf = &db.keyframe(m.keyframe).features;
                features::estimate_pose(&query, kf).map(|(t, n)| (m, t, n))
            })
            .max_by_key(|&(m, _, n)| (n, std::cmp::Reverse(m.keyframe)));
        let from_features = best.map(|(keyframe, t_cam_to_world, n)| Proposal {
            keyframe,
            feature_inliers: Some(n),
            t_world_to_cam: se3::inverse_rigid(&t_cam_to_world),
        });
        let from_keyframes = db
            .nearest(&codes, self.settings.candidates)
            .into_iter()
            .filter(|m| m.similarity >= self.settings.min_similarity)
            .map(|m| Proposal {
                keyframe: m,
                feature_inliers: None,
                t_world_to_cam: db.keyframe(m.keyframe).t_world_to_cam,
            });
        Ok(from_features.into_iter().chain(from_keyframes).collect())
    }

    /// A frame fused at `t_world_to_cam` (world to camera): its fern code, and when it is
    /// unlike every keyframe so far (`KeyframeDatabase::add_if_novel`), it becomes one,
    /// with its features in the world frame.
    pub fn offer<B: Backend>(
        &mut self,
        backend: &mut B,
        frame_id: u32,
        t_world_to_cam: DMat4,
    ) -> Result<Offered> {
        let codes = self.encode(backend)?;
        let keyframe = self
            .keyframes
            .add_if_novel(frame_id, t_world_to_cam, &codes);
        if keyframe {
            let f = self.features(backend)?;
            let index = self.keyframes.len() - 1;
            let t_cam_to_world = se3::inverse_rigid(&t_world_to_cam);
            self.keyframes
                .set_features(index, f.to_world(&t_cam_to_world));
        }
        Ok(Offered { codes, keyframe })
    }
}

/// `Ok` when ICP from the features' pose `t_features` ended at `t_icp` within
/// [`FEATURE_ICP_AGREEMENT_M`] / [`FEATURE_ICP_AGREEMENT_DEG`] of it (world to camera).
fn features_agree(t_features: &DMat4, t_icp: &DMat4) -> std::result::Result<(), String> {
    let (m_off, deg_off) = se3::pose_change(t_features, t_icp);
    if m_off > FEATURE_ICP_AGREEMENT_M || deg_off > FEATURE_ICP_AGREEMENT_DEG {
        return Err(format!(
            "ICP moved {:.0} mm / {deg_off:.1} deg from the features' pose \
             (limit {:.0} mm / {FEATURE_ICP_AGREEMENT_DEG} deg)",
            1e3 * m_off,
            1e3 * FEATURE_ICP_AGREEMENT_M
        ));
    }
    Ok(())
}
