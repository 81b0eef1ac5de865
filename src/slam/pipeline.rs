//! The dense-SLAM frame as a fixed sequence of kernel steps, generic over a [`Backend`].
//!
//! Per frame: `preprocess` (depth -> vertex, optionally bilateral-filtered, then
//! normal-depth and colour maps), then for every
//! frame but the first `predict` (render the map at the previous pose into a model
//! vertex/normal map, once per frame so each ICP iteration is O(pixels), not O(map)), up to
//! `max_iters` ICP iterations of `icp_system` + host solve + left-multiplicative update,
//! then `fuse` (merge + add), and with [`SlamParams::unstable_removal`] (the robust
//! profile) `compact` (remove unstable surfels, move the rest to the front). The pipeline knows steps and parameters, not backends: the
//! CPU twins and the GPU kernels implement [`Backend`], so the same loop runs on both.
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
//! | `preprocess` (`depth_to_vertex`, with [`SlamParams::bilateral`] `bilateral_filter`, then `vertex_to_normal`) | raw depth (u16), raw RGBA8 | `vertex` (camera frame, unfiltered), `filtered_vertex` (camera frame; only with the filter), `normal_depth` (camera-frame normal, depth in w; from `filtered_vertex` with the filter, else from `vertex`), `color` |
//! | `predict` (`project_model`, `predict_model`) | map `position_weight`, `normal_frame`; `t_world_to_cam` of the last pose | `index_map` (packed depth/index per pixel), `pred_vertex`, `pred_normal` (world frame) |
//! | `icp_system` (`icp_reduce`), per iteration | `pred_vertex`, `normal_depth`; the current `t_world_to_cam` | the 29-float system (host: [`crate::slam::solve`]; GPU: `partials`, one per workgroup, summed on the host) |
//! | `fuse` (`fuse_merge`, then `fuse_add`) | `normal_depth`, `color`; the tracked pose | map (merged in place, then appended), `assoc` (merged pixels), `counter` (surfel count) |
//! | `compact` (`compact_flags`, `prefix_sum`, `compact_scatter`), only with [`SlamParams::unstable_removal`] | map `position_weight` (w = weight), `normal_frame` (w = last frame); the frame id | `flags`, `offsets` (GPU: storage buffers of one `u32` per surfel), the second map (compacted; then the two swap), `counter` (surfels kept) |
//!
//! The tracking loop reads back only the system per iteration and the surfel count per
//! frame (twice with `compact`); the `download_*` methods copy maps to the host for outputs and comparisons,
//! and `upload_map` copies a map into the backend (to resume, or to put one backend into another's state).

use glam::DMat4;

use crate::geometry::camera::Intrinsics;
use crate::geometry::se3;
use crate::layout::{
    camera_floats, gpu_mat4, BilateralParams, CompactParams, FuseParams, IcpParams, NormalParams,
    PreprocessParams, ProjectParams, ICP_SYSTEM_LEN,
};
use crate::slam::map::SurfelMap;
use crate::slam::solve::{increment_size, update_pose, NormalEquations, SolveError};
use crate::Result;

/// The per-frame maps a backend holds after `preprocess` (downloaded for comparison), in
/// the kernels' representation: `depth_to_vertex`'s two outputs, `bilateral_filter`'s and
/// `vertex_to_normal`'s.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FrameMaps {
    /// Camera-frame vertices, metres, `w = 1` valid / `0` invalid: `depth_to_vertex`'s
    /// output, unfiltered.
    pub vertex: Vec<[f32; 4]>,
    /// `bilateral_filter`'s output (same representation), which `normal_depth` was made
    /// from; empty when the last `preprocess` ran without the filter.
    pub filtered_vertex: Vec<[f32; 4]>,
    /// Camera-frame unit normals with the vertex's depth (metres, > 0) in `w`; all zero
    /// where invalid (see `cpu::vertex_to_normal`).
    pub normal_depth: Vec<[f32; 4]>,
    /// RGB 0..255.
    pub color: Vec<[f32; 4]>,
}

