//! [`SlamParams`]: every tunable of the dense pipeline, the named [`Profile`]s they start
//! from, and the robust profile's measured constants (the reason in a line each; the
//! measurements behind them in `docs/robust-profile.md`). Turning these into the kernels'
//! parameter structs is `step_params.rs`'s job.

use crate::{Error, Result};

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

/// Every tunable of the dense pipeline, grouped by the stage that reads it (as kiss-icp
/// groups its configuration by module). `Default` is the robust profile. Each leaf is one
/// `wgslam run` option (named in its documentation) and one key of a parameter file
/// (`docs/params-file.md`); [`SlamParams::validate`] checks their ranges.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct SlamParams {
    /// The profile these values started from (each may have been overridden since;
    /// `--profile`).
    pub profile: Profile,
    /// Tracking or ground-truth poses (`run --poses`).
    pub poses: PoseSource,
    /// How raw frames become the maps every later stage reads (`depth_to_vertex`).
    pub input: InputSettings,
    /// The normal map (`vertex_to_normal`).
    pub normals: NormalSettings,
    /// The edge-preserving bilateral depth filter between `depth_to_vertex` and
    /// `vertex_to_normal`; `None` runs without it (`--bilateral` and its settings).
    pub bilateral: Option<BilateralSettings>,
    /// Frame-to-model ICP (`icp_reduce`, the solve and its schedule).
    pub icp: IcpSettings,
    /// Surfel fusion (`fuse_*`) and the removal of unstable surfels (`compact`).
    pub fusion: FusionSettings,
    /// The tracking-health test that reports a frame as lost instead of fusing it at a
    /// wrong pose (`slam::health`); `None` accepts every pose ICP returns, as before
    /// (`--tracking-health false`).
    pub health: Option<HealthSettings>,
    /// Relocalisation after a lost frame from a fern keyframe database
    /// (`slam::keyframes`); `None` only retries from the last tracked pose
    /// (`--relocalise false`). Needs [`SlamParams::health`].
    pub relocalisation: Option<RelocalisationSettings>,
    /// Loop closure: loops to old keyframes verified by ICP, a pose graph, and the map
    /// deformed with it (`slam::loops`); `None` tracks without (`--loop-closure off`).
    /// Needs [`SlamParams::relocalisation`] and [`SlamParams::health`] (the keyframe
    /// database): without them the pipeline runs without loop closure (the command line
    /// refuses `--loop-closure on` with either off).
    pub loop_closure: Option<LoopSettings>,
}

/// Loop closure (`slam::loops`; the defaults' reasons are at [`LOOP_MIN_GAP_FRAMES`]).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct LoopSettings {
    /// A keyframe is a loop candidate only this many frames or more before the frame.
    pub min_gap_frames: u32,
    /// Frames between two loop searches (a search costs a verification ICP).
    pub search_every_frames: u32,
    /// Frames after an accepted loop before the next search.
    pub cooldown_frames: u32,
    /// Global loops: keyframes at least this fern-alike.
    pub min_similarity: f64,
    /// Local loops: keyframes whose pose (as now estimated) is within this of the frame's,
    /// metres and degrees.
    pub local_radius_m: f64,
    pub local_angle_deg: f64,
    /// ICP iterations of a verification, at the pyramid level of the snapshots.
    pub verify_iterations: usize,
    /// A verified loop: inliers at least this fraction of the keyframe snapshot's valid
    /// pixels ...
    pub min_inlier_fraction: f64,
    /// ... an RMS residual at most this (metres) ...
    pub max_rms_m: f64,
    /// ... and a correction of the frame's pose at most this, metres and degrees.
    pub max_correction_m: f64,
    pub max_correction_deg: f64,
    /// A loop whose correction is below both of these is accepted without optimising
    /// (the trajectory already agrees), metres and degrees.
    pub min_correction_m: f64,
    pub min_correction_deg: f64,
    /// A pose-graph node every this many tracked frames (and one per keyframe).
    pub node_stride: u32,
    /// A loop edge's weight against an odometry edge's 1.
    pub loop_weight: f64,
}

