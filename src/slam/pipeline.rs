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
//! (`wgslam_core::cpu_backend`) holds them as `Vec`s, the GPU backend (`wgslam_gpu::backend`) as textures
//! (frame maps and the map) and storage buffers (`index_map`, `assoc`, `partials`,
//! `counter`).
//!
//! | step (kernels) | reads | writes |
//! |---|---|---|
//! | `preprocess` (`depth_to_vertex`, with [`SlamParams::bilateral`](crate::slam::params::SlamParams::bilateral) `bilateral_filter`, then `vertex_to_normal`; per coarser level `pyramid_depth` then `vertex_to_normal`) | raw depth (u16), raw RGBA8 | `vertex` (camera frame, unfiltered), `filtered_vertex` (camera frame; only with the filter), `normal_depth` (camera-frame normal, depth in w; normals from `filtered_vertex` with the filter, else from `vertex`; depth from `vertex` unless `filter_points`), `color`; per level `l >= 1`: its `vertex` (from level `l - 1`'s normals' source) and `normal_depth` |
//! | `predict` (`project_model` unless the last fusion built the index map at this view, see `FusedView`; `predict_model`; per coarser level `pyramid_model`) | map `position_weight`, `normal_frame`; `t_world_to_cam` of the last pose | `index_map` (packed depth/index per pixel), `pred_vertex`, `pred_normal` (world frame); per level `l >= 1` its `pred_vertex`, `pred_normal` (from level `l - 1`'s) |
//! | `icp_system` (`icp_reduce`), per iteration, at a level | that level's `pred_vertex`, `pred_normal`, `normal_depth`; the current `t_world_to_cam`; the level's intrinsics | the 29-float system (host: [`crate::slam::solve`]; GPU: `partials`, one per workgroup, summed on the host) |
//! | `fuse` (`fuse_merge`, or `fuse_select` + `fuse_merge_chosen` + with a prune scale, on removal frames, `fuse_prune`; then `fuse_flags`, the scan (`prefix_sum_reduce`, `prefix_sum_blocks`, `prefix_sum`), `fuse_add`) | `normal_depth`, `color`; the tracked pose | map (merged in place, duplicates retired, then appended), `assoc` (merged pixels), `merged` (the surfel each pixel merged into, best-candidate association), `index_map` (best candidate: the next prediction's, by `fuse_select` and `fuse_add`), `counter` (surfel count) |
//! | `compact` (`compact_flags`, the scan's three kernels, `compact_scatter`), only with [`FusionSettings::unstable_removal`](crate::slam::params::FusionSettings::unstable_removal) | map `position_weight` (w = weight), `normal_frame` (w = last frame); the frame id | `flags`, `offsets` (GPU: storage buffers of one `u32` per surfel), the second map (compacted; then the two swap), `counter` (surfels kept) |
//!
//! The tracking loop reads back only the system per iteration and the surfel count per
//! frame (twice with `compact`); the `download_*` methods copy maps to the host for outputs and comparisons,
//! and `upload_map` copies a map into the backend (to resume, or to put one backend into another's state).
//!
//! [`Slam::process`] tells a frame's story from three parts, each borrowing the backend for
//! its turn: the tracker (`slam::tracker`: ICP from the last pose and its health test), the
//! recovery (`slam::recovery`: the keyframe database, its ferns and features, and
//! relocalisation from them; present with the health test and relocalisation) and the loop
//! closer (`slam::loop_closer`, over `slam::loops`' state; present with loop closure, which
//! needs the recovery's keyframes). What the frame's report holds is in `slam::report`.

use glam::DMat4;

use crate::geometry::camera::Intrinsics;
use crate::geometry::rigid::nearest_rotation;
use crate::geometry::se3;
use crate::slam::backend::{Backend, NextFrame, PyramidLevel};
use crate::slam::health::TrackingHealth;
use crate::slam::loop_closer::{self, FusedFrame};
use crate::slam::loops::{LoopClosure, LoopRecord};
use crate::slam::params::{PoseSource, ValidParams};
use crate::slam::recovery::{Recovery, Relocalisation};
pub use crate::slam::report::{FrameReport, RelocalisationAttempt, TrackStatus, WideGateAttempt};
use crate::slam::solve::IcpIteration;
use crate::slam::step_params::cos_of_gate;
use crate::slam::tracker::{Icp, IcpSteps, Start, Tracker};
use crate::Result;

