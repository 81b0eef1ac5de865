//! The dense-SLAM frame as a fixed sequence of kernel steps, generic over a [`Backend`].
//!
//! Per frame: `preprocess` (depth -> vertex, optionally bilateral-filtered, then
//! normal-depth and colour maps, then the coarser levels of the ICP pyramid), then for every
//! frame but the first `predict` (render the map at the previous pose into a model
//! vertex/normal map, once per frame so each ICP iteration is O(pixels), not O(map), and
//! subsample it into the pyramid's coarser levels), ICP coarse to fine
//! ([`SlamParams::icp_level_iters`]: at each level up to its budget of iterations of
//! `icp_system` + host solve + left-multiplicative update, until the increment test
//! passes), then `fuse` (merge + add, at the finest level), and with
//! [`SlamParams::unstable_removal`] (the robust profile) `compact` (remove unstable
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
//! headers for why, and [`ROBUST_ICP_LEVEL_ITERS`] for the measured schedule.
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
//! | `predict` (`project_model` unless the last fusion built the index map at this view, see [`FusedView`]; `predict_model`; per coarser level `pyramid_model`) | map `position_weight`, `normal_frame`; `t_world_to_cam` of the last pose | `index_map` (packed depth/index per pixel), `pred_vertex`, `pred_normal` (world frame); per level `l >= 1` its `pred_vertex`, `pred_normal` (from level `l - 1`'s) |
//! | `icp_system` (`icp_reduce`), per iteration, at a level | that level's `pred_vertex`, `pred_normal`, `normal_depth`; the current `t_world_to_cam`; the level's intrinsics | the 29-float system (host: [`crate::slam::solve`]; GPU: `partials`, one per workgroup, summed on the host) |
//! | `fuse` (`fuse_merge`, or `fuse_select` + `fuse_merge_chosen` + with a prune scale, on removal frames, `fuse_prune`; then `fuse_flags`, `prefix_sum`, `fuse_add`) | `normal_depth`, `color`; the tracked pose | map (merged in place, duplicates retired, then appended), `assoc` (merged pixels), `merged` (the surfel each pixel merged into, best-candidate association), `index_map` (best candidate: the next prediction's, by `fuse_select` and `fuse_add`), `counter` (surfel count) |
//! | `compact` (`compact_flags`, `prefix_sum`, `compact_scatter`), only with [`SlamParams::unstable_removal`] | map `position_weight` (w = weight), `normal_frame` (w = last frame); the frame id | `flags`, `offsets` (GPU: storage buffers of one `u32` per surfel), the second map (compacted; then the two swap), `counter` (surfels kept) |
//!
//! The tracking loop reads back only the system per iteration and the surfel count per
//! frame (twice with `compact`); the `download_*` methods copy maps to the host for outputs and comparisons,
//! and `upload_map` copies a map into the backend (to resume, or to put one backend into another's state).

use glam::DMat4;

use crate::geometry::camera::Intrinsics;
use crate::geometry::se3;
use crate::layout::{
    camera_floats, gpu_mat4, BilateralParams, CompactParams, FuseParams, GpuMat4, IcpParams,
    NormalParams, PreprocessParams, ProjectParams, PyramidParams, ASSOCIATION_BEST_CANDIDATE,
    ICP_SYSTEM_LEN,
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
    /// The ICP pyramid's coarser levels 1, 2, ... (empty with a one-level schedule).
    pub pyramid: Vec<FrameLevel>,
}

/// One coarser level of the frame's ICP pyramid (level `l >= 1`), in the representation
/// of level 0's maps, at that level's size.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FrameLevel {
    /// `pyramid_depth`'s output: camera-frame vertices, metres, `w = 1` / `0`.
    pub vertex: Vec<[f32; 4]>,
    /// `vertex_to_normal` of `vertex`: camera-frame normal, depth in w, zero where invalid.
    pub normal_depth: Vec<[f32; 4]>,
}

/// The parameters that make one coarser level `l >= 1` of the frame's and the model's
/// pyramids from level `l - 1`: `pyramid_depth`'s and `pyramid_model`'s, and
/// `vertex_to_normal`'s at the level's size.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PyramidLevel {
    pub down: PyramidParams,
    pub normal: NormalParams,
}

