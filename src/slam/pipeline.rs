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
//! | `icp_system` (`icp_reduce`), per iteration, at a level | that level's `pred_vertex`, `pred_normal`, `normal_depth`; the current `t_world_to_cam`; the level's intrinsics | the 30-float system (host: [`crate::slam::solve`]; GPU: `partials`, one per workgroup, summed on the host) |
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
use crate::slam::params::{PoseSource, SlamParams};
use crate::slam::solve::{increment_size, update_pose, NormalEquations, SolveError};
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
    /// ICP refused the first system (at the coarsest level): tracking lost, previous pose
    /// kept, frame not fused.
    Lost(String),
    /// No valid depth pixel: skipped, previous pose kept, frame not fused.
    EmptyDepth,
}

/// What the pipeline did with one frame.
#[derive(Debug, Clone, serde::Serialize)]
pub struct FrameReport {
    /// Pose of the camera, camera to world.
    #[serde(skip)]
    pub t_cam_to_world: DMat4,
    pub status: TrackStatus,
    pub iterations: Vec<IcpIteration>,
    /// Surfels after fusing this frame.
    pub surfels: usize,
}

/// Drives a backend frame by frame; holds the pose and the frame counter.
pub struct Slam<B: Backend> {
    pub backend: B,
    pub params: SlamParams,
    /// Intrinsics of the raw frames.
    pub raw_intrinsics: Intrinsics,
    /// Intrinsics of the (downsampled) maps.
    pub intrinsics: Intrinsics,
    /// Last accepted world-to-camera pose, `None` before the first frame.
    t_world_to_cam: Option<DMat4>,
}

impl<B: Backend> Slam<B> {
    /// A pipeline over `backend` for raw frames with `raw_intrinsics`.
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
        Slam {
            backend,
            params,
            raw_intrinsics,
            intrinsics,
            t_world_to_cam: None,
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
            return Ok(self.report(self.t_world_to_cam, TrackStatus::EmptyDepth, vec![]));
        }
        let pyramid = self.pyramid_levels();
        self.backend
            .preprocess(&pp, bp.as_ref(), &np, &pyramid, raw_depth, raw_rgba)?;
        let (t_world_to_cam, status, iterations) = match given {
            Some(t) => (t, TrackStatus::Given, vec![]),
            None => self.track(&pyramid)?,
        };
        if let TrackStatus::Lost(_) = status {
            return Ok(self.report(self.t_world_to_cam, status, iterations));
        }
        self.t_world_to_cam = Some(t_world_to_cam);
        self.backend
            .fuse(&self.fuse_params(&t_world_to_cam, frame_id))?;
        if let Some(cp) = self.compact_params(frame_id) {
            self.backend.compact(&cp)?;
        }
        Ok(self.report(Some(t_world_to_cam), status, iterations))
    }

    /// The last accepted world-to-camera pose (the next frame's ICP starts from it),
    /// `None` before the first frame.
    pub fn t_world_to_cam(&self) -> Option<DMat4> {
        self.t_world_to_cam
    }

    /// Replaces the last accepted pose: the next frame tracks from `t_world_to_cam` (`None`:
    /// as before the first frame). With [`Backend::upload_map`], puts this tracker into
    /// another's state (`wgslam compare`'s lockstep mode).
    pub fn set_t_world_to_cam(&mut self, t_world_to_cam: Option<DMat4>) {
        self.t_world_to_cam = t_world_to_cam;
    }

    fn report(
        &self,
        t_world_to_cam: Option<DMat4>,
        status: TrackStatus,
        iterations: Vec<IcpIteration>,
    ) -> FrameReport {
        FrameReport {
            t_cam_to_world: se3::inverse_rigid(&t_world_to_cam.unwrap_or(DMat4::IDENTITY)),
            status,
            iterations,
            surfels: self.backend.surfel_count(),
        }
    }

    /// Frame-to-model ICP from the previous pose: predict once (every level), then iterate
    /// coarse to fine, each level starting from the pose the coarser one reached.
    fn track(
        &mut self,
        pyramid: &[PyramidLevel],
    ) -> Result<(DMat4, TrackStatus, Vec<IcpIteration>)> {
        let t_prev = self
            .t_world_to_cam
            .expect("track() is only called after a first frame");
        self.backend
            .predict(&self.project_params(&t_prev), pyramid)?;
        let mut t = t_prev;
        let mut iterations = Vec::new();
        let mut status = TrackStatus::MaxIterations;
        let schedule = self.params.icp.level_iters.clone();
        for (i, &max_iters) in schedule.iter().enumerate() {
            let level = schedule.len() - 1 - i;
            status = TrackStatus::MaxIterations;
            for _ in 0..max_iters {
                let sys = self
                    .backend
                    .icp_system(level, &self.icp_params(level, &t))?;
                let eq = NormalEquations::decode(&sys);
                iterations.push(IcpIteration {
                    level,
                    inliers: eq.inliers,
                    mean_sq_residual: eq.mean_sq_residual(),
                });
                match eq.solve() {
                    Ok(x) => {
                        t = update_pose(&t, &x);
                        let (r, tr) = increment_size(&x);
                        let min = self.params.icp.min_increment;
                        if r < min && tr < min {
                            status = TrackStatus::Converged;
                            break;
                        }
                    }
                    // The very first system: nothing to start from.
                    Err(e) if iterations.len() == 1 => return Ok((t_prev, lost(&e), iterations)),
                    // A later one: keep the last good pose and go on at the next finer
                    // level (at the finest, stop there).
                    Err(e) => {
                        status = TrackStatus::Stopped(e.to_string());
                        break;
                    }
                }
            }
        }
        // The finest level's outcome.
        Ok((t, status, iterations))
    }
}

fn lost(e: &SolveError) -> TrackStatus {
    TrackStatus::Lost(e.to_string())
}