/// Drives a backend frame by frame through its tracker, recovery and loop closer.
pub struct Slam<B: Backend> {
    pub backend: B,
    /// The parameters every step reads, validated once before the tracker was made.
    pub params: ValidParams,
    /// Intrinsics of the raw frames.
    pub raw_intrinsics: Intrinsics,
    /// Intrinsics of the (downsampled) maps.
    pub intrinsics: Intrinsics,
    tracker: Tracker,
    /// The keyframe database and relocalisation (`None` without the health test or
    /// relocalisation).
    recovery: Option<Recovery>,
    /// Loop closure's state (`None` with `--loop-closure off`, or without the recovery's
    /// keyframes).
    loop_closer: Option<LoopClosure>,
    /// The last frame's number, once one was processed: the next must be greater (the
    /// map's ages, surfel removal's schedule and loop closure's pose graph count forward).
    last_frame: Option<u32>,
    /// Frames preprocessed from images the fusion before them uploaded
    /// ([`Slam::process_before`]).
    frames_uploaded_ahead: u64,
}

/// The pose a frame is fused at and how it was obtained.
struct Accepted {
    /// World to camera.
    t_world_to_cam: DMat4,
    status: TrackStatus,
    /// Whether its motion joins the health test's typical motion: tracked from the
    /// previous frame's pose, one frame on.
    motion_counts: bool,
}

impl Accepted {
    fn new(t_world_to_cam: DMat4, status: TrackStatus, motion_counts: bool) -> Self {
        Accepted {
            t_world_to_cam,
            status,
            motion_counts,
        }
    }
}

/// What tracking made of a frame, less what fusing it adds to the report.
#[derive(Default)]
struct Tracked {
    /// ICP iterations of the attempt from the last tracked pose.
    iterations: Vec<IcpIteration>,
    /// That attempt's health.
    health: Option<TrackingHealth>,
    /// The second attempt with the wider gate after it failed, if one was made.
    wide_gate: Option<WideGateAttempt>,
    /// Relocalisation attempts after those failed.
    relocalisation: Vec<RelocalisationAttempt>,
}

impl Tracked {
    fn new(iterations: Vec<IcpIteration>, health: Option<TrackingHealth>) -> Self {
        Tracked {
            iterations,
            health,
            wide_gate: None,
            relocalisation: vec![],
        }
    }
}

/// What a frame's report says of the map besides its tracking.
struct Fused {
    /// Whether it became a relocalisation keyframe.
    keyframe: bool,
    /// The loops verified at it.
    loops: Vec<LoopRecord>,
    /// The map's size before its fusion ([`FrameReport::surfels_before`]).
    surfels_before: usize,
}

impl<B: Backend> Slam<B> {
    /// A tracker for `seq`: its raw intrinsics, and its depth scale in place of
    /// `params.input.depth_scale` (the sequence knows its units; this is the one place that
    /// copies them into the parameters). An error only for a sequence whose depth scale is
    /// not a positive number (one that `dataset::open` made is).
    pub fn for_sequence(
        backend: B,
        seq: &crate::dataset::Sequence,
        params: ValidParams,
    ) -> Result<Self> {
        let params = params.with_depth_scale(seq.depth_scale)?;
        Ok(Self::new(backend, seq.intrinsics, params))
    }

    /// A tracker for frames with `raw_intrinsics` and `params.input.depth_scale` as given.
    pub fn new(backend: B, raw_intrinsics: Intrinsics, params: ValidParams) -> Self {
        let intrinsics = raw_intrinsics.downsampled(params.input.downsample);
        let size = [intrinsics.width, intrinsics.height];
        let recovery = match (&params.health, &params.relocalisation) {
            (Some(_), Some(r)) => Some(Recovery::new(r, size)),
            _ => None,
        };
        // Snapshots at the ICP pyramid's second-coarsest level (160 x 120 with the robust
        // three-level schedule at 320 x 240), the finest with one level.
        let loop_level = params.icp.level_iters.len().saturating_sub(2);
        let loop_closer = match (&recovery, params.loop_closure) {
            (Some(_), Some(l)) => Some(LoopClosure::new(l, loop_level)),
            _ => None,
        };
        Slam {
            backend,
            params,
            raw_intrinsics,
            intrinsics,
            tracker: Tracker::default(),
            recovery,
            loop_closer,
            last_frame: None,
            frames_uploaded_ahead: 0,
        }
    }