impl FrameMaps {
    /// The normal map decoded from `normal_depth` (xyz, `w = 1` valid / `0` invalid), for
    /// reports and comparisons.
    pub fn normal_map(&self) -> Vec<[f32; 4]> {
        self.normal_depth
            .iter()
            .map(|n| {
                if n[3] > 0.0 {
                    [n[0], n[1], n[2], 1.0]
                } else {
                    [0.0; 4]
                }
            })
            .collect()
    }
}

/// Predicted model vertex and normal maps (world frame, `w = 1` valid).
pub type Prediction = (Vec<[f32; 4]>, Vec<[f32; 4]>);

/// Work counters a backend reports for the benchmark.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct BackendCounters {
    /// Bytes read back from the device since creation.
    pub readback_bytes: u64,
    /// Command submissions since creation.
    pub submissions: u64,
}

/// Runs the kernel steps of one frame. Every method mirrors one or two kernels.
pub trait Backend {
    /// Short name for logs and reports (`cpu`, `gpu`).
    fn name(&self) -> &'static str;
    /// `depth_to_vertex`, then `bilateral_filter` when `bilateral` is given, then
    /// `vertex_to_normal` on the filtered vertex map (or on the unfiltered one without the
    /// filter) on a raw frame (`raw_depth`: u16 depth units; `raw_rgba`: packed RGBA8, both
    /// raw_width x raw_height). The unfiltered vertex map is kept either way.
    fn preprocess(
        &mut self,
        params: &PreprocessParams,
        bilateral: Option<&BilateralParams>,
        normal: &NormalParams,
        raw_depth: &[u16],
        raw_rgba: &[u32],
    ) -> Result<()>;
    /// `project_model` then `predict_model` at `params.t_world_to_cam`
    /// (`surfel_count` is filled in by the backend).
    fn predict(&mut self, params: &ProjectParams) -> Result<()>;
    /// `icp_reduce` at the current estimate: the summed 29-entry system.
    fn icp_system(&mut self, params: &IcpParams) -> Result<[f64; ICP_SYSTEM_LEN]>;
    /// `fuse_merge` then `fuse_add` (`surfel_count` and `capacity` are filled in by the
    /// backend, which grows the map first when needed). Returns surfels after fusion.
    fn fuse(&mut self, params: &FuseParams) -> Result<usize>;
    /// `compact_flags`, `prefix_sum`, then `compact_scatter` into a second map, which
    /// becomes the map: removes the unstable surfels and moves the survivors to the front
    /// in their order (`surfel_count` is filled in by the backend). Returns surfels after.
    fn compact(&mut self, params: &CompactParams) -> Result<usize>;
    /// Surfels in the map.
    fn surfel_count(&self) -> usize;
    /// The whole map (for export and comparison).
    fn download_map(&mut self) -> Result<SurfelMap>;
    /// Replaces the map with `map` (growing the storage if needed): to resume from a saved
    /// map, or to put this backend into another's state (`wgslam compare`'s lockstep mode).
    /// [`crate::Error::Capacity`] when the backend cannot hold it.
    fn upload_map(&mut self, map: &SurfelMap) -> Result<()>;
    /// The current frame's maps.
    fn download_frame(&mut self) -> Result<FrameMaps>;
    /// The predicted model vertex and normal maps (world frame).
    fn download_prediction(&mut self) -> Result<Prediction>;
    /// Work counters (zero for the CPU).
    fn counters(&self) -> BackendCounters {
        BackendCounters::default()
    }
    /// Blocks until all submitted work has finished (for per-stage wall-clock timing;
    /// a no-op for the CPU).
    fn finish(&mut self) -> Result<()> {
        Ok(())
    }
}

