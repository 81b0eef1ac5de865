//! The relocalisation keyframe database: randomised ferns over a small RGB-D image
//! (ElasticFusion's `Ferns`, after Glocker et al., "Real-time RGB-D camera relocalization
//! via randomized ferns for keyframe encoding", TVCG 2015), kept on the host.
//!
//! Each of [`RelocalisationSettings::ferns`] ferns is a random cell of the
//! [`FERN_GRID`](crate::layout::FERN_GRID) and four random thresholds (red, green, blue in
//! 0..255, depth in [`FERN_DEPTH_RANGE_M`]); a frame's code per fern is four bits
//! (`fern_encode`, a kernel with a CPU twin, over the frame's level-0 maps). A frame that
//! tracked well becomes a keyframe when it is unlike every keyframe so far: its
//! dissimilarity to the nearest (the fraction of codes that differ, over the ferns valid in
//! both) is above [`RelocalisationSettings::keyframe_dissimilarity`]. Lookup counts, per
//! keyframe, the ferns whose code equals the query's, through one list of keyframes per fern
//! and code, so it costs the matching entries, not keyframes x ferns.
//!
//! The ferns come from a fixed seed, so every run (and both backends) use the same ones.
//! The database holds per keyframe a pose, one byte per fern (500 B for the default 500
//! ferns) and its features for feature-based relocalisation (`slam::features`: up to 500
//! points and descriptors, 28 KB), at most [`RelocalisationSettings::max_keyframes`] of
//! them (2,000: 57 MB at most); past that no new keyframe is added (logged once), so memory
//! stays bounded on any sequence length.

use glam::DMat4;

use crate::geometry::se3;
use crate::layout::{Fern, FernParams, FERN_GRID, FERN_NO_DEPTH};
use crate::slam::params::RelocalisationSettings;
use wgslam_core::seeded::SplitMix;

/// The depth thresholds' range, metres: ElasticFusion draws them from 0.4 m to its depth
/// cut-off; 4 m covers the indoor range of the sequences here (ICL-NUIM 1.4-5.3 m,
/// 7-Scenes median 1.8 m, SUN3D median 2.2 m).
pub const FERN_DEPTH_RANGE_M: [f32; 2] = [0.4, 4.0];
/// The ferns' seed (any fixed value: runs must be repeatable).
const FERN_SEED: u64 = 0x5eed_fe70_2015_0001;

/// One keyframe: the frame it was, its pose, and its code per fern.
#[derive(Debug, Clone)]
pub struct Keyframe {
    /// Sequence position of the frame.
    pub frame_id: u32,
    /// Its pose, world to camera.
    pub t_world_to_cam: DMat4,
    /// Its code per fern (0..15, or `FERN_NO_DEPTH`).
    codes: Vec<u8>,
    /// Ferns with a valid code.
    valid: u32,
    /// Its corners and descriptors, points in the WORLD frame (`slam::features`); empty
    /// until [`KeyframeDatabase::set_features`].
    pub features: crate::slam::features::Features,
}

/// A keyframe found by [`KeyframeDatabase::nearest`] and how alike it is.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Match {
    /// Index in the database.
    pub keyframe: usize,
    /// Sequence position of the keyframe's frame.
    pub frame_id: u32,
    /// Fraction of the ferns valid in both whose codes are equal (1: the same small image).
    pub similarity: f64,
}

/// The ferns and the keyframes.
#[derive(Debug, Clone)]
pub struct KeyframeDatabase {
    settings: RelocalisationSettings,
    ferns: Vec<Fern>,
    keyframes: Vec<Keyframe>,
    /// `ids[fern * 16 + code]`: the keyframes with that code for that fern.
    ids: Vec<Vec<u32>>,
    /// Whether the "database full" note was logged.
    full_noted: bool,
}

impl KeyframeDatabase {
    /// An empty database with `settings.ferns` ferns from the fixed seed.
    pub fn new(settings: &RelocalisationSettings) -> Self {
        let mut rng = SplitMix(FERN_SEED);
        let ferns = (0..settings.ferns)
            .map(|_| Fern {
                cell_u: rng.below(FERN_GRID[0] as u64) as u32,
                cell_v: rng.below(FERN_GRID[1] as u64) as u32,
                _pad0: 0,
                _pad1: 0,
                threshold: [
                    rng.between(0.0, 255.0),
                    rng.between(0.0, 255.0),
                    rng.between(0.0, 255.0),
                    rng.between(FERN_DEPTH_RANGE_M[0], FERN_DEPTH_RANGE_M[1]),
                ],
            })
            .collect::<Vec<_>>();
        KeyframeDatabase {
            settings: settings.clone(),
            ids: vec![Vec::new(); ferns.len() * 16],
            ferns,
            keyframes: Vec::new(),
            full_noted: false,
        }
    }

