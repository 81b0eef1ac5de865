//! [`SlamParams`]: every tunable of the dense pipeline, the named [`Profile`]s they start
//! from, and the robust profile's measured constants (the reason in a line each; the
//! measurements behind them in `docs/robust-profile.md`). Turning these into the kernels'
//! parameter structs is `step_params.rs`'s job.

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
    /// Raw depth units per metre (the sequence's own: [`crate::slam::pipeline::Slam::for_sequence`] sets it).
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
/// units of the surfel weight: summed `pixel_confidence`s, at most 1 per observation. It
/// trims the copies seen a few times and never again without moving the ATE; the longest
/// window (20 / 20) that removes the most (measurements: `docs/robust-profile.md`).
pub const ROBUST_STABLE_WEIGHT: f32 = 20.0;
/// How often the robust profile's removal rule runs, frames: compaction copies the whole
/// map, and an unstable surfel can stay a few frames longer at no cost to tracking or map
/// size (measurements: `docs/robust-profile.md`).
pub const ROBUST_REMOVAL_EVERY: u32 = 10;
/// Pruning radius of the robust profile's duplicate removal (`fuse_prune`), in the larger
/// surfel radius: with 0.5 the map stops growing over revisits of noisy depth while the ATE
/// moves by 0.2 mm; wider, it removes surfels tracking needs (measurements:
/// `docs/robust-profile.md`).
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

/// Huber threshold of the robust profile, metres: about 3 sigma of the depth noise at 2 m
/// (sigma(2 m) = 6 mm by the model in `cpu::icp_reduce`), so residuals of well-matched
/// points keep full weight and mismatches beyond are down-weighted, not cut.
pub const ROBUST_HUBER_M: f32 = 0.02;

/// Fusion gates of the robust profile: the depth gate (along the pixel's ray with
/// best-candidate association) and the normal-angle gate. Noisy normals rarely agree
/// within the assignment's 5 degrees; 60 degrees is the widest gate that still separates a
/// wall from the floor it meets (measurements: `docs/robust-profile.md`).
pub const ROBUST_FUSE_DIST_M: f32 = 0.05;
/// See [`ROBUST_FUSE_DIST_M`].
pub const ROBUST_FUSE_NORMAL_DEG: f32 = 60.0;

/// Confidence sigma of the robust profile: ElasticFusion's 0.6 (a measurement at the
/// image corner weighs 0.25 of one at the centre); neutral on ICL-NUIM, whose noise model
/// has no lens falloff (measurements: `docs/robust-profile.md`).
pub const ROBUST_CONFIDENCE_SIGMA: f32 = 0.6;

/// Convergence threshold of the robust profile (radians and metres): noisy depth moves
/// every increment by more than the assignment's 1e-6, so ICP would always use all its
/// iterations; 1e-5 (10 micrometres, 2 millidegrees) is far below the noise.
pub const ROBUST_MIN_INCREMENT: f64 = 1e-5;

/// ICP iterations per pyramid level of the robust profile, coarse to fine (level 2 at
/// 80x60, level 1 at 160x120, level 0 at 320x240 with the default downsampling):
/// KinectFusion's schedule, the cheapest measured that keeps tracking at every 12th frame
/// of ICL kt2 (measurements: `docs/robust-profile.md`).
pub const ROBUST_ICP_LEVEL_ITERS: [usize; 3] = [10, 5, 4];

/// Most pyramid levels a schedule may have (`--icp-level-iters`): a fourth level is 40x30
/// at the default 320x240, a fifth would be 20x15, too few pixels to constrain a pose
/// ([`crate::slam::solve::MIN_INLIERS`] correspondences at the least).
pub const MAX_ICP_LEVELS: usize = 4;