/// A boxed backend is a backend (the CLI picks CPU or GPU at run time): every step goes to
/// the box's content. The one hand-written forwarding of the trait besides
/// [`crate::slam::instrumented::Instrumented`].
impl<B: Backend + ?Sized> Backend for Box<B> {
    fn name(&self) -> &'static str {
        (**self).name()
    }
    fn preprocess(
        &mut self,
        params: &PreprocessParams,
        bilateral: Option<&BilateralParams>,
        normal: &NormalParams,
        raw_depth: &[u16],
        raw_rgba: &[u32],
    ) -> Result<()> {
        (**self).preprocess(params, bilateral, normal, raw_depth, raw_rgba)
    }
    fn predict(&mut self, params: &ProjectParams) -> Result<()> {
        (**self).predict(params)
    }
    fn icp_system(&mut self, params: &IcpParams) -> Result<[f64; ICP_SYSTEM_LEN]> {
        (**self).icp_system(params)
    }
    fn fuse(&mut self, params: &FuseParams) -> Result<usize> {
        (**self).fuse(params)
    }
    fn compact(&mut self, params: &CompactParams) -> Result<usize> {
        (**self).compact(params)
    }
    fn surfel_count(&self) -> usize {
        (**self).surfel_count()
    }
    fn download_map(&mut self) -> Result<SurfelMap> {
        (**self).download_map()
    }
    fn upload_map(&mut self, map: &SurfelMap) -> Result<()> {
        (**self).upload_map(map)
    }
    fn download_frame(&mut self) -> Result<FrameMaps> {
        (**self).download_frame()
    }
    fn download_prediction(&mut self) -> Result<Prediction> {
        (**self).download_prediction()
    }
    fn counters(&self) -> BackendCounters {
        (**self).counters()
    }
    fn finish(&mut self) -> Result<()> {
        (**self).finish()
    }
}

/// Where the poses come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub enum PoseSource {
    /// Frame-to-model ICP (the first frame at ground truth, or identity without it).
    Track,
    /// Ground-truth poses, no tracking (the fusion-only experiment).
    GroundTruth,
}

/// A named set of [`SlamParams`]: the course assignment's exact algorithm, or the robust
/// tracker for real sensors. Recorded in `metrics.json` with every parameter.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum Profile {
    /// The handout's experiment: raw normals, one level, a 0.07 m distance gate, no angle
    /// gate, unweighted rows, 0.03 m / 5 degree fusion gates, count weights.
    Assignment,
    /// Tracking for noisy depth (work in progress, see the README): ElasticFusion's 0.10 m /
    /// 20 degree association gates, Huber-weighted rows scaled by the depth-noise model, a
    /// convergence test that noisy data can meet, the bilateral depth filter
    /// ([`BilateralSettings`]); the assignment's fusion with wider gates
    /// ([`ROBUST_FUSE_DIST_M`]).
    Robust,
}

/// Every tunable of the dense pipeline. `Default` is the assignment's profile.
#[derive(Debug, Clone, serde::Serialize)]
pub struct SlamParams {
    /// The profile these values started from (each may have been overridden since).
    pub profile: Profile,
    /// Keep every N-th pixel in each direction (the assignment uses 2).
    pub downsample: u32,
    /// Raw depth units per metre (the sequence's own: [`Slam::for_sequence`] sets it).
    pub depth_scale: f32,
    /// Valid depth range, metres.
    pub min_depth_m: f32,
    pub max_depth_m: f32,
    /// Normals across a depth jump larger than this (metres) are invalid.
    pub max_depth_jump_m: f32,
    /// ICP filter 2: maximum point distance, metres.
    pub icp_dist_m: f32,
    /// ICP filter 2: maximum angle between model and frame normals, degrees; 180 or more
    /// turns the gate off.
    pub icp_normal_deg: f32,
    /// Huber threshold on the point-to-plane residual, metres; 0 turns the weight off.
    pub icp_huber_m: f32,
    /// Weight each ICP row by the depth-noise model (`cpu::icp_reduce::noise_weight`).
    pub icp_noise_weight: bool,
    /// ICP iterations per frame at most.
    pub icp_max_iters: usize,
    /// Stop iterating when the increment's rotation (rad) and translation (m) are both below.
    pub icp_min_increment: f64,
    /// Fusion filter 2: maximum point distance, metres.
    pub fuse_dist_m: f32,
    /// Fusion filter 2: maximum normal angle, degrees.
    pub fuse_normal_deg: f32,
    /// Tracking or ground-truth poses.
    pub poses: PoseSource,
    /// The edge-preserving bilateral depth filter between `depth_to_vertex` and
    /// `vertex_to_normal`; `None` (the default) runs without it.
    pub bilateral: Option<BilateralSettings>,
    /// Removal of unstable surfels after each fusion (the `compact` step); `None` (the
    /// assignment) keeps every surfel.
    pub unstable_removal: Option<UnstableRemoval>,
}