    /// The ferns, for `Backend::encode_ferns`.
    pub fn ferns(&self) -> &[Fern] {
        &self.ferns
    }

    /// `fern_encode`'s parameters for level-0 maps of `width` x `height`.
    pub fn params(&self, width: u32, height: u32) -> FernParams {
        FernParams {
            width,
            height,
            cell_width: width.div_ceil(FERN_GRID[0]).max(1),
            cell_height: height.div_ceil(FERN_GRID[1]).max(1),
            fern_count: self.ferns.len() as u32,
            _pad0: 0,
            _pad1: 0,
            _pad2: 0,
        }
    }

    /// Keyframes so far.
    pub fn len(&self) -> usize {
        self.keyframes.len()
    }

    /// True without keyframes.
    pub fn is_empty(&self) -> bool {
        self.keyframes.is_empty()
    }

    /// The keyframe at `index`.
    pub fn keyframe(&self, index: usize) -> &Keyframe {
        &self.keyframes[index]
    }

    /// Per keyframe, the ferns whose code equals `codes`' (valid codes only).
    fn co_occurrences(&self, codes: &[u32]) -> Vec<u32> {
        let mut counts = vec![0u32; self.keyframes.len()];
        for (f, &code) in codes.iter().enumerate() {
            if code < FERN_NO_DEPTH {
                for &k in &self.ids[f * 16 + code as usize] {
                    counts[k as usize] += 1;
                }
            }
        }
        counts
    }

    /// The up to `k` keyframes most like `codes`, most alike first (ties: the older first).
    /// Similarity: equal codes over the smaller of the two frames' valid-code counts, as
    /// ElasticFusion's dissimilarity (1 minus this) uses.
    pub fn nearest(&self, codes: &[u32], k: usize) -> Vec<Match> {
        let valid = codes.iter().filter(|&&c| c < FERN_NO_DEPTH).count() as u32;
        let mut matches: Vec<Match> = self
            .co_occurrences(codes)
            .into_iter()
            .enumerate()
            .map(|(i, equal)| {
                let kf = &self.keyframes[i];
                let denom = valid.min(kf.valid).max(1);
                Match {
                    keyframe: i,
                    frame_id: kf.frame_id,
                    similarity: equal as f64 / denom as f64,
                }
            })
            .collect();
        matches.sort_by(|a, b| {
            b.similarity
                .total_cmp(&a.similarity)
                .then(a.keyframe.cmp(&b.keyframe))
        });
        matches.truncate(k);
        matches
    }

    /// Adds the frame as a keyframe when it has valid codes and is new: unlike every
    /// keyframe so far (dissimilarity to the nearest above the setting), or farther from
    /// every keyframe's pose than [`RelocalisationSettings::keyframe_distance_m`] /
    /// `keyframe_angle_deg` (so keyframes cover the path even where the ferns see little
    /// difference, as on ICL-NUIM's uniformly coloured walls); true when added.
    pub fn add_if_novel(&mut self, frame_id: u32, t_world_to_cam: DMat4, codes: &[u32]) -> bool {
        assert_eq!(codes.len(), self.ferns.len(), "one code per fern");
        let valid = codes.iter().filter(|&&c| c < FERN_NO_DEPTH).count() as u32;
        if valid == 0 {
            return false;
        }
        if let Some(best) = self.nearest(codes, 1).first() {
            let looks_known = 1.0 - best.similarity <= self.settings.keyframe_dissimilarity;
            let s = &self.settings;
            let near_one = self.keyframes.iter().any(|k| {
                let (m, deg) = se3::pose_change(&k.t_world_to_cam, &t_world_to_cam);
                m <= s.keyframe_distance_m && deg <= s.keyframe_angle_deg
            });
            if looks_known && near_one {
                return false;
            }
        }
        if self.keyframes.len() >= self.settings.max_keyframes {
            if !self.full_noted {
                eprintln!(
                    "note: the relocalisation database is full ({} keyframes); frames from \
                     {frame_id} on are not added",
                    self.keyframes.len()
                );
                self.full_noted = true;
            }
            return false;
        }
        let id = self.keyframes.len() as u32;
        for (f, &code) in codes.iter().enumerate() {
            if code < FERN_NO_DEPTH {
                self.ids[f * 16 + code as usize].push(id);
            }
        }
        self.keyframes.push(Keyframe {
            frame_id,
            t_world_to_cam,
            codes: codes.iter().map(|&c| c.min(FERN_NO_DEPTH) as u8).collect(),
            valid,
            features: Default::default(),
        });
        true
    }