    /// Processes one raw frame. `gt_cam_to_world` is used for the first frame (and for every
    /// frame with [`PoseSource::GroundTruth`]); `frame_id` is stored in fused surfels and
    /// must be greater than the last frame's (else an error, before any work).
    pub fn process(
        &mut self,
        frame_id: u32,
        raw_depth: &[u16],
        raw_rgba: &[u32],
        gt_cam_to_world: Option<&DMat4>,
    ) -> Result<FrameReport> {
        self.process_before(frame_id, raw_depth, raw_rgba, gt_cam_to_world, None)
    }

    /// [`Slam::process`] of a frame that `next` will follow (when the caller already holds
    /// it): a backend that uploads its frames uploads `next`'s images while this frame's
    /// fusion runs, and `next`'s own `process` finds them there (by its `frame_id`, so
    /// `next` must hold the very images that frame will be processed with). The results are
    /// the same as without `next`, whichever frame comes next.
    pub fn process_before(
        &mut self,
        frame_id: u32,
        raw_depth: &[u16],
        raw_rgba: &[u32],
        gt_cam_to_world: Option<&DMat4>,
        next: Option<NextFrame<'_>>,
    ) -> Result<FrameReport> {
        if let Some(last) = self.last_frame.filter(|&last| frame_id <= last) {
            return Err(crate::Error::Argument(format!(
                "frame {frame_id} is not after the last frame, {last}: frames go in order"
            )));
        }
        let given = self.given_pose(frame_id, gt_cam_to_world)?;
        self.last_frame = Some(frame_id);
        if raw_depth.iter().all(|&d| d == 0) {
            self.tracker.missed();
            return self.untracked(TrackStatus::EmptyDepth, Tracked::default());
        }
        let steps = self.preprocess(frame_id, raw_depth, raw_rgba)?;
        let Some(t_last) = self.tracker.t_world_to_cam().filter(|_| given.is_none()) else {
            let t = given.expect("a first frame or a ground-truth pose");
            let accepted = Accepted::new(t, TrackStatus::Given, false);
            return self.accept(frame_id, accepted, Tracked::default(), &steps, next);
        };
        // Track from the last pose.
        let gap = self.tracker.frames_since_tracked() + 1;
        let wide_gate_deg = self.wide_gate_deg();
        let wide_steps;
        let mut icp = Icp {
            backend: &mut self.backend,
            params: &self.params,
            steps: &steps,
        };
        let first = self
            .tracker
            .attempt(&mut icp, Start::from_last(t_last, gap))?;
        let mut tracked = Tracked::new(first.iterations, first.health);
        let Err(why) = first.verdict else {
            let accepted = Accepted::new(first.t_world_to_cam, first.status, gap == 1);
            return self.accept(frame_id, accepted, tracked, &steps, next);
        };
        // Again from the last pose with the wider full-resolution angle gate at level 0.
        if let Some(normal_deg) = wide_gate_deg {
            wide_steps = steps.with_level0_gate(cos_of_gate(normal_deg));
            icp.steps = &wide_steps;
            let second = self
                .tracker
                .attempt(&mut icp, Start::from_last(t_last, gap))?;
            icp.steps = &steps;
            let passed = second.verdict.is_ok();
            tracked.wide_gate = Some(WideGateAttempt {
                normal_deg,
                iterations: second.iterations.len(),
                health: second.health,
                rejected: second.verdict.err(),
            });
            if passed {
                let accepted = Accepted::new(second.t_world_to_cam, second.status, gap == 1);
                return self.accept(frame_id, accepted, tracked, &steps, next);
            }
        }
        // Lost from there: relocalise from the keyframes.
        let relocalised = match &self.recovery {
            Some(recovery) => recovery.relocalise(&mut icp, &self.tracker)?,
            None => Relocalisation::default(),
        };
        tracked.relocalisation = relocalised.tried;
        if let Some((att, keyframe_frame)) = relocalised.accepted {
            let status = TrackStatus::Relocalised { keyframe_frame };
            let accepted = Accepted::new(att.t_world_to_cam, status, false);
            return self.accept(frame_id, accepted, tracked, &steps, next);
        }
        self.tracker.missed();
        self.untracked(TrackStatus::Lost(why), tracked)
    }

