//! The dense-SLAM frame as a fixed sequence of kernel steps, generic over a [`Backend`].
//!
//! Per frame: `preprocess` (depth -> vertex, optionally bilateral-filtered, then
//! normal-depth and colour maps, then the coarser levels of the ICP pyramid), then for every
//! frame but the first `predict` (render the map at the previous pose into a model
//! vertex/normal map, once per frame so each ICP iteration is O(pixels), not O(map), and
//! subsample it into the pyramid's coarser levels), ICP coarse to fine
//! ([`IcpSettings::level_iters`](crate::slam::params::IcpSettings::level_iters): at each level up to its budget of iterations of
//! `icp_system` + host solve + left-multiplicative update, until the increment test
//! passes), then `fuse` (merge + add, at the finest level), and with
//! [`FusionSettings::unstable_removal`](crate::slam::params::FusionSettings::unstable_removal) (the robust profile) `compact` (remove unstable
//! surfels, move the rest to the front). The pipeline knows steps and parameters, not
//! backends: the CPU twins and the GPU kernels implement [`Backend`], so the same loop runs
//! on both.
//!
//! The ICP pyramid: level 0 is the maps above (the downsampled image); level `l + 1` is
//! level `l` halved (size rounded up), coarse pixel `(u, v)` sampling finer pixel `(2u, 2v)`
//! so its intrinsics are level `l`'s halved ([`Slam::level_intrinsics`]). With one level
//! (the assignment's schedule) no pyramid kernel runs and tracking is today's single-level
//! ICP, bit for bit. The frame side averages depth edge-aware (`pyramid_depth`, then
//! `vertex_to_normal` per level), the model side subsamples (`pyramid_model`); see the twins'
//! headers for why, and [`ROBUST_ICP_LEVEL_ITERS`](crate::slam::params::ROBUST_ICP_LEVEL_ITERS) for the measured schedule.
//!
//! What each step reads and writes. Frame maps are width x height (the downsampled
//! image); the map is one entry per surfel in the packed representation of
//! `common.wgsl` (`position_weight`, `normal_frame`, `color`). The CPU backend
//! (`cpu_backend.rs`) holds them as `Vec`s, the GPU backend (`gpu/backend.rs`) as textures
//! (frame maps and the map) and storage buffers (`index_map`, `assoc`, `partials`,
//! `counter`).
//!
//! | step (kernels) | reads | writes |
//! |---|---|---|
//! | `preprocess` (`depth_to_vertex`, with [`SlamParams::bilateral`] `bilateral_filter`, then `vertex_to_normal`; per coarser level `pyramid_depth` then `vertex_to_normal`) | raw depth (u16), raw RGBA8 | `vertex` (camera frame, unfiltered), `filtered_vertex` (camera frame; only with the filter), `normal_depth` (camera-frame normal, depth in w; from `filtered_vertex` with the filter, else from `vertex`), `color`; per level `l >= 1`: its `vertex` (from level `l - 1`'s normals' source) and `normal_depth` |
//! | `predict` (`project_model` unless the last fusion built the index map at this view, see `FusedView`; `predict_model`; per coarser level `pyramid_model`) | map `position_weight`, `normal_frame`; `t_world_to_cam` of the last pose | `index_map` (packed depth/index per pixel), `pred_vertex`, `pred_normal` (world frame); per level `l >= 1` its `pred_vertex`, `pred_normal` (from level `l - 1`'s) |
//! | `icp_system` (`icp_reduce`), per iteration, at a level | that level's `pred_vertex`, `pred_normal`, `normal_depth`; the current `t_world_to_cam`; the level's intrinsics | the 29-float system (host: [`crate::slam::solve`]; GPU: `partials`, one per workgroup, summed on the host) |
//! | `fuse` (`fuse_merge`, or `fuse_select` + `fuse_merge_chosen` + with a prune scale, on removal frames, `fuse_prune`; then `fuse_flags`, `prefix_sum`, `fuse_add`) | `normal_depth`, `color`; the tracked pose | map (merged in place, duplicates retired, then appended), `assoc` (merged pixels), `merged` (the surfel each pixel merged into, best-candidate association), `index_map` (best candidate: the next prediction's, by `fuse_select` and `fuse_add`), `counter` (surfel count) |
//! | `compact` (`compact_flags`, `prefix_sum`, `compact_scatter`), only with [`FusionSettings::unstable_removal`](crate::slam::params::FusionSettings::unstable_removal) | map `position_weight` (w = weight), `normal_frame` (w = last frame); the frame id | `flags`, `offsets` (GPU: storage buffers of one `u32` per surfel), the second map (compacted; then the two swap), `counter` (surfels kept) |
//!
//! The tracking loop reads back only the system per iteration and the surfel count per
//! frame (twice with `compact`); the `download_*` methods copy maps to the host for outputs and comparisons,
//! and `upload_map` copies a map into the backend (to resume, or to put one backend into another's state).