/// The removal rule for unstable surfels (Keller et al. 2013, ElasticFusion): after fusing
/// frame `f`, a surfel with weight (observations) below `stable_weight` whose last
/// observation is more than `max_age_frames` frames before `f` is removed: it was seen once
/// or twice and never again (depth noise, a flying pixel at an edge). See
/// [`ROBUST_STABLE_WEIGHT`] for the measured defaults.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct UnstableRemoval {
    /// Surfels with fewer observations than this are unstable.
    pub stable_weight: f32,
    /// Unstable surfels not observed for more than this many frames are removed.
    pub max_age_frames: u32,
}

impl Default for UnstableRemoval {
    fn default() -> Self {
        UnstableRemoval {
            stable_weight: ROBUST_STABLE_WEIGHT,
            max_age_frames: ROBUST_UNSTABLE_MAX_AGE,
        }
    }
}

/// Stable weight of the robust profile's removal rule (see [`UnstableRemoval`]). Measured
/// on the noisy ICL kt2 frames 1..200 at 320x240 (`wgslam run ... --profile robust
/// --backend cpu --stable-weight W --unstable-max-age A`), ATE aligned / map fraction of
/// all pixels; without removal 7.91 mm / 0.0225:
///
/// | W \ A | 1 | 3 or 5 | 10 | 20 | 50 |
/// |---|---|---|---|---|---|
/// | 2 | 7.85 / 0.0214 | 7.89 / 0.0219 (3) | 7.91 / 0.0222 | 7.90 / 0.0222 | |
/// | 3 | 7.86 / 0.0210 | 7.89 / 0.0218 (5) | 7.92 / 0.0219 | 7.91 / 0.0220 | |
/// | 5 | 7.87 / 0.0204 | 7.90 / 0.0214 (5) | 7.93 / 0.0216 | 7.91 / 0.0217 | |
/// | 10 | 7.94 / 0.0194 | 7.92 / 0.0205 (5) | 7.94 / 0.0208 | 7.91 / 0.0209 | |
/// | 15 | 7.95 / 0.0186 | 7.91 / 0.0198 (5) | 7.94 / 0.0201 | 7.92 / 0.0203 | 7.92 / 0.0209 |
/// | 20 | 7.97 / 0.0179 | 7.91 / 0.0191 (5) | 7.92 / 0.0194 | 7.90 / 0.0197 | 7.92 / 0.0205 |
/// | 30 | 7.99 / 0.0166 | 7.94 / 0.0179 (5) | 7.93 / 0.0183 | 7.92 / 0.0187 | |
///
/// The ATE barely moves (the removed surfels are rarely the ones ICP matches); the map
/// is mostly surfels seen many times (median weight 55: with the wide fusion gates several
/// surfels merge with each pixel), so only a high stable weight reaches 0.02. 20 / 20 is
/// the longest time window under 0.02. On the noise-free frames 1..200 it keeps the ATE
/// (0.180 mm with and without) and shrinks the map from 0.0198 to 0.0174 (15 / 5: 0.0176;
/// 10 / 1: 0.176 mm / 0.0182): the rule also drops real surfaces seen for only a few
/// frames at the edge of the view, not only noise.
pub const ROBUST_STABLE_WEIGHT: f32 = 20.0;
/// Age limit of the robust profile's removal rule, frames; see [`ROBUST_STABLE_WEIGHT`].
pub const ROBUST_UNSTABLE_MAX_AGE: u32 = 20;

/// Parameters of the bilateral depth filter (`cpu::bilateral_filter`), in pixels of the
/// (downsampled) maps and metres. The defaults (3x3 window, sigma 1 px, range sigma
/// `0.01 z²`) were measured at the default 320x240: see the twin's header for the table.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct BilateralSettings {
    /// Half-width of the window, pixels: (2r+1)² neighbours.
    pub radius_px: u32,
    /// Spatial Gaussian's standard deviation, pixels.
    pub sigma_space_px: f32,
    /// Range Gaussian's standard deviation on depth differences, metres, at depth 0 ...
    pub sigma_depth_m: f32,
    /// ... plus this times the pixel's depth squared (1/m).
    pub sigma_depth_per_m2: f32,
}