impl FrameMaps {
    /// The normal map decoded from `normal_depth` (xyz, `w = 1` valid / `0` invalid), for
    /// reports and comparisons.
    pub fn normal_map(&self) -> Vec<[f32; 4]> {
        Self::normal_map_of(&self.normal_depth)
    }

    /// The normal map decoded from any `normal_depth` map (a pyramid level's too).
    pub fn normal_map_of(normal_depth: &[[f32; 4]]) -> Vec<[f32; 4]> {
        normal_depth
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

/// Predicted model vertex and normal maps of one pyramid level (world frame, `w = 1` valid).
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
    /// raw_width x raw_height). The unfiltered vertex map is kept either way. Then, for
    /// each entry of `pyramid` (levels 1, 2, ...), `pyramid_depth` from the finer level's
    /// vertex map (at level 0 the one the normals were made from) and `vertex_to_normal`.
    fn preprocess(
        &mut self,
        params: &PreprocessParams,
        bilateral: Option<&BilateralParams>,
        normal: &NormalParams,
        pyramid: &[PyramidLevel],
        raw_depth: &[u16],
        raw_rgba: &[u32],
    ) -> Result<()>;
    /// `project_model` then `predict_model` at `params.t_world_to_cam`
    /// (`surfel_count` is filled in by the backend), then `pyramid_model` for each entry of
    /// `pyramid` (the same levels as the last `preprocess`'s). When the map last changed in
    /// a best-candidate `fuse` at the same view ([`FusedView`]), that fusion's index map
    /// stands in for `project_model`'s.
    fn predict(&mut self, params: &ProjectParams, pyramid: &[PyramidLevel]) -> Result<()>;
    /// `icp_reduce` at the current estimate on pyramid level `level` (0 = finest; `params`
    /// carry that level's size and intrinsics): the summed 29-entry system.
    fn icp_system(&mut self, level: usize, params: &IcpParams) -> Result<[f64; ICP_SYSTEM_LEN]>;
    /// `fuse_merge` (projective) or `fuse_select` + `fuse_merge_chosen` (+ `fuse_prune`
    /// with a prune scale) (best candidate), then `fuse_add` (`surfel_count` and
    /// `capacity` are filled in by the backend, which grows the map first when needed).
    /// Returns surfels after fusion.
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
    /// The predicted model vertex and normal maps (world frame) of pyramid level `level`
    /// (0 = finest); empty before the first frame or beyond the pyramid.
    fn download_prediction(&mut self, level: usize) -> Result<Prediction>;
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

/// The view a best-candidate `fuse` projected the map from. Its `fuse_select` builds
/// `project_model`'s index map at that view on the way (every surfel whose centre lands in
/// the image, nearest first) and its `fuse_add` adds the new surfels, so a backend keeps
/// the view until the map changes otherwise (`compact`, `upload_map`, the next `fuse`) and
/// its `predict` skips `project_model` when asked for the same view, as it is on every
/// tracked frame: the next frame is predicted at the pose the last one was fused at. The
/// one difference from projecting afresh: a surfel merged this frame keys the pixel its
/// centre projected to before the merge moved it (by a fraction of its radius), with its
/// depth from then; `predict_model` reads its merged position and normal either way.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FusedView {
    t_world_to_cam: GpuMat4,
    /// fx, fy, cx, cy (pixels).
    intrinsics: [f32; 4],
    width: u32,
    height: u32,
}

impl FusedView {
    /// The view of a fusion, if its association builds the index map (best candidate).
    pub fn of_fuse(p: &FuseParams) -> Option<Self> {
        (p.association == ASSOCIATION_BEST_CANDIDATE).then_some(Self {
            t_world_to_cam: p.t_world_to_cam,
            intrinsics: [p.fx, p.fy, p.cx, p.cy],
            width: p.width,
            height: p.height,
        })
    }