use glam::DMat4;

use crate::geometry::camera::Intrinsics;
use crate::geometry::se3;
use crate::slam::backend::{Backend, PyramidLevel};
use crate::slam::features;
use crate::slam::health::{HealthMonitor, TrackingHealth};
use crate::slam::keyframes::{KeyframeDatabase, Match};
use crate::slam::loops::{LoopClosure, LoopRecord, Snapshot};
use crate::slam::params::{PoseSource, SlamParams};
use crate::slam::solve::{increment_size, update_pose, NormalEquations};
use crate::Result;

/// One ICP iteration's statistics.
#[derive(Debug, Clone, Copy, serde::Serialize)]
pub struct IcpIteration {
    /// Pyramid level the iteration ran at (0 = the full maps).
    pub level: usize,
    /// Correspondences that passed both filters.
    pub inliers: u64,
    /// Mean squared point-to-plane residual before the update, m².
    pub mean_sq_residual: f64,
    /// Smallest over largest eigenvalue of AᵀA; `None` when the system was refused.
    pub eigen_ratio: Option<f64>,
    /// Eigen-directions the guarded solve held (degenerate geometry).
    pub held_directions: usize,
}

/// How a frame's pose was obtained.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub enum TrackStatus {
    /// The first frame (ground truth or identity) or a ground-truth pose.
    Given,
    /// ICP converged (increment below threshold) at the finest level within its budget.
    Converged,
    /// ICP used all of the finest level's iterations; the last pose is kept.
    MaxIterations,
    /// ICP refused a later system at the finest level; the last good pose is kept. (A
    /// refused system at a coarser level ends that level only; the finer ones go on.)
    Stopped(String),
    /// Tracking from the last pose failed, and ICP from the pose of the keyframe that was
    /// frame `keyframe_frame` passed the health test: the frame is fused there.
    Relocalised { keyframe_frame: u32 },
    /// Tracking lost: ICP refused the first system, or its result failed the health test,
    /// and no relocalisation passed. The frame is not fused and has no tracked pose.
    Lost(String),
    /// No valid depth pixel: skipped, not fused, no tracked pose.
    EmptyDepth,
}

impl TrackStatus {
    /// Whether the frame has a pose the run stands by (written to `trajectory.tum`, fused).
    pub fn is_tracked(&self) -> bool {
        !matches!(self, TrackStatus::Lost(_) | TrackStatus::EmptyDepth)
    }
}

/// One relocalisation attempt: ICP against the map from a keyframe's pose, or from the pose
/// that matching the frame's features with a keyframe's gave.
#[derive(Debug, Clone, serde::Serialize)]
pub struct RelocalisationAttempt {
    /// The keyframe and how alike its fern code is.
    pub keyframe: Match,
    /// RANSAC inliers of the feature matches the start pose came from; `None` when ICP
    /// started from the keyframe's own pose.
    pub feature_inliers: Option<usize>,
    /// The result's health (`None` when ICP refused its first system).
    pub health: Option<TrackingHealth>,
    /// `None` when accepted, else why not.
    pub rejected: Option<String>,
}