/// The tracking-health test of a frame's final ICP state (see `slam::health` for the
/// measurements behind the defaults).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct HealthSettings {
    /// Lost below this fraction of candidate pixels (past filter 1) that are inliers at the
    /// finest level's last iteration (`--health-min-inliers`).
    pub min_inlier_fraction: f64,
    /// Lost when the finest level's RMS residual is above this many times its typical
    /// value (the median over the last tracked frames) (`--health-max-residual-ratio`).
    pub max_residual_ratio: f64,
    /// Lost when the frame's motion (translation or rotation) is above this many times its
    /// typical per-frame value and above the floors below.
    pub max_motion_ratio: f64,
    /// Motion below these is never suspicious, metres and degrees per frame.
    pub motion_floor_m: f64,
    pub motion_floor_deg: f64,
    /// Tracked frames before the residual and motion tests start (they need a typical
    /// value); the inlier test holds from the second frame on.
    pub warmup_frames: usize,
    /// A recovery (a relocalisation attempt, or tracking from the last pose after lost
    /// frames) must have a residual ratio at most this ...
    pub recovery_max_residual_ratio: f64,
    /// ... and an inlier fraction at least this times the typical one.
    pub recovery_min_inlier_ratio: f64,
}

/// Relocalisation from the fern keyframe database.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct RelocalisationSettings {
    /// Ferns per frame code.
    pub ferns: usize,
    /// A tracked frame becomes a keyframe when its dissimilarity to every keyframe (the
    /// fraction of fern codes that differ) is above this.
    pub keyframe_dissimilarity: f64,
    /// Keyframes tried (ICP from their poses against the map) per lost frame, most alike
    /// first.
    pub candidates: usize,
    /// Keyframes less alike than this are not tried.
    pub min_similarity: f64,
    /// A tracked frame also becomes a keyframe when every keyframe's pose is farther than
    /// this (metres) or turned more than `keyframe_angle_deg` (degrees).
    pub keyframe_distance_m: f64,
    pub keyframe_angle_deg: f64,
    /// The database's size limit (memory stays bounded on any sequence).
    pub max_keyframes: usize,
}

/// How raw frames are read into the (downsampled) vertex maps (`depth_to_vertex`).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct InputSettings {
    /// Keep every N-th pixel in each direction, 1 to [`MAX_DOWNSAMPLE`] (`--downsample`;
    /// both profiles 2).
    pub downsample: u32,
    /// Raw depth units per metre. The sequence's own replaces it ([`Slam::for_sequence`]);
    /// set it with the dataset option `--depth-scale`.
    ///
    /// [`Slam::for_sequence`]: crate::slam::pipeline::Slam::for_sequence
    pub depth_scale: f32,
    /// Nearer pixels are invalid, metres (`--min-depth`).
    pub min_depth_m: f32,
    /// Farther pixels are invalid, metres (`--max-depth`).
    pub max_depth_m: f32,
}

/// The normal map (`vertex_to_normal`).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct NormalSettings {
    /// Normals across a depth jump larger than this (metres) are invalid
    /// (`--max-depth-jump`).
    pub max_depth_jump_m: f32,
}

/// Frame-to-model ICP: the association gates and row weights of `icp_reduce`, the
/// coarse-to-fine schedule and the convergence test.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct IcpSettings {
    /// Filter 2: maximum point distance, metres (`--icp-dist`).
    pub dist_m: f32,
    /// Filter 2: maximum angle between model and frame normals, degrees; 180 or more turns
    /// the gate off (`--icp-angle`).
    pub normal_deg: f32,
    /// Huber threshold on the point-to-plane residual, metres; 0 turns the weight off
    /// (`--icp-huber`).
    pub huber_m: f32,
    /// Weight each row by the depth-noise model (`cpu::icp_reduce::noise_weight`;
    /// `--icp-noise-weight`).
    pub noise_weight: bool,
    /// Iterations per pyramid level at most, coarse to fine: one entry per level, the last
    /// for level 0 (the full maps). `[10]` (the assignment's) is single-level ICP; the
    /// robust profile's is [`ROBUST_ICP_LEVEL_ITERS`]. 1 to [`MAX_ICP_LEVELS`] entries, each
    /// at least 1 (`--icp-level-iters`).
    pub level_iters: Vec<usize>,
    /// Stop iterating when the increment's rotation (rad) and translation (m) are both
    /// below (`--icp-min-increment`).
    pub min_increment: f64,
    /// How the frame's coarser pyramid levels are made (used with more than one level).
    pub pyramid: PyramidSettings,
    /// Degenerate geometry: eigen-directions of AᵀA with an eigenvalue below this fraction
    /// of the largest get no update (`solve::NormalEquations::solve_guarded`); 0 refuses a
    /// system below `solve::MIN_RECIPROCAL_CONDITION` instead (the assignment's)
    /// (`--icp-degenerate-ratio`).
    pub degenerate_eigen_ratio: f64,
}