    /// The last tracked pose (the next frame's ICP starts from it), `None` before the
    /// first frame.
    pub fn t_world_to_cam(&self) -> Option<DMat4> {
        self.tracker.t_world_to_cam()
    }

    /// Replaces the last tracked pose: the next frame tracks from `t_world_to_cam` (`None`:
    /// as before the first frame). With [`Inspect::upload_map`], puts this tracker into
    /// another's state (`wgslam compare`'s lockstep mode).
    ///
    /// [`Inspect::upload_map`]: crate::slam::backend::Inspect::upload_map
    pub fn set_t_world_to_cam(&mut self, t_world_to_cam: Option<DMat4>) {
        self.tracker.set_t_world_to_cam(t_world_to_cam);
    }

    /// Loop closure's state: the trajectory as now estimated and the loops found; `None`
    /// without loop closure.
    pub fn loop_closure(&self) -> Option<&LoopClosure> {
        self.loop_closer.as_ref()
    }

    /// Frames so far whose images were uploaded while the frame before them fused
    /// ([`Slam::process_before`]; 0 on a backend that does not upload).
    pub fn frames_uploaded_ahead(&self) -> u64 {
        self.frames_uploaded_ahead
    }

    /// Keyframes in the relocalisation database (0 without relocalisation).
    pub fn keyframe_count(&self) -> usize {
        self.recovery.as_ref().map_or(0, |r| r.keyframes().len())
    }

    /// The pose a frame is given rather than tracked (world to camera): with
    /// [`PoseSource::GroundTruth`] every frame's ground truth, else the first frame's
    /// ground truth (or the identity); `None` for a frame to track.
    fn given_pose(&self, frame_id: u32, gt_cam_to_world: Option<&DMat4>) -> Result<Option<DMat4>> {
        match (self.params.poses, self.t_world_to_cam(), gt_cam_to_world) {
            (PoseSource::GroundTruth, _, Some(gt)) => Ok(Some(se3::inverse_rigid(gt))),
            (PoseSource::GroundTruth, _, None) => Err(crate::Error::Argument(format!(
                "--poses gt needs ground truth, and frame {frame_id} has none"
            ))),
            // The start pose's rotation is made orthonormal: 7-Scenes' reference poses are
            // scaled by up to 1e-4, every tracked pose would inherit it, and the angle
            // between two equal poses would read 1 degree (loop closure's corrections).
            (PoseSource::Track, None, gt) => Ok(Some(gt.map_or(DMat4::IDENTITY, |g| {
                let (r, p) = se3::to_rt(g);
                se3::inverse_rigid(&se3::from_rt(nearest_rotation(r), p))
            }))),
            (PoseSource::Track, Some(_), _) => Ok(None),
        }
    }

    /// Runs `preprocess` on a raw frame (on the images the last fusion staged, when they are
    /// this frame's); returns what its ICP reads.
    fn preprocess(
        &mut self,
        frame_id: u32,
        raw_depth: &[u16],
        raw_rgba: &[u32],
    ) -> Result<IcpSteps> {
        let steps = self.preprocess_steps();
        if self.backend.preprocess_staged(&steps, frame_id)? {
            self.frames_uploaded_ahead += 1;
        } else {
            self.backend.preprocess(&steps, raw_depth, raw_rgba)?;
        }
        Ok(self.icp_steps(steps.pyramid))
    }

    /// The kernels' parameters this frame's ICP reads, at the map's present surfel count.
    fn icp_steps(&self, pyramid: Vec<PyramidLevel>) -> IcpSteps {
        // Any pose: each use sets its own (`IcpSteps`).
        let t = DMat4::IDENTITY;
        IcpSteps {
            project: self.project_params(&t),
            icp: (0..self.levels()).map(|l| self.icp_params(l, &t)).collect(),
            pyramid,
        }
    }