/// What the pipeline did with one frame.
#[derive(Debug, Clone, serde::Serialize)]
pub struct FrameReport {
    /// Pose of the camera, camera to world: the tracked pose, or for a frame without one
    /// (lost, empty depth) the last tracked pose, which is not written as this frame's.
    #[serde(skip)]
    pub t_cam_to_world: DMat4,
    pub status: TrackStatus,
    /// ICP iterations of the tracking attempt from the last tracked pose.
    pub iterations: Vec<IcpIteration>,
    /// The health of that attempt (`None` for a given pose or without the test).
    pub health: Option<TrackingHealth>,
    /// Relocalisation attempts after it failed, in order (empty when none were made).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub relocalisation: Vec<RelocalisationAttempt>,
    /// Whether the frame became a relocalisation keyframe.
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub keyframe: bool,
    /// Loop candidates verified at this frame, accepted or rejected (empty when none).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub loops: Vec<LoopRecord>,
    /// Surfels after fusing this frame.
    pub surfels: usize,
}

/// Keyframes whose features a lost frame is matched against: the most fern-alike ones.
pub const FEATURE_KEYFRAMES: usize = 30;
/// ICP from the features' pose must end within this of it (metres, degrees): RANSAC's
/// poses were measured within 1-5 cm and about 1 degree of the truth on ICL-NUIM, ICP's
/// basin is about 0.25 m / 12 degrees, so a result farther away went somewhere else.
pub const FEATURE_ICP_AGREEMENT_M: f64 = 0.10;
pub const FEATURE_ICP_AGREEMENT_DEG: f64 = 5.0;

/// How ICP at one pyramid level ended ([`Slam::icp_level`]).
enum LevelEnd {
    /// The increment test passed.
    Converged,
    /// The level's budget of iterations ran out.
    MaxIterations,
    /// A system was refused (why); the last good pose is kept.
    Refused(String),
}

/// One ICP run from a start pose and what the health test made of it.
struct Attempt {
    t_world_to_cam: DMat4,
    status: TrackStatus,
    iterations: Vec<IcpIteration>,
    health: Option<TrackingHealth>,
    /// `Err(why)` when ICP refused its first system or the health test failed.
    verdict: std::result::Result<(), String>,
}

/// Drives a backend frame by frame; holds the pose, the tracking health's running values
/// and the relocalisation keyframe database.
pub struct Slam<B: Backend> {
    pub backend: B,
    pub params: SlamParams,
    /// Intrinsics of the raw frames.
    pub raw_intrinsics: Intrinsics,
    /// Intrinsics of the (downsampled) maps.
    pub intrinsics: Intrinsics,
    /// Last tracked world-to-camera pose, `None` before the first frame.
    t_world_to_cam: Option<DMat4>,
    /// Frames processed since the last tracked one (0 right after a tracked frame).
    frames_since_tracked: u32,
    monitor: HealthMonitor,
    keyframes: Option<KeyframeDatabase>,
    /// The keypoint descriptors' test pattern (`slam::features::pattern`).
    pattern: Vec<[i32; 4]>,
    /// Loop closure's state (`None` with `--loop-closure off`).
    loops: Option<LoopClosure>,
}

impl<B: Backend> Slam<B> {
    /// A tracker for `seq`: its raw intrinsics, and its depth scale in place of
    /// `params.input.depth_scale` (the sequence knows its units; this is the one place that
    /// copies them into the parameters).
    pub fn for_sequence(backend: B, seq: &crate::dataset::Sequence, params: SlamParams) -> Self {
        let mut params = params;
        params.input.depth_scale = seq.depth_scale;
        Self::new(backend, seq.intrinsics, params)
    }