/// Surfel fusion: the association and its gates, the measurements' weights, duplicate
/// pruning and the removal of unstable surfels.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct FusionSettings {
    /// Filter 2: maximum point distance, metres (`--fuse-dist`).
    pub dist_m: f32,
    /// Filter 2: maximum normal angle, degrees (`--fuse-angle`).
    pub normal_deg: f32,
    /// How fusion pairs pixels with surfels (`--fuse-association`).
    pub association: Association,
    /// Standard deviation of a measurement's confidence over its normalised distance from
    /// the image centre (`pixel_confidence`); 0 weighs every measurement 1 (counts;
    /// `--confidence-sigma`).
    pub confidence_sigma: f32,
    /// Best-candidate fusion's pruning of duplicate surfels (`fuse_prune`), in radii; 0
    /// turns it off (`--prune-scale`). It runs on the frames
    /// [`FusionSettings::unstable_removal`] runs after, or on every frame without the
    /// removal. A retired surfel has weight 0 and last frame 0, so the removal drops it
    /// once the frame is past `max_age_frames` (from frame 30 on in the robust profile, at
    /// once; retired on frames 10 and 20, at frame 30). See [`ROBUST_PRUNE_RADIUS_SCALE`].
    pub prune_scale: f32,
    /// Removal of unstable surfels after each fusion (the `compact` step); `None` (the
    /// assignment) keeps every surfel (`--stable-weight`, `--unstable-max-age`,
    /// `--removal-every`).
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

impl Default for HealthSettings {
    fn default() -> Self {
        HealthSettings {
            min_inlier_fraction: HEALTH_MIN_INLIER_FRACTION,
            max_residual_ratio: HEALTH_MAX_RESIDUAL_RATIO,
            max_motion_ratio: HEALTH_MAX_MOTION_RATIO,
            motion_floor_m: HEALTH_MOTION_FLOOR_M,
            motion_floor_deg: HEALTH_MOTION_FLOOR_DEG,
            warmup_frames: HEALTH_WARMUP_FRAMES,
            recovery_max_residual_ratio: HEALTH_RECOVERY_MAX_RESIDUAL_RATIO,
            recovery_min_inlier_ratio: HEALTH_RECOVERY_MIN_INLIER_RATIO,
        }
    }
}

impl Default for RelocalisationSettings {
    fn default() -> Self {
        RelocalisationSettings {
            ferns: RELOC_FERNS,
            keyframe_dissimilarity: RELOC_KEYFRAME_DISSIMILARITY,
            candidates: RELOC_CANDIDATES,
            min_similarity: RELOC_MIN_SIMILARITY,
            keyframe_distance_m: RELOC_KEYFRAME_DISTANCE_M,
            keyframe_angle_deg: RELOC_KEYFRAME_ANGLE_DEG,
            max_keyframes: RELOC_MAX_KEYFRAMES,
        }
    }
}