    /// Whether `predict(p)` asks for this view (bit for bit).
    pub fn is_view_of(&self, p: &ProjectParams) -> bool {
        let FusedView {
            t_world_to_cam,
            intrinsics,
            width,
            height,
        } = *self;
        (t_world_to_cam, intrinsics, width, height)
            == (
                p.t_world_to_cam,
                [p.fx, p.fy, p.cx, p.cy],
                p.width,
                p.height,
            )
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
        pyramid: &[PyramidLevel],
        raw_depth: &[u16],
        raw_rgba: &[u32],
    ) -> Result<()> {
        (**self).preprocess(params, bilateral, normal, pyramid, raw_depth, raw_rgba)
    }
    fn predict(&mut self, params: &ProjectParams, pyramid: &[PyramidLevel]) -> Result<()> {
        (**self).predict(params, pyramid)
    }
    fn icp_system(&mut self, level: usize, params: &IcpParams) -> Result<[f64; ICP_SYSTEM_LEN]> {
        (**self).icp_system(level, params)
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
    fn download_prediction(&mut self, level: usize) -> Result<Prediction> {
        (**self).download_prediction(level)
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
    /// Tracking and fusion for noisy depth (Keller et al. 2013, ElasticFusion): the
    /// bilateral depth filter ([`BilateralSettings`]); coarse-to-fine ICP over three levels
    /// ([`ROBUST_ICP_LEVEL_ITERS`]) with 0.10 m / 20 degree association gates,
    /// Huber-weighted rows scaled by the depth-noise model and a convergence test that
    /// noisy data can meet; fusion with best-candidate association
    /// ([`Association::BestCandidate`]), confidence-weighted averages
    /// ([`ROBUST_CONFIDENCE_SIGMA`]), surfel radii, wider gates ([`ROBUST_FUSE_DIST_M`]), the
    /// retirement of duplicate surfels ([`ROBUST_PRUNE_RADIUS_SCALE`]) and the removal of
    /// unstable surfels ([`ROBUST_STABLE_WEIGHT`]).
    Robust,
}

/// Every tunable of the dense pipeline. `Default` is the robust profile.
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
    /// ICP iterations per pyramid level at most, coarse to fine: one entry per level, the
    /// last for level 0 (the full maps). `[10]` (the assignment's) is single-level ICP;
    /// the robust profile's is [`ROBUST_ICP_LEVEL_ITERS`]. Must not be empty.
    pub icp_level_iters: Vec<usize>,
    /// How the frame's coarser pyramid levels are made (used with more than one level).
    pub pyramid: PyramidSettings,
    /// Stop iterating when the increment's rotation (rad) and translation (m) are both below.
    pub icp_min_increment: f64,
    /// Fusion filter 2: maximum point distance, metres.
    pub fuse_dist_m: f32,
    /// Fusion filter 2: maximum normal angle, degrees.
    pub fuse_normal_deg: f32,
    /// How fusion pairs pixels with surfels.
    pub fuse_association: Association,
    /// Standard deviation of a measurement's confidence over its normalised distance from
    /// the image centre (`pixel_confidence`); 0 weighs every measurement 1 (counts).
    pub fuse_confidence_sigma: f32,
    /// Best-candidate fusion's pruning of duplicate surfels (`fuse_prune`), in radii; 0
    /// turns it off. It runs on the frames [`SlamParams::unstable_removal`] runs after, or
    /// on every frame without the removal. A retired surfel has weight 0 and last frame 0,
    /// so the removal drops it once the frame is past `max_age_frames` (from frame 30 on
    /// in the robust profile, at once; retired on frames 10 and 20, at frame 30).
    /// See [`ROBUST_PRUNE_RADIUS_SCALE`].
    pub fuse_prune_scale: f32,
    /// Tracking or ground-truth poses.
    pub poses: PoseSource,
    /// The edge-preserving bilateral depth filter between `depth_to_vertex` and
    /// `vertex_to_normal`; `None` (the default) runs without it.
    pub bilateral: Option<BilateralSettings>,
    /// Removal of unstable surfels after each fusion (the `compact` step); `None` (the
    /// assignment) keeps every surfel.
    pub unstable_removal: Option<UnstableRemoval>,
}

/// How fusion pairs the frame's pixels with the map's surfels.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, clap::ValueEnum)]
#[serde(rename_all = "kebab-case")]
pub enum Association {
    /// The assignment's: every surfel merges with the pixel it projects to when the
    /// distance and angle gates pass; several surfels may merge with one pixel, and a pixel
    /// no surfel merged with becomes a new surfel.
    Projective,
    /// Keller et al. 2013 / ElasticFusion: each pixel picks the one surfel nearest its ray
    /// among those whose centres project into it and whose disc covers its ray within the
    /// depth and angle gates (`fuse_select`); only that surfel merges (`fuse_merge_chosen`).
    /// A pixel that chose nothing becomes a new surfel unless the surfel a neighbouring
    /// pixel merged into passes its gates (`fuse_flags`).
    BestCandidate,
}

impl Association {
    /// `FuseParams::association`.
    pub fn code(self) -> u32 {
        match self {
            Association::Projective => crate::layout::ASSOCIATION_PROJECTIVE,
            Association::BestCandidate => crate::layout::ASSOCIATION_BEST_CANDIDATE,
        }
    }
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
    /// The rule runs after frames whose sequence position is a multiple of this (1: every
    /// frame). See [`ROBUST_REMOVAL_EVERY`].
    pub every_frames: u32,
}

impl Default for UnstableRemoval {
    fn default() -> Self {
        UnstableRemoval {
            stable_weight: ROBUST_STABLE_WEIGHT,
            max_age_frames: ROBUST_UNSTABLE_MAX_AGE,
            every_frames: ROBUST_REMOVAL_EVERY,
        }
    }
}

/// Stable weight of the robust profile's removal rule (see [`UnstableRemoval`]), in the
/// units of the surfel weight: summed `pixel_confidence`s, at most 1 per observation.
/// Measured with best-candidate fusion on the noisy ICL kt2 frames 1..200 at 320x240
/// (`wgslam run ... --profile robust --backend cpu --stable-weight W`, age 20), ATE
/// aligned / map fraction of all pixels:
///
/// | W | 0 (off) | 5 | 10 | 20 | 30 |
/// |---|---|---|---|---|---|
/// | | 6.50 mm / 0.0085 | 6.50 / 0.0083 | 6.51 / 0.0080 | 6.50 / 0.0077 | 6.50 / 0.0073 |
///
/// Best-candidate association already keeps the map small (a second copy of a surface is
/// not refreshed), so the rule only trims the last tenth: copies that were seen a few
/// times and never again, flying pixels at edges. The ATE does not move. With projective
/// (the assignment's) fusion and count weights the same rule had mattered more (0.0225 to
/// 0.0197 at 20 / 20). 20 / 20 is kept: the longest window that removes the most.
pub const ROBUST_STABLE_WEIGHT: f32 = 20.0;
/// How often the robust profile's removal rule runs, frames. Compaction copies the whole
/// map, which lavapipe's texture stores make the dearest kernel of a frame at 640x480
/// (`compact_scatter` 98 ms of 405 ms per frame over noisy frames 1..120, `wgslam bench
/// --kernels --backends gpu`), while a surfel that turned unstable-and-old can stay a few
/// frames longer at no cost to tracking or map size: noisy 1..200 at 320x240 (CPU), every
/// frame 6.504 mm / 117,626 surfels, every 10th 6.499 mm / 117,711.
pub const ROBUST_REMOVAL_EVERY: u32 = 10;
/// Pruning radius of the robust profile's duplicate removal (`fuse_prune`), in the larger
/// surfel radius. With noisy depth, best-candidate fusion leaves layered copies of a
/// surface that different pixels keep refreshing, so they grow confident and the
/// unstable-surfel removal never takes them; the camera then sees a denser map on every
/// revisit. Measured with a CPU prototype of this rule on the 1000-frame revisit of ICL
/// kt2 at 640x480 (`wgslam bench ... --frames 1..209 --revisit 1000 --downsample 1
/// --backends cpu`), map after passes 1 and 5, ATE:
///
/// | scale | noisy | noise-free |
/// |---|---|---|
/// | 0 (off) | 646,827 -> 805,469 (1.25x), 6.62 mm | 512,891 -> 486,202 (0.95x), 0.10 mm |
/// | 0.5 | 485,574 -> 437,236 (0.90x), 6.85 mm | 435,229 -> 380,206 (0.87x), 0.11 mm |
/// | 1.0, no weight test | 272,602 -> 246,804, 15.68 mm | |
/// | 1.0 | 359,963 -> 289,987 (0.81x), 7.97 mm | |
///
/// 0.5: the map stops growing over revisits and the ATE moves by 0.2 mm noisy and 0.01 mm
/// noise-free. Wider, it removes surfels tracking needs. The kernels (`fuse_prune`) give
/// the 0.5 row on both backends (noisy 485,957 -> 437,327 CPU, 485,587 -> 437,398 GPU,
/// ATE 6.85 / 6.83 mm; noise-free 0.11 mm); over noisy frames 1..200 the ATE is 7.45 mm
/// against 7.10 without. Run only on the removal frames (every 10th) and against the
/// surfel each pixel merged into (today's rule): noisy 500,374 -> 441,123 (0.88x), ATE
/// 7.02 mm; noise-free 442,302 -> 384,417 (0.87x), 0.10 mm (CPU; the GPU within 300
/// surfels and 0.01 mm).
pub const ROBUST_PRUNE_RADIUS_SCALE: f32 = 0.5;

/// Age limit of the robust profile's removal rule, frames; see [`ROBUST_STABLE_WEIGHT`].
pub const ROBUST_UNSTABLE_MAX_AGE: u32 = 20;

/// How `pyramid_depth` makes a coarser level of the frame's ICP pyramid (see
/// `cpu::pyramid_depth`): the mean of the depths in a `(2 radius_px + 1)²` window of the
/// finer level around the sampled pixel within `max_depth_diff_m + max_depth_diff_per_m2
/// z²` of its depth `z`. The defaults: a 3x3 window (the smallest one centred on the
/// sampled pixel that covers the 2x2 block of finer pixels a coarse pixel stands for) and
/// a gate of 3 sigma of the bilateral filter's range model
/// (`0.01 z²`, see [`BilateralSettings`]): 3 cm at 1 m, 12 cm at 2 m, the noisy set's
/// disparity steps pass and depth edges between objects do not. See
/// [`ROBUST_ICP_LEVEL_ITERS`] for the measurements.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct PyramidSettings {
    /// Window half-width, pixels of the finer level.
    pub radius_px: u32,
    /// Depth gate at depth 0, metres ...
    pub max_depth_diff_m: f32,
    /// ... plus this times the sampled pixel's depth squared (1/m).
    pub max_depth_diff_per_m2: f32,
}

impl Default for PyramidSettings {
    fn default() -> Self {
        PyramidSettings {
            radius_px: 1,
            max_depth_diff_m: 0.0,
            max_depth_diff_per_m2: 0.03,
        }
    }
}

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
    /// The robust profile, as on the command line.
    fn default() -> Self {
        Self::profile(Profile::Robust)
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
            icp_level_iters: vec![10],
            pyramid: PyramidSettings::default(),
            icp_min_increment: 1e-6,
            fuse_dist_m: 0.03,
            fuse_normal_deg: 5.0,
            fuse_association: Association::Projective,
            fuse_confidence_sigma: 0.0,
            fuse_prune_scale: 0.0,
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
                icp_level_iters: ROBUST_ICP_LEVEL_ITERS.to_vec(),
                icp_min_increment: ROBUST_MIN_INCREMENT,
                fuse_dist_m: ROBUST_FUSE_DIST_M,
                fuse_normal_deg: ROBUST_FUSE_NORMAL_DEG,
                fuse_association: Association::BestCandidate,
                fuse_confidence_sigma: ROBUST_CONFIDENCE_SIGMA,
                fuse_prune_scale: ROBUST_PRUNE_RADIUS_SCALE,
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

/// Fusion gates of the robust profile: the depth gate (along the pixel's ray with
/// best-candidate association) and the normal-angle gate. First chosen with projective
/// fusion, where raw central-difference
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
/// widest gate that still separates a wall from the floor it meets. With best-candidate
/// association (noisy, 320x240, CPU) the gates matter less: 0.05 / 60 6.50 mm / 0.0077;
/// 0.05 / 45 6.63 / 0.0087; 0.05 / 30 6.29 / 0.011; 0.03 / 60 6.13 / 0.0086 (within the
/// run-to-run spread of the tracker's choices), so they are kept.
pub const ROBUST_FUSE_DIST_M: f32 = 0.05;
/// See [`ROBUST_FUSE_DIST_M`].
pub const ROBUST_FUSE_NORMAL_DEG: f32 = 60.0;

/// Confidence sigma of the robust profile: ElasticFusion's 0.6 (a measurement at the
/// image corner weighs exp(-1 / 0.72) = 0.25 of one at the centre). On the ICL frames it
/// neither helps nor hurts (noisy 1..200 at 320x240: 6.50 mm / map 0.0077 with it, 6.44 mm
/// / 0.0081 with `--confidence-sigma 0`): their noise model has no lens falloff, which a
/// real sensor has.
pub const ROBUST_CONFIDENCE_SIGMA: f32 = 0.6;

/// Convergence threshold of the robust profile (radians and metres): noisy depth moves
/// every increment by more than the assignment's 1e-6, so ICP would always use all its
/// iterations; 1e-5 (10 micrometres, 2 millidegrees) is far below the noise.
pub const ROBUST_MIN_INCREMENT: f64 = 1e-5;

/// ICP iterations per pyramid level of the robust profile, coarse to fine (level 2 at
/// 80x60, level 1 at 160x120, level 0 at 320x240 with the default downsampling):
/// KinectFusion's schedule. Measured on ICL kt2 at 320x240, CPU backend (`wgslam run
/// DATASET --profile robust --backend cpu --icp-level-iters S`), ATE aligned: frames
/// 1..200 noisy and noise-free, and noisy frames 1..200 keeping every k-th frame (k = 8,
/// 10, 12: 8, 10, 12 times the motion between frames; the sequence moves ~10 mm and 0.4
/// degrees per frame); the last column is the ICP work per tracked frame on noisy 1..200
/// in level-0 iterations (an iteration at level l costs 4^-l of one at level 0):
///
/// | schedule | noisy | noise-free | every 8th | every 10th | every 12th | work |
/// |---|---|---|---|---|---|---|
/// | 15 (one level: the profile before the pyramid) | 7.90 mm | 0.180 mm | 23.8 mm | 169 mm | 260 mm | 6.96 |
/// | 10,5 | 7.91 mm | 0.181 mm | 15.2 mm | 11.3 mm | 139 mm | 5.44 |
/// | 4,4,4 | 7.91 mm | 0.181 mm | 6.10 mm | 5.65 mm | 32.1 mm | 4.75 |
/// | 5,5,5 | 7.91 mm | 0.181 mm | 6.10 mm | 5.64 mm | 5.70 mm | 5.25 |
/// | **10,5,4** | 7.92 mm | 0.180 mm | 6.10 mm | 5.65 mm | 6.25 mm | 4.90 |
/// | 10,5,8 | 7.91 mm | 0.180 mm | 6.10 mm | 5.64 mm | 6.26 mm | 5.68 |
/// | 10,10,10 | 7.91 mm | 0.181 mm | 6.10 mm | 5.64 mm | 6.26 mm | 5.74 |
/// | 20,10,4 | 7.91 mm | 0.181 mm | 6.10 mm | 5.64 mm | 6.26 mm | 5.11 |
/// | 10,10,5,4 (four levels) | 7.92 mm | 0.181 mm | 6.10 mm | 5.65 mm | 6.25 mm | 4.95 |
///
/// On the sequence as recorded every schedule is as accurate as one level (the finest
/// level decides the pose; the motion between frames is well inside one level's basin);
/// the pyramid is what keeps tracking when frames move farther apart: one level fails
/// from every 8th frame, two from every 10th, three hold to every 12th (every 16th fails
/// with all of them: 128 mm with 10,5,4). 10,5,4 is the cheapest schedule that holds at
/// every 12th frame: its level 0 runs out of its 4 iterations on 75 of the 199 noisy
/// frames without costing accuracy. The way the frame's levels are made
/// ([`PyramidSettings`]) matters only at the largest motions: at every 12th frame a 3x3
/// mean within 0.03 z² (the default) gives 6.25 mm, 5x5 within 0.09 m (KinectFusion's)
/// 6.25 mm, plain subsampling (radius 0) 7.14 mm; on the other sets all agree within
/// 0.02 mm, and so does a 3x3 edge-aware average on the model side instead of
/// subsampling (see `cpu::pyramid_model`).
pub const ROBUST_ICP_LEVEL_ITERS: [usize; 3] = [10, 5, 4];

/// Most pyramid levels a schedule may have (`--icp-level-iters`): a fourth level is 40x30
/// at the default 320x240, a fifth would be 20x15, too few pixels to constrain a pose
/// ([`crate::slam::solve::MIN_INLIERS`] correspondences at the least).
pub const MAX_ICP_LEVELS: usize = 4;

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

    /// Pyramid levels of [`SlamParams::icp_level_iters`] (one per entry).
    pub fn levels(&self) -> usize {
        self.params.icp_level_iters.len()
    }

    /// Intrinsics of pyramid level `level`: level 0 is [`Slam::intrinsics`], each coarser
    /// level halves the one before (coarse pixel `(u, v)` samples finer pixel `(2u, 2v)`).
    pub fn level_intrinsics(&self, level: usize) -> Intrinsics {
        (0..level).fold(self.intrinsics, |k, _| k.downsampled(2))
    }

    /// Parameters that make the coarser pyramid levels `1..levels()` (empty with one level).
    pub fn pyramid_levels(&self) -> Vec<PyramidLevel> {
        let s = self.params.pyramid;
        (1..self.levels())
            .map(|level| {
                let (fine, coarse) = (
                    self.level_intrinsics(level - 1),
                    self.level_intrinsics(level),
                );
                PyramidLevel {
                    down: PyramidParams::halving(
                        &fine,
                        s.radius_px,
                        s.max_depth_diff_m,
                        s.max_depth_diff_per_m2,
                    ),
                    normal: NormalParams {
                        width: coarse.width,
                        height: coarse.height,
                        ..self.normal_params()
                    },
                }
            })
            .collect()
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

    /// Parameters of `icp_reduce` at the current estimate on pyramid level `level`.
    pub fn icp_params(&self, level: usize, t_world_to_cam: &DMat4) -> IcpParams {
        let k = self.level_intrinsics(level);
        let [fx, fy, cx, cy] = camera_floats(&k);
        IcpParams {
            t_world_to_cam: gpu_mat4(t_world_to_cam),
            fx,
            fy,
            cx,
            cy,
            width: k.width,
            height: k.height,
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
            association: self.params.fuse_association.code(),
            confidence_sigma: self.params.fuse_confidence_sigma,
            prune_radius_scale: self.prune_scale(frame_id),
            _pad1: 0,
            _pad2: 0,
        }
    }

    /// `fuse_prune`'s radius scale for `frame_id`: [`SlamParams::fuse_prune_scale`] on the
    /// frames the unstable-surfel removal runs after ([`Slam::removal_after`]), 0 (off) on
    /// the others; every frame when there is no removal.
    fn prune_scale(&self, frame_id: u32) -> f32 {
        if self.params.unstable_removal.is_none() || self.removal_after(frame_id).is_some() {
            self.params.fuse_prune_scale
        } else {
            0.0
        }
    }

    /// The unstable-surfel removal's settings when it runs after fusing `frame_id`
    /// ([`UnstableRemoval::every_frames`]), else `None`.
    fn removal_after(&self, frame_id: u32) -> Option<UnstableRemoval> {
        self.params
            .unstable_removal
            .filter(|r| frame_id % r.every_frames.max(1) == 0)
    }

    /// Parameters of the compaction kernels after fusing `frame_id` (count filled by the
    /// backend), or `None` when [`SlamParams::unstable_removal`] is off or does not run
    /// after this frame ([`UnstableRemoval::every_frames`]).
    pub fn compact_params(&self, frame_id: u32) -> Option<CompactParams> {
        let r = self.removal_after(frame_id)?;
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
        if self.params.icp_level_iters.is_empty() {
            return Err(crate::Error::Argument(
                "the ICP schedule (icp_level_iters) needs at least one level".into(),
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
        let schedule = self.params.icp_level_iters.clone();
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
                        let min = self.params.icp_min_increment;
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::slam::cpu_backend::CpuBackend;

    /// `predict` reuses a fusion's index map only for the very view it was built at, and
    /// only after best-candidate association (the only one whose `fuse_select` builds it).
    #[test]
    fn fused_view_matches_only_its_own_view() {
        let robust = Slam::new(
            CpuBackend::new(),
            Intrinsics::ICL_NUIM,
            SlamParams::profile(Profile::Robust),
        );
        let t = se3::exp(&[0.01, -0.02, 0.03, 0.1, 0.2, -0.3]);
        let view = FusedView::of_fuse(&robust.fuse_params(&t, 5)).expect("best candidate");
        assert!(view.is_view_of(&robust.project_params(&t)));
        let moved = se3::exp(&[0.01, -0.02, 0.03, 0.1, 0.2, -0.3001]);
        assert!(!view.is_view_of(&robust.project_params(&moved)));
        let mut other_size = robust.project_params(&t);
        other_size.width /= 2;
        assert!(!view.is_view_of(&other_size));
        let assignment = Slam::new(
            CpuBackend::new(),
            Intrinsics::ICL_NUIM,
            SlamParams::profile(Profile::Assignment),
        );
        assert_eq!(FusedView::of_fuse(&assignment.fuse_params(&t, 5)), None);
    }
}