    /// A tracker for frames with `raw_intrinsics` and `params.input.depth_scale` as given.
    pub fn new(backend: B, raw_intrinsics: Intrinsics, params: SlamParams) -> Self {
        let intrinsics = raw_intrinsics.downsampled(params.input.downsample.max(1));
        let keyframes = match (&params.health, &params.relocalisation) {
            (Some(_), Some(r)) => Some(KeyframeDatabase::new(r)),
            _ => None,
        };
        // Snapshots at the ICP pyramid's second-coarsest level (160 x 120 with the robust
        // three-level schedule at 320 x 240), the finest with one level.
        let loop_level = params.icp.level_iters.len().saturating_sub(2);
        let loops = match (&keyframes, params.loop_closure) {
            (Some(_), Some(l)) => Some(LoopClosure::new(l, loop_level)),
            _ => None,
        };
        Slam {
            backend,
            params,
            raw_intrinsics,
            intrinsics,
            t_world_to_cam: None,
            frames_since_tracked: 0,
            monitor: HealthMonitor::default(),
            pattern: match keyframes {
                Some(_) => features::pattern(),
                None => vec![],
            },
            keyframes,
            loops,
        }
    }

    /// Processes one raw frame. `gt_cam_to_world` is used for the first frame (and for every
    /// frame with [`PoseSource::GroundTruth`]); `frame_id` is stored in fused surfels.
    pub fn process(
        &mut self,
        frame_id: u32,
        raw_depth: &[u16],
        raw_rgba: &[u32],
        gt_cam_to_world: Option<&DMat4>,
    ) -> Result<FrameReport> {
        let (pp, bp, np) = (
            self.preprocess_params(),
            self.bilateral_params(),
            self.normal_params(),
        );
        let given = match (self.params.poses, self.t_world_to_cam, gt_cam_to_world) {
            (PoseSource::GroundTruth, _, Some(gt)) => Some(se3::inverse_rigid(gt)),
            (PoseSource::GroundTruth, _, None) => {
                return Err(crate::Error::Argument(format!(
                    "--poses gt needs ground truth, and frame {frame_id} has none"
                )))
            }
            (PoseSource::Track, None, gt) => {
                Some(gt.map(se3::inverse_rigid).unwrap_or(DMat4::IDENTITY))
            }
            (PoseSource::Track, Some(_), _) => None,
        };
        if self.params.icp.level_iters.is_empty() {
            return Err(crate::Error::Argument(
                "the ICP schedule (icp.level_iters) needs at least one level".into(),
            ));
        }
        let valid = raw_depth.iter().filter(|&&d| d > 0).count();
        if valid == 0 {
            self.frames_since_tracked += 1;
            return Ok(self.untracked(TrackStatus::EmptyDepth, vec![], None, vec![]));
        }
        let pyramid = self.pyramid_levels();
        self.backend
            .preprocess(&pp, bp.as_ref(), &np, &pyramid, raw_depth, raw_rgba)?;
        let Some(t_prev) = self.t_world_to_cam.filter(|_| given.is_none()) else {
            let t = given.expect("a first frame or a ground-truth pose");
            return self.accept(frame_id, t, TrackStatus::Given, vec![], None, vec![], false);
        };
        let gap = self.frames_since_tracked + 1;
        let first = self.attempt(&pyramid, t_prev, Some(gap))?;
        if first.verdict.is_ok() {
            let motion_counts = gap == 1;
            return self.accept(
                frame_id,
                first.t_world_to_cam,
                first.status,
                first.iterations,
                first.health,
                vec![],
                motion_counts,
            );
        }
        let why = first.verdict.clone().unwrap_err();
        let (relocalised, tried) = self.relocalise(&pyramid)?;
        if let Some((att, keyframe_frame)) = relocalised {
            return self.accept(
                frame_id,
                att.t_world_to_cam,
                TrackStatus::Relocalised { keyframe_frame },
                first.iterations,
                first.health,
                tried,
                false,
            );
        }
        self.frames_since_tracked += 1;
        Ok(self.untracked(
            TrackStatus::Lost(why),
            first.iterations,
            first.health,
            tried,
        ))
    }