impl Default for LoopSettings {
    fn default() -> Self {
        LoopSettings {
            min_gap_frames: LOOP_MIN_GAP_FRAMES,
            search_every_frames: LOOP_SEARCH_EVERY_FRAMES,
            cooldown_frames: LOOP_COOLDOWN_FRAMES,
            min_similarity: LOOP_MIN_SIMILARITY,
            local_radius_m: LOOP_LOCAL_RADIUS_M,
            local_angle_deg: LOOP_LOCAL_ANGLE_DEG,
            verify_iterations: LOOP_VERIFY_ITERATIONS,
            min_inlier_fraction: LOOP_MIN_INLIER_FRACTION,
            max_rms_m: LOOP_MAX_RMS_M,
            max_correction_m: LOOP_MAX_CORRECTION_M,
            max_correction_deg: LOOP_MAX_CORRECTION_DEG,
            min_correction_m: LOOP_MIN_CORRECTION_M,
            min_correction_deg: LOOP_MIN_CORRECTION_DEG,
            node_stride: LOOP_NODE_STRIDE,
            loop_weight: LOOP_WEIGHT,
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
            poses: PoseSource::Track,
            input: InputSettings {
                downsample: 2,
                depth_scale: 5000.0,
                min_depth_m: 0.1,
                max_depth_m: 10.0,
            },
            normals: NormalSettings {
                max_depth_jump_m: 0.1,
            },
            bilateral: None,
            icp: IcpSettings {
                dist_m: 0.07,
                normal_deg: 180.0,
                huber_m: 0.0,
                noise_weight: false,
                level_iters: vec![10],
                min_increment: 1e-6,
                pyramid: PyramidSettings::default(),
                degenerate_eigen_ratio: 0.0,
            },
            fusion: FusionSettings {
                dist_m: 0.03,
                normal_deg: 5.0,
                association: Association::Projective,
                confidence_sigma: 0.0,
                prune_scale: 0.0,
                unstable_removal: None,
            },
            health: Some(HealthSettings::default()),
            relocalisation: Some(RelocalisationSettings::default()),
            // The assignment's algorithm has no loop closure.
            loop_closure: None,
        };
        match profile {
            Profile::Assignment => assignment,
            Profile::Robust => SlamParams {
                bilateral: Some(BilateralSettings::default()),
                icp: IcpSettings {
                    dist_m: 0.10,
                    normal_deg: 20.0,
                    huber_m: ROBUST_HUBER_M,
                    noise_weight: true,
                    level_iters: ROBUST_ICP_LEVEL_ITERS.to_vec(),
                    min_increment: ROBUST_MIN_INCREMENT,
                    degenerate_eigen_ratio: ROBUST_DEGENERATE_EIGEN_RATIO,
                    ..assignment.icp
                },
                fusion: FusionSettings {
                    dist_m: ROBUST_FUSE_DIST_M,
                    normal_deg: ROBUST_FUSE_NORMAL_DEG,
                    association: Association::BestCandidate,
                    confidence_sigma: ROBUST_CONFIDENCE_SIGMA,
                    prune_scale: ROBUST_PRUNE_RADIUS_SCALE,
                    unstable_removal: Some(UnstableRemoval::default()),
                },
                loop_closure: Some(LoopSettings::default()),
                ..assignment
            },
        }
    }