    /// Fuses the frame at `t_world_to_cam` (world to camera), staging `next`'s images (see
    /// [`Slam::process_before`]), hands it to the tracker, the recovery (fern code, perhaps
    /// a keyframe) and the loop closer, and reports it.
    fn accept(
        &mut self,
        frame_id: u32,
        accepted: Accepted,
        tracked: Tracked,
        steps: &IcpSteps,
        next: Option<NextFrame<'_>>,
    ) -> Result<FrameReport> {
        let Accepted {
            t_world_to_cam,
            status,
            motion_counts,
        } = accepted;
        // Known without a wait: the ICP read-backs' waits covered the last fusion.
        let surfels_before = self.backend.surfel_count()?;
        self.backend
            .fuse(&self.fuse_params(&t_world_to_cam, frame_id), next)?;
        if let Some(cp) = self.compact_params(frame_id) {
            self.backend.compact(&cp)?;
        }
        // The health of the pose the frame was fused at: the attempt's from the last pose,
        // or the accepted second or relocalisation attempt's.
        let relocalised = tracked.relocalisation.iter().find(|a| a.rejected.is_none());
        let wide = tracked.wide_gate.as_ref().filter(|a| a.rejected.is_none());
        let fused_health = match (relocalised, wide) {
            (Some(a), _) => a.health,
            (None, Some(a)) => a.health,
            (None, None) => tracked.health,
        };
        self.tracker
            .tracked(t_world_to_cam, fused_health.as_ref(), motion_counts);
        let offered = match &mut self.recovery {
            Some(recovery) => Some(recovery.offer(&mut self.backend, frame_id, t_world_to_cam)?),
            None => None,
        };
        let mut loops = vec![];
        if let (Some(lc), Some(recovery), Some(offered)) =
            (&mut self.loop_closer, &mut self.recovery, &offered)
        {
            let mut icp = Icp {
                backend: &mut self.backend,
                params: &self.params,
                steps,
            };
            let frame = FusedFrame {
                frame_id,
                t_world_to_cam,
                offered,
            };
            let closed = loop_closer::close_loops(lc, &mut icp, recovery, frame)?;
            if let Some(t) = closed.t_world_to_cam {
                self.tracker.set_t_world_to_cam(Some(t));
            }
            loops = closed.loops;
        }
        let keyframe = offered.is_some_and(|o| o.keyframe);
        let fused = Fused {
            keyframe,
            loops,
            surfels_before,
        };
        Ok(self.report(&t_world_to_cam, status, tracked, fused))
    }

    /// The report of a frame that is not fused (lost or without depth).
    fn untracked(&mut self, status: TrackStatus, tracked: Tracked) -> Result<FrameReport> {
        let t_world_to_cam = self.tracker.t_world_to_cam().unwrap_or(DMat4::IDENTITY);
        let fused = Fused {
            keyframe: false,
            loops: vec![],
            surfels_before: self.backend.surfel_count()?,
        };
        Ok(self.report(&t_world_to_cam, status, tracked, fused))
    }