    /// The last tracked pose (the next frame's ICP starts from it), `None` before the
    /// first frame.
    pub fn t_world_to_cam(&self) -> Option<DMat4> {
        self.t_world_to_cam
    }

    /// Replaces the last tracked pose: the next frame tracks from `t_world_to_cam` (`None`:
    /// as before the first frame). With [`Inspect::upload_map`], puts this tracker into
    /// another's state (`wgslam compare`'s lockstep mode).
    ///
    /// [`Inspect::upload_map`]: crate::slam::backend::Inspect::upload_map
    pub fn set_t_world_to_cam(&mut self, t_world_to_cam: Option<DMat4>) {
        self.t_world_to_cam = t_world_to_cam;
    }

    /// Loop closure's state: the trajectory as now estimated and the loops found; `None`
    /// without loop closure.
    pub fn loop_closure(&self) -> Option<&LoopClosure> {
        self.loops.as_ref()
    }

    /// Keyframes in the relocalisation database (0 without relocalisation).
    pub fn keyframe_count(&self) -> usize {
        self.keyframes.as_ref().map_or(0, |k| k.len())
    }

    /// Fuses the frame at `t_world_to_cam` (world to camera), records its health, and
    /// offers it to the keyframe database.
    #[allow(clippy::too_many_arguments)]
    fn accept(
        &mut self,
        frame_id: u32,
        t_world_to_cam: DMat4,
        status: TrackStatus,
        iterations: Vec<IcpIteration>,
        health: Option<TrackingHealth>,
        relocalisation: Vec<RelocalisationAttempt>,
        motion_counts: bool,
    ) -> Result<FrameReport> {
        self.t_world_to_cam = Some(t_world_to_cam);
        self.frames_since_tracked = 0;
        self.backend
            .fuse(&self.fuse_params(&t_world_to_cam, frame_id))?;
        if let Some(cp) = self.compact_params(frame_id) {
            self.backend.compact(&cp)?;
        }
        // The health of the pose the frame was fused at: the attempt's from the last pose,
        // or for a relocalised frame the accepted attempt's.
        let fused_health = relocalisation
            .iter()
            .find(|a| a.rejected.is_none())
            .and_then(|a| a.health)
            .or(health);
        if let Some(h) = &fused_health {
            self.monitor.record(h, motion_counts);
        }
        let mut keyframe = false;
        let mut codes = Vec::new();
        if let Some(db) = &self.keyframes {
            let p = db.params(self.intrinsics.width, self.intrinsics.height);
            codes = self.backend.encode_ferns(&p, db.ferns())?;
            let db = self.keyframes.as_mut().expect("checked");
            keyframe = db.add_if_novel(frame_id, t_world_to_cam, &codes);
            if keyframe {
                let (w, h) = (self.intrinsics.width, self.intrinsics.height);
                let f = features::extract(&mut self.backend, w, h, &self.pattern)?;
                let db = self.keyframes.as_mut().expect("checked");
                let index = db.len() - 1;
                db.set_features(index, f.to_world(&se3::inverse_rigid(&t_world_to_cam)));
            }
        }
        let loops = match self.loops.is_some() {
            true => self.close_loops(frame_id, t_world_to_cam, keyframe, &codes)?,
            false => vec![],
        };
        Ok(FrameReport {
            t_cam_to_world: se3::inverse_rigid(&t_world_to_cam),
            status,
            iterations,
            health,
            relocalisation,
            keyframe,
            loops,
            surfels: self.backend.surfel_count(),
        })
    }