    /// Checks every value's range; the error ([`Error::Argument`]) names the option that
    /// sets it (`--icp-dist`, also the parameter file's key without the dashes). Every
    /// command validates its parameters before running (the CLI's `ParamOverrides::
    /// slam_params`), and so do the jobs `tools::run`, `tools::two_frame` and
    /// `tools::compare`.
    pub fn validate(&self) -> Result<()> {
        let fail = |msg: String| Err(Error::Argument(msg));
        let positive = |v: f64| v.is_finite() && v > 0.0;
        let off_or_positive = |v: f64| v.is_finite() && v >= 0.0;
        let i = &self.input;
        if i.downsample == 0 || i.downsample > MAX_DOWNSAMPLE {
            return fail(format!(
                "--downsample {} must be between 1 and {MAX_DOWNSAMPLE}",
                i.downsample
            ));
        }
        if !positive(i.depth_scale as f64) {
            return fail(format!("--depth-scale {} must be positive", i.depth_scale));
        }
        if !(i.min_depth_m.is_finite()
            && i.min_depth_m >= 0.0
            && i.max_depth_m.is_finite()
            && i.max_depth_m > i.min_depth_m)
        {
            return fail(format!(
                "--min-depth {} and --max-depth {} must be a range 0 <= min < max",
                i.min_depth_m, i.max_depth_m
            ));
        }
        if let Some(b) = &self.bilateral {
            if b.radius_px > MAX_BILATERAL_RADIUS {
                return fail(format!(
                    "--bilateral-radius {} must be at most {MAX_BILATERAL_RADIUS}",
                    b.radius_px
                ));
            }
            if !positive(b.sigma_space_px as f64) {
                return fail(format!(
                    "--bilateral-sigma-space {} must be a positive number",
                    b.sigma_space_px
                ));
            }
            let (depth, z2) = (b.sigma_depth_m, b.sigma_depth_per_m2);
            if !(depth >= 0.0 && z2 >= 0.0 && depth + z2 > 0.0 && (depth + z2).is_finite()) {
                return fail(format!(
                    "--bilateral-sigma-depth {depth} and --bilateral-sigma-depth-z2 {z2} must \
                     be non-negative numbers, not both zero"
                ));
            }
        }
        let icp = &self.icp;
        let s = &icp.level_iters;
        if s.is_empty() || s.len() > MAX_ICP_LEVELS || s.contains(&0) {
            return fail(format!(
                "--icp-level-iters {s:?}: want 1 to {MAX_ICP_LEVELS} iteration counts, coarse \
                 to fine, each at least 1 (e.g. 10,5,4)"
            ));
        }
        if icp.pyramid.radius_px > MAX_BILATERAL_RADIUS {
            return fail(format!(
                "--pyramid-radius {} must be at most {MAX_BILATERAL_RADIUS}",
                icp.pyramid.radius_px
            ));
        }
        let f = &self.fusion;
        if !positive(icp.min_increment) {
            return fail(format!(
                "--icp-min-increment {} must be positive",
                icp.min_increment
            ));
        }
        for (flag, v) in [
            ("--max-depth-jump", self.normals.max_depth_jump_m),
            ("--pyramid-depth-gate-z2", icp.pyramid.max_depth_diff_per_m2),
            ("--icp-dist", icp.dist_m),
            ("--icp-angle", icp.normal_deg),
            ("--fuse-dist", f.dist_m),
            ("--fuse-angle", f.normal_deg),
        ] {
            if !positive(v as f64) {
                return fail(format!("{flag} {v} must be positive"));
            }
        }
        for (flag, v) in [
            ("--icp-huber", icp.huber_m),
            ("--confidence-sigma", f.confidence_sigma),
            ("--prune-scale", f.prune_scale),
        ] {
            if !off_or_positive(v as f64) {
                return fail(format!("{flag} {v} must be 0 (off) or positive"));
            }
        }
        if !(icp.degenerate_eigen_ratio.is_finite()
            && (0.0..1.0).contains(&icp.degenerate_eigen_ratio))
        {
            return fail(format!(
                "--icp-degenerate-ratio {} must be 0 (off) or a fraction below 1",
                icp.degenerate_eigen_ratio
            ));
        }
        if let Some(h) = &self.health {
            if !(0.0..=1.0).contains(&h.min_inlier_fraction) {
                return fail(format!(
                    "--health-min-inliers {} must be a fraction between 0 and 1",
                    h.min_inlier_fraction
                ));
            }
            for (flag, v) in [
                ("--health-max-residual-ratio", h.max_residual_ratio),
                ("health.max_motion_ratio", h.max_motion_ratio),
                ("health.motion_floor_m", h.motion_floor_m),
                ("health.motion_floor_deg", h.motion_floor_deg),
            ] {
                if !positive(v) {
                    return fail(format!("{flag} {v} must be positive"));
                }
            }
        }
        if let Some(r) = &self.relocalisation {
            if r.ferns == 0 || r.ferns > MAX_FERNS || r.candidates == 0 || r.max_keyframes == 0 {
                return fail(format!(
                    "relocalisation: ferns ({}, at most {MAX_FERNS}), candidates ({}) and \
                     max_keyframes ({}) must be at least 1",
                    r.ferns, r.candidates, r.max_keyframes
                ));
            }
        }
        if let Some(l) = &self.loop_closure {
            if l.search_every_frames == 0 || l.node_stride == 0 || l.verify_iterations == 0 {
                return fail(
                    "loop closure: search_every_frames, node_stride and verify_iterations \
                     must be at least 1"
                        .into(),
                );
            }
            for (name, v) in [
                ("loop.min_inlier_fraction", l.min_inlier_fraction),
                ("loop.max_rms_m", l.max_rms_m),
                ("loop.max_correction_m", l.max_correction_m),
                ("loop.max_correction_deg", l.max_correction_deg),
                ("loop.loop_weight", l.loop_weight),
            ] {
                if !positive(v) {
                    return fail(format!("{name} {v} must be positive"));
                }
            }
        }
        if let Some(r) = &f.unstable_removal {
            if !off_or_positive(r.stable_weight as f64) {
                return fail(format!(
                    "--stable-weight {} must be 0 (off) or positive",
                    r.stable_weight
                ));
            }
            if r.every_frames == 0 {
                return fail("--removal-every must be at least 1".into());
            }
        }
        Ok(())
    }
}