impl Default for BilateralSettings {
    fn default() -> Self {
        BilateralSettings {
            radius_px: 1,
            sigma_space_px: 1.0,
            sigma_depth_m: 0.0,
            sigma_depth_per_m2: 0.01,
        }
    }
}

impl Default for SlamParams {
    fn default() -> Self {
        Self::profile(Profile::Assignment)
    }
}

impl SlamParams {
    /// The values of `profile`.
    pub fn profile(profile: Profile) -> Self {
        let assignment = SlamParams {
            profile,
            downsample: 2,
            depth_scale: 5000.0,
            min_depth_m: 0.1,
            max_depth_m: 10.0,
            max_depth_jump_m: 0.1,
            icp_dist_m: 0.07,
            icp_normal_deg: 180.0,
            icp_huber_m: 0.0,
            icp_noise_weight: false,
            icp_max_iters: 10,
            icp_min_increment: 1e-6,
            fuse_dist_m: 0.03,
            fuse_normal_deg: 5.0,
            poses: PoseSource::Track,
            bilateral: None,
            unstable_removal: None,
        };
        match profile {
            Profile::Assignment => assignment,
            Profile::Robust => SlamParams {
                icp_dist_m: 0.10,
                icp_normal_deg: 20.0,
                icp_huber_m: ROBUST_HUBER_M,
                icp_noise_weight: true,
                icp_max_iters: 15,
                icp_min_increment: ROBUST_MIN_INCREMENT,
                fuse_dist_m: ROBUST_FUSE_DIST_M,
                fuse_normal_deg: ROBUST_FUSE_NORMAL_DEG,
                bilateral: Some(BilateralSettings::default()),
                unstable_removal: Some(UnstableRemoval::default()),
                ..assignment
            },
        }
    }
}

/// `IcpParams::cos_normal_threshold` that turns the angle gate off (below -1).
const ANGLE_GATE_OFF: f32 = -2.0;

/// Huber threshold of the robust profile, metres: about 3 sigma of the depth noise at 2 m
/// (sigma(2 m) = 6 mm by the model in `cpu::icp_reduce`), so residuals of well-matched
/// points keep full weight and mismatches beyond are down-weighted, not cut.
pub const ROBUST_HUBER_M: f32 = 0.02;

/// Fusion gates of the robust profile until fusion itself is rebuilt for noisy depth
/// (surfel confidence and radius, normals from filtered depth). Raw central-difference
/// normals on noisy depth rarely agree within the assignment's 5 degrees, so almost
/// nothing merged and the map became a cloud of noise. Measured on the noisy ICL kt2
/// frames 1..200 at 320x240 with the robust tracker (`wgslam run ... --profile robust
/// --fuse-dist D --fuse-angle A`), ATE aligned / map fraction of all pixels:
/// 0.03 m / 5 deg 187 mm / 0.34; 0.03 / 30 113 mm / 0.20; 0.05 / 20 50 mm / 0.16;
/// 0.05 / 45 12.5 mm / 0.067; 0.05 / 60 8.8 mm / 0.045; 0.05 / 80 5.9 mm / 0.032;
/// 0.04 / 60 11.0 mm / 0.053; 0.06 / 60 9.6 mm / 0.042; 0.07 / 45 14.0 mm / 0.060;
/// 0.10 / 45 14.5 mm / 0.059. Wider angles keep winning because the raw normals are
/// noise. With the bilateral filter (now part of the profile) the normals are smoother:
/// 0.05 / 30 8.9 mm / 0.042; 0.05 / 60 7.9 mm / 0.0225; 0.05 / 80 7.8 mm / 0.021; and the
/// noise-free frames 1..200 give 0.180 mm / 0.0198 at 0.05 / 60. 60 degrees is kept as the
/// widest gate that still separates a wall from the floor it meets.
pub const ROBUST_FUSE_DIST_M: f32 = 0.05;
/// See [`ROBUST_FUSE_DIST_M`].
pub const ROBUST_FUSE_NORMAL_DEG: f32 = 60.0;