    /// Loop closure after a frame was fused at `t_world_to_cam`: records its pose (and a
    /// keyframe's snapshot), and when it searches, verifies its candidates most likely
    /// first until one is accepted; an accepted loop above noise moves the trajectory,
    /// the keyframes, the map and this tracker's pose. Returns the candidates verified.
    fn close_loops(
        &mut self,
        frame_id: u32,
        t_world_to_cam: DMat4,
        keyframe: bool,
        codes: &[u32],
    ) -> Result<Vec<LoopRecord>> {
        let lc = self.loops.as_mut().expect("called with loop closure");
        let level = lc.level();
        let snapshot = match keyframe {
            true => {
                let (vertex, normal_depth) = self.backend.frame_level(level)?;
                Some(Snapshot::new(vertex, normal_depth))
            }
            false => None,
        };
        let lc = self.loops.as_mut().expect("called with loop closure");
        let t_cam_to_world = se3::inverse_rigid(&t_world_to_cam);
        lc.record(frame_id, t_cam_to_world, snapshot);
        let (Some(db), true) = (&self.keyframes, lc.searches(frame_id)) else {
            return Ok(vec![]);
        };
        let candidates = lc.candidates(frame_id, &t_cam_to_world, codes, db);
        let before = lc.loops().len();
        let iters = self.params.loop_closure.map_or(0, |l| l.verify_iterations);
        for c in candidates {
            let lc = self.loops.as_ref().expect("called with loop closure");
            let (vertex, normal) =
                lc.prediction(c.keyframe_frame, &lc.keyframe_pose(c.keyframe_frame));
            self.backend.set_prediction(level, &vertex, &normal)?;
            let mut t = t_world_to_cam;
            let mut iterations = Vec::new();
            let refused = match self.icp_level(level, iters, &mut t, &mut iterations)? {
                LevelEnd::Refused(why) => Some(why),
                _ => None,
            };
            let t_loop = se3::inverse_rigid(&t);
            let lc = self.loops.as_mut().expect("called with loop closure");
            let verdict = lc.judge(frame_id, &c, &iterations, refused, &t_cam_to_world, &t_loop);
            if verdict.is_ok() {
                let db = self.keyframes.as_mut().expect("loop closure has keyframes");
                let (nodes, t_new) = lc.close(frame_id, c.keyframe_frame, &t_loop, db);
                if let Some(nodes) = nodes {
                    self.backend.deform(&nodes)?;
                    self.t_world_to_cam = Some(se3::inverse_rigid(&t_new));
                }
                break;
            }
        }
        let lc = self.loops.as_ref().expect("called with loop closure");
        Ok(lc.loops()[before..].to_vec())
    }

    /// The report of a frame that is not fused (lost or without depth).
    fn untracked(
        &self,
        status: TrackStatus,
        iterations: Vec<IcpIteration>,
        health: Option<TrackingHealth>,
        relocalisation: Vec<RelocalisationAttempt>,
    ) -> FrameReport {
        FrameReport {
            t_cam_to_world: se3::inverse_rigid(&self.t_world_to_cam.unwrap_or(DMat4::IDENTITY)),
            status,
            iterations,
            health,
            relocalisation,
            keyframe: false,
            loops: vec![],
            surfels: self.backend.surfel_count(),
        }
    }

    /// ICP from `t_start` and the health test of its result (`motion_gap`: see
    /// [`HealthMonitor::measure`]).
    fn attempt(
        &mut self,
        pyramid: &[PyramidLevel],
        t_start: DMat4,
        motion_gap: Option<u32>,
    ) -> Result<Attempt> {
        // A recovery: after lost frames, or from a keyframe's pose.
        self.attempt_judged(pyramid, t_start, motion_gap, motion_gap != Some(1))
    }