/// Largest [`InputSettings::downsample`]: 16 is 40x30 maps from 640x480 frames.
pub const MAX_DOWNSAMPLE: u32 = 16;

/// Ferns per code at most (the database stores a byte per fern per keyframe).
pub const MAX_FERNS: usize = 4096;

/// Largest [`BilateralSettings::radius_px`] and [`PyramidSettings::radius_px`]: a 33x33
/// window is already far past any useful one.
pub const MAX_BILATERAL_RADIUS: u32 = 16;

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

/// The robust profile's degenerate-direction guard: well below the smallest eigenvalue
/// ratio of any frame of the sequences here, far above a plane's (see `slam::health`).
pub const ROBUST_DEGENERATE_EIGEN_RATIO: f64 = 1e-4;

/// Tracking-health defaults (both profiles); the measurements are in `slam::health`'s
/// header.
pub const HEALTH_MIN_INLIER_FRACTION: f64 = 0.3;
pub const HEALTH_MAX_RESIDUAL_RATIO: f64 = 4.0;
pub const HEALTH_MAX_MOTION_RATIO: f64 = 8.0;
pub const HEALTH_MOTION_FLOOR_M: f64 = 0.10;
pub const HEALTH_MOTION_FLOOR_DEG: f64 = 8.0;
pub const HEALTH_WARMUP_FRAMES: usize = 5;
pub const HEALTH_RECOVERY_MAX_RESIDUAL_RATIO: f64 = 1.3;
pub const HEALTH_RECOVERY_MIN_INLIER_RATIO: f64 = 0.75;

/// Relocalisation defaults: ElasticFusion's 500 ferns and its keyframe threshold (0.3095,
/// rounded), five candidates per lost frame, candidates at least 30 % alike (its
/// `blockHDAware > 0.3`), at most 2,000 keyframes (57 MB of codes and features).
pub const RELOC_FERNS: usize = 500;
pub const RELOC_KEYFRAME_DISSIMILARITY: f64 = 0.3;
pub const RELOC_CANDIDATES: usize = 5;
/// Keyframes at least every 0.15 m or 10 degrees of the path: within the basin of ICP's
/// 0.10 m / 20 degree gates from any point of the path.
pub const RELOC_KEYFRAME_DISTANCE_M: f64 = 0.15;
pub const RELOC_KEYFRAME_ANGLE_DEG: f64 = 10.0;
pub const RELOC_MIN_SIMILARITY: f64 = 0.3;
pub const RELOC_MAX_KEYFRAMES: usize = 2_000;