    /// A frame's report at `t_world_to_cam`, with its tracking attempts and what its
    /// fusion (or the lack of one) made of it.
    fn report(
        &self,
        t_world_to_cam: &DMat4,
        status: TrackStatus,
        tracked: Tracked,
        fused: Fused,
    ) -> FrameReport {
        let Fused {
            keyframe,
            loops,
            surfels_before,
        } = fused;
        FrameReport {
            t_cam_to_world: se3::inverse_rigid(t_world_to_cam),
            status,
            iterations: tracked.iterations,
            health: tracked.health,
            wide_gate: tracked.wide_gate,
            relocalisation: tracked.relocalisation,
            keyframe,
            loops,
            surfels_before,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::slam::cpu_backend::CpuBackend;
    use crate::slam::fused_view::FusedView;
    use crate::slam::params::Profile;

    /// A CPU pipeline with `profile`'s parameters, for ICL-NUIM's camera.
    fn cpu_slam(profile: Profile) -> Slam<CpuBackend> {
        Slam::new(
            CpuBackend::new(),
            Intrinsics::ICL_NUIM,
            ValidParams::profile(profile),
        )
    }

    /// `predict` reuses a fusion's index map only for the very view it was built at, and
    /// only after best-candidate association (the only one whose `fuse_select` builds it).
    #[test]
    fn fused_view_matches_only_its_own_view() {
        let robust = cpu_slam(Profile::Robust);
        let t = se3::exp(&[0.01, -0.02, 0.03, 0.1, 0.2, -0.3]);
        let view = FusedView::of_fuse(&robust.fuse_params(&t, 5)).expect("best candidate");
        assert!(view.is_view_of(&robust.project_params(&t)));
        let moved = se3::exp(&[0.01, -0.02, 0.03, 0.1, 0.2, -0.3001]);
        assert!(!view.is_view_of(&robust.project_params(&moved)));
        let mut other_size = robust.project_params(&t);
        other_size.camera.width /= 2;
        assert!(!view.is_view_of(&other_size));
        let assignment = cpu_slam(Profile::Assignment);
        assert_eq!(FusedView::of_fuse(&assignment.fuse_params(&t, 5)), None);
    }

    /// The robust profile's ICP angle gate is `icp.full_res_normal_deg` (25 degrees) only
    /// at a level of the sensor's own pixels (`--downsample 1`, level 0), and
    /// `icp.normal_deg` (20) at every coarser level and at the default downsampling; a
    /// second attempt with `icp.full_res_retry_normal_deg` (30) there is made only at full
    /// resolution, and only when that is wider than the first attempt's gate.
    #[test]
    fn the_full_resolution_angle_gates_are_level_zero_at_downsample_one() {
        use crate::slam::params::{
            ROBUST_ICP_FULL_RES_NORMAL_DEG as FULL_RES, ROBUST_ICP_RETRY_NORMAL_DEG as RETRY,
        };
        let slam = |downsample: u32, retry_deg: Option<f32>| {
            let mut p = crate::slam::params::SlamParams::profile(Profile::Robust);
            p.input.downsample = downsample;
            if let Some(deg) = retry_deg {
                p.icp.full_res_retry_normal_deg = deg;
            }
            Slam::new(
                CpuBackend::new(),
                Intrinsics::ICL_NUIM,
                p.validate().unwrap(),
            )
        };
        let gate_deg = |downsample: u32, level: usize| {
            let cos = slam(downsample, None)
                .icp_params(level, &DMat4::IDENTITY)
                .cos_normal_threshold;
            (cos.acos().to_degrees() * 1e3).round() / 1e3
        };
        const { assert!(FULL_RES > 20.0 && RETRY > FULL_RES) };
        assert_eq!(gate_deg(1, 0), FULL_RES);
        assert_eq!(gate_deg(1, 1), 20.0);
        assert_eq!(gate_deg(2, 0), 20.0);
        assert_eq!(slam(1, None).wide_gate_deg(), Some(RETRY));
        assert_eq!(slam(2, None).wide_gate_deg(), None);
        assert_eq!(slam(1, Some(FULL_RES)).wide_gate_deg(), None);
        assert_eq!(slam(1, Some(0.0)).wide_gate_deg(), None);
    }

    /// `IcpSteps` made once per frame give, at any pose and level, exactly the parameters
    /// `project_params` and `icp_params` make at that pose (the pose is the only thing in
    /// them that changes between uses).
    #[test]
    fn icp_steps_at_a_pose_are_the_step_params_at_it() {
        let slam = cpu_slam(Profile::Robust);
        let steps = slam.icp_steps(slam.pyramid_levels());
        assert!(slam.levels() > 1, "the robust profile has a pyramid");
        for x in [
            [0.0; 6],
            [0.01, -0.02, 0.03, 0.1, 0.2, -0.3],
            [0.3, 0.1, -0.2, -1.0, 0.5, 2.0],
        ] {
            let t = se3::exp(&x);
            assert_eq!(steps.project_at(&t), slam.project_params(&t));
            for level in 0..slam.levels() {
                assert_eq!(
                    steps.icp_at(level, &t),
                    slam.icp_params(level, &t),
                    "level {level}"
                );
            }
        }
    }
}