    /// Moves every keyframe with a loop closure's correction of its frame
    /// (`correction_of(frame)`: a world-frame transform applied to camera-to-world poses):
    /// its pose and its features' world points.
    pub fn correct(&mut self, correction_of: impl Fn(u32) -> DMat4) {
        for kf in &mut self.keyframes {
            let c = correction_of(kf.frame_id);
            kf.t_world_to_cam *= se3::inverse_rigid(&c);
            for p in &mut kf.features.points {
                *p = c.transform_point3(*p);
            }
        }
    }

    /// Stores the features of the keyframe at `index` (points in the world frame).
    pub fn set_features(&mut self, index: usize, features: crate::slam::features::Features) {
        self.keyframes[index].features = features;
    }
}

impl Keyframe {
    /// Its code per fern.
    pub fn codes(&self) -> impl Iterator<Item = u32> + '_ {
        self.codes.iter().map(|&c| c as u32)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn settings() -> RelocalisationSettings {
        RelocalisationSettings {
            ferns: 100,
            max_keyframes: 3,
            ..RelocalisationSettings::default()
        }
    }

    /// Codes that differ from `base` in the first `n` ferns.
    fn changed(base: &[u32], n: usize) -> Vec<u32> {
        base.iter()
            .enumerate()
            .map(|(i, &c)| if i < n { (c + 1) % 16 } else { c })
            .collect()
    }

    /// A frame like a keyframe is not added; an unlike one is; lookup ranks by equal codes
    /// and ignores ferns without depth; the database stops at its cap.
    #[test]
    fn adds_novel_frames_and_finds_the_nearest() {
        let s = settings();
        let mut db = KeyframeDatabase::new(&s);
        assert_eq!(db.ferns().len(), 100);
        let a: Vec<u32> = (0..100).map(|i| (i * 7 % 16) as u32).collect();
        assert!(db.add_if_novel(1, DMat4::IDENTITY, &a));
        // 20 % of the codes differ: below the dissimilarity threshold, not a keyframe.
        assert!(!db.add_if_novel(2, DMat4::IDENTITY, &changed(&a, 20)));
        let b = changed(&a, 60);
        assert!(db.add_if_novel(3, DMat4::IDENTITY, &b));
        let near = db.nearest(&changed(&b, 10), 2);
        assert_eq!(near[0].frame_id, 3);
        assert!((near[0].similarity - 0.9).abs() < 1e-12, "{near:?}");
        assert_eq!(near[1].frame_id, 1);
        // Ferns without depth count in neither the matches nor the denominator.
        let mut holes = a.clone();
        holes[90..].fill(FERN_NO_DEPTH);
        assert_eq!(db.nearest(&holes, 1)[0].similarity, 1.0);
        assert!(!db.add_if_novel(4, DMat4::IDENTITY, &vec![FERN_NO_DEPTH; 100]));
        // The cap: a third keyframe fits, a fourth does not.
        assert!(db.add_if_novel(5, DMat4::IDENTITY, &changed(&a, 100)));
        let far: Vec<u32> = a.iter().map(|&c| (c + 8) % 16).collect();
        assert!(!db.add_if_novel(6, DMat4::IDENTITY, &far));
        assert_eq!(db.len(), 3);
    }

    /// The ferns are the same in every database (fixed seed), inside the grid and ranges.
    #[test]
    fn ferns_are_repeatable_and_in_range() {
        let a = KeyframeDatabase::new(&settings());
        let b = KeyframeDatabase::new(&settings());
        assert_eq!(a.ferns(), b.ferns());
        for f in a.ferns() {
            assert!(f.cell_u < FERN_GRID[0] && f.cell_v < FERN_GRID[1]);
            assert!(f.threshold[..3].iter().all(|&t| (0.0..255.0).contains(&t)));
            assert!((FERN_DEPTH_RANGE_M[0]..FERN_DEPTH_RANGE_M[1]).contains(&f.threshold[3]));
        }
        let p = a.params(320, 240);
        assert_eq!((p.cell_width, p.cell_height, p.fern_count), (4, 4, 100));
    }
}