    /// [`Slam::attempt`] with the choice of the stricter recovery test.
    fn attempt_judged(
        &mut self,
        pyramid: &[PyramidLevel],
        t_start: DMat4,
        motion_gap: Option<u32>,
        recovery: bool,
    ) -> Result<Attempt> {
        let (t, status, iterations) = self.track(pyramid, t_start)?;
        let candidates = match status {
            TrackStatus::Lost(_) => None,
            _ => self.candidates_at(&t)?,
        };
        let health = match (&self.params.health, candidates) {
            (Some(s), Some(c)) => self
                .monitor
                .measure(s, &iterations, c, &t_start, &t, motion_gap),
            _ => None,
        };
        let verdict = match (&status, &self.params.health, &health) {
            (TrackStatus::Lost(why), _, _) => Err(why.clone()),
            (_, Some(s), Some(h)) if recovery => self.monitor.judge_recovery(s, h),
            (_, Some(s), Some(h)) => self.monitor.judge(s, h),
            _ => Ok(()),
        };
        Ok(Attempt {
            t_world_to_cam: t,
            status,
            iterations,
            health,
            verdict,
        })
    }

    /// After a failed attempt: ICP from the poses of the keyframes most like this frame,
    /// most alike first, until one passes the health test. Returns the accepted attempt
    /// and its keyframe's frame, and every attempt made.
    #[allow(clippy::type_complexity)]
    fn relocalise(
        &mut self,
        pyramid: &[PyramidLevel],
    ) -> Result<(Option<(Attempt, u32)>, Vec<RelocalisationAttempt>)> {
        let (Some(db), Some(settings)) = (&self.keyframes, &self.params.relocalisation) else {
            return Ok((None, vec![]));
        };
        if db.is_empty() {
            return Ok((None, vec![]));
        }
        let p = db.params(self.intrinsics.width, self.intrinsics.height);
        let codes = self.backend.encode_ferns(&p, db.ferns())?;
        let db = self.keyframes.as_ref().expect("checked");
        let candidates: Vec<(Match, DMat4)> = db
            .nearest(&codes, settings.candidates)
            .into_iter()
            .filter(|m| m.similarity >= settings.min_similarity)
            .map(|m| (m, db.keyframe(m.keyframe).t_world_to_cam))
            .collect();
        let mut tried = Vec::new();
        // Features first: the keyframe whose features give the pose with most RANSAC
        // inliers (among the most fern-alike keyframes), ICP from that pose.
        let ranked = db.nearest(&codes, FEATURE_KEYFRAMES);
        let (w, h) = (self.intrinsics.width, self.intrinsics.height);
        let query = features::extract(&mut self.backend, w, h, &self.pattern)?;
        let db = self.keyframes.as_ref().expect("checked");
        let best = ranked
            .iter()
            .filter_map(|m| {
                let kf = &db.keyframe(m.keyframe).features;
                features::estimate_pose(&query, kf).map(|(t, n)| (*m, t, n))
            })
            .max_by_key(|&(m, _, n)| (n, std::cmp::Reverse(m.keyframe)));
        if let Some((m, t_cam_to_world, n)) = best {
            // Two independent estimates that agree: the features' pose (from anywhere the
            // views overlap) and ICP's from it (dense, against the map). The tracking
            // test applies, not the stricter recovery one, whose residual bound assumes
            // the view overlaps the map as much as during tracking.
            let t_features = se3::inverse_rigid(&t_cam_to_world);
            let mut att = self.attempt_judged(pyramid, t_features, None, false)?;
            if att.verdict.is_ok() {
                let (m_off, deg_off) =
                    crate::slam::health::pose_change(&t_features, &att.t_world_to_cam);
                if m_off > FEATURE_ICP_AGREEMENT_M || deg_off > FEATURE_ICP_AGREEMENT_DEG {
                    att.verdict = Err(format!(
                        "ICP moved {:.0} mm / {deg_off:.1} deg from the features' pose \
                         (limit {:.0} mm / {FEATURE_ICP_AGREEMENT_DEG} deg)",
                        1e3 * m_off,
                        1e3 * FEATURE_ICP_AGREEMENT_M
                    ));
                }
            }
            tried.push(RelocalisationAttempt {
                keyframe: m,
                feature_inliers: Some(n),
                health: att.health,
                rejected: att.verdict.clone().err(),
            });
            if att.verdict.is_ok() {
                return Ok((Some((att, m.frame_id)), tried));
            }
        }
        for (m, t_keyframe) in candidates {
            let att = self.attempt(pyramid, t_keyframe, None)?;
            tried.push(RelocalisationAttempt {
                keyframe: m,
                feature_inliers: None,
                health: att.health,
                rejected: att.verdict.clone().err(),
            });
            if att.verdict.is_ok() {
                return Ok((Some((att, m.frame_id)), tried));
            }
        }
        Ok((None, tried))
    }