/// Convergence threshold of the robust profile (radians and metres): noisy depth moves
/// every increment by more than the assignment's 1e-6, so ICP would always use all its
/// iterations; 1e-5 (10 micrometres, 2 millidegrees) is far below the noise.
pub const ROBUST_MIN_INCREMENT: f64 = 1e-5;

/// One ICP iteration's statistics.
#[derive(Debug, Clone, Copy, serde::Serialize)]
pub struct IcpIteration {
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
    /// ICP converged (increment below threshold) within the iteration budget.
    Converged,
    /// ICP used all iterations; the last pose is kept.
    MaxIterations,
    /// ICP refused a later iteration's system; the last good pose is kept.
    Stopped(String),
    /// ICP refused the first system: tracking lost, previous pose kept, frame not fused.
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
    /// `params.depth_scale` (the sequence knows its units; this is the one place that
    /// copies them into the parameters).
    pub fn for_sequence(backend: B, seq: &crate::dataset::Sequence, params: SlamParams) -> Self {
        let params = SlamParams {
            depth_scale: seq.depth_scale,
            ..params
        };
        Self::new(backend, seq.intrinsics, params)
    }

    /// A tracker for frames with `raw_intrinsics` and `params.depth_scale` as given.
    pub fn new(backend: B, raw_intrinsics: Intrinsics, params: SlamParams) -> Self {
        let intrinsics = raw_intrinsics.downsampled(params.downsample.max(1));
        Slam {
            backend,
            params,
            raw_intrinsics,
            intrinsics,
            t_world_to_cam: None,
        }
    }

    /// Parameters of `depth_to_vertex`.
    pub fn preprocess_params(&self) -> PreprocessParams {
        let [fx, fy, cx, cy] = camera_floats(&self.intrinsics);
        PreprocessParams {
            fx,
            fy,
            cx,
            cy,
            width: self.intrinsics.width,
            height: self.intrinsics.height,
            raw_width: self.raw_intrinsics.width,
            raw_height: self.raw_intrinsics.height,
            stride: self.params.downsample.max(1),
            depth_scale: self.params.depth_scale,
            min_depth_m: self.params.min_depth_m,
            max_depth_m: self.params.max_depth_m,
        }
    }

    /// Parameters of `bilateral_filter`, or `None` when [`SlamParams::bilateral`] is off.
    pub fn bilateral_params(&self) -> Option<BilateralParams> {
        let b = self.params.bilateral?;
        let [fx, fy, cx, cy] = camera_floats(&self.intrinsics);
        Some(BilateralParams {
            fx,
            fy,
            cx,
            cy,
            width: self.intrinsics.width,
            height: self.intrinsics.height,
            radius_px: b.radius_px,
            sigma_space_px: b.sigma_space_px,
            sigma_depth_m: b.sigma_depth_m,
            sigma_depth_per_m2: b.sigma_depth_per_m2,
            _pad1: 0,
            _pad2: 0,
        })
    }

    /// Parameters of `vertex_to_normal`.
    pub fn normal_params(&self) -> NormalParams {
        NormalParams {
            width: self.intrinsics.width,
            height: self.intrinsics.height,
            max_depth_jump_m: self.params.max_depth_jump_m,
            _pad: 0,
        }
    }

    /// Parameters of `project_model`/`predict_model` at a world-to-camera pose.
    pub fn project_params(&self, t_world_to_cam: &DMat4) -> ProjectParams {
        let [fx, fy, cx, cy] = camera_floats(&self.intrinsics);
        ProjectParams {
            t_world_to_cam: gpu_mat4(t_world_to_cam),
            fx,
            fy,
            cx,
            cy,
            width: self.intrinsics.width,
            height: self.intrinsics.height,
            surfel_count: self.backend.surfel_count() as u32,
            _pad: 0,
        }
    }