/// Loop-closure defaults. A loop is a return after at least 60 frames (2 s at 30 Hz:
/// nearer keyframes are what tracking itself aligns against); searched every 5 frames and
/// not for 30 frames after a closure (a return is seen over many frames; one closure per
/// return is enough, and a search costs an ICP of 10 iterations at the snapshots' level).
pub const LOOP_MIN_GAP_FRAMES: u32 = 60;
pub const LOOP_SEARCH_EVERY_FRAMES: u32 = 5;
pub const LOOP_COOLDOWN_FRAMES: u32 = 30;
/// Global candidates at least 50 % fern-alike (relocalisation tries from 30 %: a loop
/// changes the map, so it asks for more).
pub const LOOP_MIN_SIMILARITY: f64 = 0.5;
/// Local candidates: keyframes within ICP's basin (about 0.25 m / 12 degrees, see
/// `slam::pipeline::FEATURE_ICP_AGREEMENT_M`) of the frame's pose as estimated.
pub const LOOP_LOCAL_RADIUS_M: f64 = 0.25;
pub const LOOP_LOCAL_ANGLE_DEG: f64 = 12.0;
pub const LOOP_VERIFY_ITERATIONS: usize = 10;
/// Verification: half the snapshot's pixels inliers (tracking's health test asks 30 % of
/// the candidates; a loop's view overlaps its keyframe's by construction), an RMS
/// residual of at most 15 mm (tracking's typical residual on the real sequences here is
/// 5-10 mm at the coarse levels), and a correction within ICP's basin.
pub const LOOP_MIN_INLIER_FRACTION: f64 = 0.5;
pub const LOOP_MAX_RMS_M: f64 = 0.015;
pub const LOOP_MAX_CORRECTION_M: f64 = 0.25;
pub const LOOP_MAX_CORRECTION_DEG: f64 = 12.0;
/// Corrections below 10 mm and 1 degree are within the verification's own noise (a
/// frame registered against a 160 x 120 snapshot: 5-20 mm and 1-4 degrees against the
/// 7-Scenes reference poses): such a loop is recorded, but nothing moves.
pub const LOOP_MIN_CORRECTION_M: f64 = 0.010;
pub const LOOP_MIN_CORRECTION_DEG: f64 = 1.0;
/// A pose-graph node every 10 tracked frames (a 1,000-frame run: about 100 nodes plus
/// keyframes, a solve of milliseconds).
pub const LOOP_NODE_STRIDE: u32 = 10;
/// A loop edge weighs as an odometry edge: measured with weight 10 on 7-Scenes 0..299
/// and noisy ICL-NUIM 0..209 (GPU), the ATE was 19.34 / 7.64 mm, with 1 19.32 / 7.55 mm.
pub const LOOP_WEIGHT: f64 = 1.0;

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
        let cases: [(&str, Spoil); 26] = [
            ("--downsample", |p| p.input.downsample = 0),
            ("--downsample", |p| p.input.downsample = MAX_DOWNSAMPLE + 1),
            ("--depth-scale", |p| p.input.depth_scale = 0.0),
            ("--min-depth", |p| p.input.min_depth_m = -0.1),
            ("--max-depth", |p| p.input.max_depth_m = 0.05),
            ("--max-depth", |p| p.input.max_depth_m = f32::INFINITY),
            ("--max-depth-jump", |p| p.normals.max_depth_jump_m = 0.0),
            ("--bilateral-radius", |p| {
                bilateral(p, |b| b.radius_px = MAX_BILATERAL_RADIUS + 1)
            }),
            ("--bilateral-sigma-space", |p| {
                bilateral(p, |b| b.sigma_space_px = 0.0)
            }),
            ("--bilateral-sigma-depth", |p| {
                bilateral(p, |b| b.sigma_depth_m = -0.01)
            }),
            ("--bilateral-sigma-depth-z2", |p| {
                bilateral(p, |b| b.sigma_depth_per_m2 = 0.0)
            }),
            ("--icp-dist", |p| p.icp.dist_m = 0.0),
            ("--icp-angle", |p| p.icp.normal_deg = -20.0),
            ("--icp-huber", |p| p.icp.huber_m = -0.02),
            ("--icp-level-iters", |p| p.icp.level_iters = vec![]),
            ("--icp-level-iters", |p| p.icp.level_iters = vec![10, 0, 4]),
            ("--icp-level-iters", |p| {
                p.icp.level_iters = vec![1; MAX_ICP_LEVELS + 1]
            }),
            ("--icp-min-increment", |p| p.icp.min_increment = 0.0),
            ("--pyramid-depth-gate-z2", |p| {
                p.icp.pyramid.max_depth_diff_per_m2 = f32::NAN
            }),
            ("--fuse-dist", |p| p.fusion.dist_m = -0.05),
            ("--fuse-angle", |p| p.fusion.normal_deg = f32::INFINITY),
            ("--confidence-sigma", |p| p.fusion.confidence_sigma = -1.0),
            ("--prune-scale", |p| p.fusion.prune_scale = f32::NAN),
            ("--stable-weight", |p| {
                removal(p, |r| r.stable_weight = -1.0)
            }),
            ("--removal-every", |p| removal(p, |r| r.every_frames = 0)),
            ("--fuse-dist", |p| p.fusion.dist_m = 0.0),
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