    /// Frame-to-model ICP from `t_start`: predict once (every level) at it, then iterate
    /// coarse to fine, each level starting from the pose the coarser one reached.
    fn track(
        &mut self,
        pyramid: &[PyramidLevel],
        t_start: DMat4,
    ) -> Result<(DMat4, TrackStatus, Vec<IcpIteration>)> {
        self.backend
            .predict(&self.project_params(&t_start), pyramid)?;
        let mut t = t_start;
        let mut iterations = Vec::new();
        let mut status = TrackStatus::MaxIterations;
        let schedule = self.params.icp.level_iters.clone();
        for (i, &max_iters) in schedule.iter().enumerate() {
            let level = schedule.len() - 1 - i;
            status = match self.icp_level(level, max_iters, &mut t, &mut iterations)? {
                LevelEnd::Converged => TrackStatus::Converged,
                LevelEnd::MaxIterations => TrackStatus::MaxIterations,
                // The very first system: nothing to start from.
                LevelEnd::Refused(why) if iterations.len() == 1 => {
                    return Ok((t_start, TrackStatus::Lost(why), iterations))
                }
                // A later one: keep the last good pose and go on at the next finer level
                // (at the finest, stop there).
                LevelEnd::Refused(why) => TrackStatus::Stopped(why),
            };
        }
        // The finest level's outcome.
        Ok((t, status, iterations))
    }

    /// Up to `max_iters` ICP iterations at pyramid `level` against its prediction, from
    /// `t` (world to camera), which each solved system updates; each iteration is
    /// appended to `iterations`. Ends at convergence, at the budget, or at a refused
    /// system (`t` then keeps the last good pose).
    fn icp_level(
        &mut self,
        level: usize,
        max_iters: usize,
        t: &mut DMat4,
        iterations: &mut Vec<IcpIteration>,
    ) -> Result<LevelEnd> {
        let guard = self.params.icp.degenerate_eigen_ratio;
        for _ in 0..max_iters {
            let sys = self.backend.icp_system(level, &self.icp_params(level, t))?;
            let eq = NormalEquations::decode(&sys);
            let solved = eq.solve_guarded(guard);
            let (eigen_ratio, held_directions) = match &solved {
                Ok(s) => (Some(s.eigen_ratio), s.held_directions),
                Err(_) => (None, 0),
            };
            iterations.push(IcpIteration {
                level,
                inliers: eq.inliers,
                mean_sq_residual: eq.mean_sq_residual(),
                eigen_ratio,
                held_directions,
            });
            match solved {
                Ok(s) => {
                    *t = update_pose(t, &s.x);
                    let (r, tr) = increment_size(&s.x);
                    let min = self.params.icp.min_increment;
                    if r < min && tr < min {
                        return Ok(LevelEnd::Converged);
                    }
                }
                Err(e) => return Ok(LevelEnd::Refused(e.to_string())),
            }
        }
        Ok(LevelEnd::MaxIterations)
    }

    /// Source pixels that pass filter 1 at level 0 at `t` (`icp_candidates`), for the
    /// health test's inlier fraction; `None` without the test.
    fn candidates_at(&mut self, t: &DMat4) -> Result<Option<u64>> {
        match self.params.health {
            Some(_) => Ok(Some(self.backend.icp_candidates(&self.icp_params(0, t))?)),
            None => Ok(None),
        }
    }
}