    /// Parameters of `icp_reduce` at the current estimate.
    pub fn icp_params(&self, t_world_to_cam: &DMat4) -> IcpParams {
        let [fx, fy, cx, cy] = camera_floats(&self.intrinsics);
        IcpParams {
            t_world_to_cam: gpu_mat4(t_world_to_cam),
            fx,
            fy,
            cx,
            cy,
            width: self.intrinsics.width,
            height: self.intrinsics.height,
            dist_threshold_m: self.params.icp_dist_m,
            cos_normal_threshold: if self.params.icp_normal_deg >= 180.0 {
                ANGLE_GATE_OFF
            } else {
                self.params.icp_normal_deg.to_radians().cos()
            },
            huber_delta_m: self.params.icp_huber_m,
            noise_weighting: self.params.icp_noise_weight as u32,
            _pad0: 0,
            _pad1: 0,
        }
    }

    /// Parameters of `fuse_merge`/`fuse_add` (count and capacity filled by the backend).
    pub fn fuse_params(&self, t_world_to_cam: &DMat4, frame_id: u32) -> FuseParams {
        let [fx, fy, cx, cy] = camera_floats(&self.intrinsics);
        FuseParams {
            t_world_to_cam: gpu_mat4(t_world_to_cam),
            t_cam_to_world: gpu_mat4(&se3::inverse_rigid(t_world_to_cam)),
            fx,
            fy,
            cx,
            cy,
            width: self.intrinsics.width,
            height: self.intrinsics.height,
            surfel_count: self.backend.surfel_count() as u32,
            frame_id,
            dist_threshold_m: self.params.fuse_dist_m,
            cos_normal_threshold: self.params.fuse_normal_deg.to_radians().cos(),
            capacity: 0,
            _pad: 0,
        }
    }

    /// Parameters of the compaction kernels after fusing `frame_id` (count filled by the
    /// backend), or `None` when [`SlamParams::unstable_removal`] is off.
    pub fn compact_params(&self, frame_id: u32) -> Option<CompactParams> {
        let r = self.params.unstable_removal?;
        Some(CompactParams {
            surfel_count: self.backend.surfel_count() as u32,
            frame_id,
            stable_weight: r.stable_weight,
            max_age_frames: r.max_age_frames,
        })
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
        let valid = raw_depth.iter().filter(|&&d| d > 0).count();
        if valid == 0 {
            return Ok(self.report(self.t_world_to_cam, TrackStatus::EmptyDepth, vec![]));
        }
        self.backend
            .preprocess(&pp, bp.as_ref(), &np, raw_depth, raw_rgba)?;
        let (t_world_to_cam, status, iterations) = match given {
            Some(t) => (t, TrackStatus::Given, vec![]),
            None => self.track()?,
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

    /// Frame-to-model ICP from the previous pose: predict once, then iterate.
    fn track(&mut self) -> Result<(DMat4, TrackStatus, Vec<IcpIteration>)> {
        let t_prev = self
            .t_world_to_cam
            .expect("track() is only called after a first frame");
        self.backend.predict(&self.project_params(&t_prev))?;
        let mut t = t_prev;
        let mut iterations = Vec::new();
        for it in 0..self.params.icp_max_iters {
            let sys = self.backend.icp_system(&self.icp_params(&t))?;
            let eq = NormalEquations::decode(&sys);
            iterations.push(IcpIteration {
                inliers: eq.inliers,
                mean_sq_residual: eq.mean_sq_residual(),
            });
            match eq.solve() {
                Ok(x) => {
                    t = update_pose(&t, &x);
                    let (r, tr) = increment_size(&x);
                    if r < self.params.icp_min_increment && tr < self.params.icp_min_increment {
                        return Ok((t, TrackStatus::Converged, iterations));
                    }
                }
                Err(e) if it == 0 => return Ok((t_prev, lost(&e), iterations)),
                Err(e) => return Ok((t, TrackStatus::Stopped(e.to_string()), iterations)),
            }
        }
        Ok((t, TrackStatus::MaxIterations, iterations))
    }
}

fn lost(e: &SolveError) -> TrackStatus {
    TrackStatus::Lost(e.to_string())
}
