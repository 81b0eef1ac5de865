//! [`SlamParams`]: every tunable of the dense pipeline, and the named [`Profile`]s they
//! start from. The structs here are the parameters' schema: each field is a key
//! (`icp.dist_m`, [`keys`]) that the command line's flags, parameter files and batch
//! manifests set, [`SlamParams::validate`] checks the values and the rules between
//! sections once and makes them [`ValidParams`] ([`valid`]), what a run takes, and
//! [`defaults`] holds the profiles' measured constants (the reason in a line each) and the
//! keyframe database's and loop closure's settings made of them.
//! Turning these into the kernels' parameter structs is `step_params.rs`'s job.

pub mod defaults;
pub mod keys;
pub mod resolution;
pub mod valid;
pub mod validate;

pub use defaults::*;
pub use keys::{Key, KEY_SECTIONS, OPTIONAL_SECTIONS};
pub use valid::ValidParams;

use clap::ValueEnum;
use serde::{Deserialize, Serialize};

/// Where the poses come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum PoseSource {
    /// Frame-to-model ICP (the first frame at ground truth, or identity without it).
    Track,
    /// Ground-truth poses, no tracking (the fusion-only experiment).
    GroundTruth,
}

/// A named set of [`SlamParams`]: the course assignment's exact algorithm, or the robust
/// tracker for real sensors. Recorded in `metrics.json` with every parameter.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize, clap::ValueEnum,
)]
#[serde(rename_all = "lowercase")]
pub enum Profile {
    /// The handout's experiment: raw normals, one level, a 0.07 m distance gate, no angle
    /// gate, unweighted rows, 0.03 m / 5 degree fusion gates, count weights.
    Assignment,
    /// Tracking and fusion for noisy depth (Keller et al. 2013, ElasticFusion): the
    /// bilateral depth filter; coarse-to-fine ICP over three levels (10, 5 and 4
    /// iterations) with 0.10 m / 20 degree association gates (30 degrees at full
    /// resolution), Huber-weighted rows scaled by
    /// the depth-noise model and a convergence test that noisy data can meet; fusion with
    /// best-candidate association, confidence-weighted averages, surfel radii, wider gates
    /// (0.05 m / 60 degrees), the retirement of duplicate surfels and the removal of
    /// unstable surfels.
    // This text is the command line's help, so it names values, not constants; the test
    // `keys::help_tests` checks them against the profile's.
    Robust,
}

/// Every tunable of the dense pipeline, grouped by the stage that reads it (as kiss-icp
/// groups its configuration by module). `Default` is the robust profile. Each leaf is a
/// key, `section.field` ([`SlamParams::with_keys`]), most of them also a `wgslam run`
/// option (named in its documentation; `docs/params-file.md` lists both);
/// [`SlamParams::validate`] checks their ranges, once, and makes the [`ValidParams`] a
/// run takes.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
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
    /// database; [`SlamParams::validate`] refuses it without them, and
    /// [`SlamParams::with_keys`] turns it off with them unless it is asked for).
    pub loop_closure: Option<LoopSettings>,
}

/// Loop closure (`slam::loops`; the defaults' reasons are at [`LOOP_MIN_GAP_FRAMES`]).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
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
    /// A correction above the `min_correction_*` is applied only when a second
    /// verification, at one of the next `confirm_within_searches` searches, measures the
    /// same correction within these, metres and degrees.
    pub confirm_agreement_m: f64,
    pub confirm_agreement_deg: f64,
    pub confirm_within_searches: u32,
    /// A confirmed loop bends the map only when the optimised graph leaves at most this
    /// fraction of its own disagreement on its edge; more means the rest of the graph
    /// contradicts it, and it is rejected ([`LOOP_MAX_LEFT_FRACTION`]).
    #[serde(default = "default_max_left_fraction")]
    pub max_left_fraction: f64,
    /// ... and when no other loop edge's disagreement grows by more than this, in the
    /// graph's metric (metres, a radian weighing as a metre; [`LOOP_OTHER_EDGE_SLACK_M`]).
    #[serde(default = "default_other_edge_slack_m")]
    pub other_edge_slack_m: f64,
}

fn default_max_left_fraction() -> f64 {
    LOOP_MAX_LEFT_FRACTION
}

fn default_other_edge_slack_m() -> f64 {
    LOOP_OTHER_EDGE_SLACK_M
}

/// The tracking-health test of a frame's final ICP state (see `slam::health` for the
/// measurements behind the defaults).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
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
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
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
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct InputSettings {
    /// Keep every N-th pixel in each direction, 1 to [`MAX_DOWNSAMPLE`] (`--downsample`;
    /// both profiles 2; a command that the user gives none takes the backends' default,
    /// [`resolution`]).
    pub downsample: u32,
    /// Raw depth units per metre, the value the run used. Set by key (`--depth-scale`, a
    /// file's `depth-scale` or `[input] depth_scale`, a manifest's override), it is the
    /// sequence's ([`crate::dataset::SequenceOptions::depth_scale`]: the user's value over
    /// `camera.json`'s over the layout's), which [`Slam::for_sequence`] writes here once.
    ///
    /// [`Slam::for_sequence`]: crate::slam::pipeline::Slam::for_sequence
    pub depth_scale: f32,
    /// Nearer pixels are invalid, metres (`--min-depth`).
    pub min_depth_m: f32,
    /// Farther pixels are invalid, metres (`--max-depth`).
    pub max_depth_m: f32,
}

/// The normal map (`vertex_to_normal`).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct NormalSettings {
    /// Normals across a depth jump larger than this (metres) are invalid
    /// (`--max-depth-jump`).
    pub max_depth_jump_m: f32,
}

/// Frame-to-model ICP: the association gates and row weights of `icp_reduce`, the
/// coarse-to-fine schedule and the convergence test.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct IcpSettings {
    /// Filter 2: maximum point distance, metres (`--icp-dist`).
    pub dist_m: f32,
    /// Filter 2: maximum angle between model and frame normals, degrees; 180 or more turns
    /// the gate off (`--icp-angle`).
    pub normal_deg: f32,
    /// Filter 2's angle gate, degrees, at a pyramid level whose pixels are the sensor's own
    /// (`input.downsample` 1, level 0), where the normals, from neighbours half as far
    /// apart as at the default 2x downsampling, are noisier; 0: `normal_deg` there too
    /// (the assignment's; `--icp-full-res-angle`). See [`ROBUST_ICP_FULL_RES_NORMAL_DEG`].
    #[serde(default)]
    pub full_res_normal_deg: f32,
    /// Level 0's angle gate, degrees, of a second attempt from the last pose at full
    /// resolution when the first failed the health test; 0 (the assignment's), or not
    /// wider than the first attempt's gate: no second attempt (`--icp-retry-angle`). See
    /// [`ROBUST_ICP_RETRY_NORMAL_DEG`].
    #[serde(default)]
    pub full_res_retry_normal_deg: f32,
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
    /// Also stop a level when the increment is within the pose's own noise: its squared
    /// length in the metric of the pose covariance `σ² (AᵀA)⁻¹`
    /// (`solve::NormalEquations::step_chi2`, χ² with 6 degrees of freedom) is below this;
    /// 0 turns the test off (the assignment's). On real depth the increments stop
    /// shrinking at 10-50 micrometres, far below the noise but above `min_increment`: see
    /// [`ROBUST_STOP_CHI2`].
    #[serde(default)]
    pub stop_chi2: f64,
    /// The same test's bar at the iterations with the photometric term (RGB-D tracking),
    /// the step still measured in the geometric term's covariance; 0: `stop_chi2`'s (the
    /// assignment's). See [`ROBUST_PHOTOMETRIC_STOP_CHI2`].
    #[serde(default)]
    pub photometric_stop_chi2: f64,
    /// Stop a level when an increment undoes most of the previous one (projective
    /// association flipping between two correspondence sets), leaving the pose halfway;
    /// off in the assignment's.
    #[serde(default)]
    pub stop_on_reversal: bool,
    /// How the frame's coarser pyramid levels are made (used with more than one level).
    pub pyramid: PyramidSettings,
    /// Degenerate geometry: eigen-directions of AᵀA with an eigenvalue below this fraction
    /// of the largest get no update (`solve::NormalEquations::solve_guarded`); 0 refuses a
    /// system below `solve::MIN_RECIPROCAL_CONDITION` instead (the assignment's)
    /// (`--icp-degenerate-ratio`).
    pub degenerate_eigen_ratio: f64,
    /// What frame-to-model tracking aligns: the depth only (point-to-plane ICP), or depth
    /// and colour (with the photometric term; `--tracking`).
    #[serde(default)]
    pub tracking: Tracking,
    /// With `tracking = "rgbd"`: the photometric term's weight relative to the geometric
    /// one, each normalised by its own mean squared residual of the iteration (so the
    /// weight has no unit and depends on no sensor's noise): 1 trusts a photometric row as
    /// much as a point-to-plane one (`--photometric-weight`; see [`PHOTOMETRIC_WEIGHT`]).
    #[serde(default = "photometric_weight_default")]
    pub photometric_weight: f64,
    /// With `tracking = "rgbd"`: the pyramid levels that carry the photometric term (0: the
    /// full maps, 1 the next coarser, ...; each below the number of `level_iters`)
    /// (`--photometric-levels`; see [`PHOTOMETRIC_LEVELS`]).
    #[serde(default = "photometric_levels_default")]
    pub photometric_levels: Vec<usize>,
}

/// The default of [`IcpSettings::photometric_levels`] (serde's default for files written
/// before the key existed).
fn photometric_levels_default() -> Vec<usize> {
    PHOTOMETRIC_LEVELS.to_vec()
}

/// The default of [`IcpSettings::photometric_weight`] (serde's default for files written
/// before the key existed).
fn photometric_weight_default() -> f64 {
    PHOTOMETRIC_WEIGHT
}

/// What frame-to-model tracking aligns ([`IcpSettings::tracking`]).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize, ValueEnum)]
#[serde(rename_all = "kebab-case")]
pub enum Tracking {
    /// Point-to-plane ICP on the depth alone (the default; docs/rgbd-tracking.md has the
    /// measurements that keep it so).
    #[default]
    Geometric,
    /// Point-to-plane ICP plus a photometric term: the frame's intensity against the
    /// intensity the map predicts, at the pyramid levels --photometric-levels names (the
    /// full maps by default), added to the geometric system with the weight
    /// --photometric-weight (docs/rgbd-tracking.md).
    //
    // Clap shows these doc comments as `--help` text: no intra-doc links
    // (`cli::help_tests`). The code is `cpu::photo_reduce`,
    // `IcpSettings::photometric_levels` and `IcpSettings::photometric_weight`.
    Rgbd,
}

/// Surfel fusion: the association and its gates, the measurements' weights, duplicate
/// pruning and the removal of unstable surfels.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct FusionSettings {
    /// Filter 2: maximum point distance, metres (`--fuse-dist`). With best-candidate
    /// association it is the depth gate of a surfel seen once (weight 1 or less).
    pub dist_m: f32,
    /// Best-candidate association's depth gate for a surfel fused many times, metres
    /// (`--fuse-dist-confident`; `cpu::fuse_depth_gate` narrows a surfel's gate from
    /// `dist_m` towards it as its weight grows). 0, or above `dist_m`: `dist_m` for every
    /// surfel (both profiles; files written before the key). Measurements:
    /// `docs/robust-profile.md`.
    #[serde(default)]
    pub dist_confident_m: f32,
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
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize, clap::ValueEnum,
)]
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
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
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

/// How `pyramid_depth` makes a coarser level of the frame's ICP pyramid (see
/// `cpu::pyramid_depth`): the mean of the depths in a `(2 radius_px + 1)²` window of the
/// finer level around the sampled pixel within `max_depth_diff_m + max_depth_diff_per_m2
/// z²` of its depth `z`. The defaults: a 3x3 window (the smallest one centred on the
/// sampled pixel that covers the 2x2 block of finer pixels a coarse pixel stands for) and
/// a gate of 3 sigma of the bilateral filter's range model
/// (`0.01 z²`, see [`BilateralSettings`]): 3 cm at 1 m, 12 cm at 2 m, the noisy set's
/// disparity steps pass and depth edges between objects do not. See
/// [`ROBUST_ICP_LEVEL_ITERS`] for the measurements.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
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
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct BilateralSettings {
    /// Half-width of the window, pixels: (2r+1)² neighbours.
    pub radius_px: u32,
    /// Spatial Gaussian's standard deviation, pixels.
    pub sigma_space_px: f32,
    /// Range Gaussian's standard deviation on depth differences, metres, at depth 0 ...
    pub sigma_depth_m: f32,
    /// ... plus this times the pixel's depth squared (1/m).
    pub sigma_depth_per_m2: f32,
    /// The filtered depth also makes level 0's points, the ones ICP and fusion rebuild;
    /// off (the default), they keep the raw depth and the filter makes the normals and the
    /// coarser pyramid levels (see `cpu::vertex_to_normal`).
    pub filter_points: bool,
}

impl Default for BilateralSettings {
    fn default() -> Self {
        BilateralSettings {
            radius_px: 1,
            sigma_space_px: 1.0,
            sigma_depth_m: 0.0,
            sigma_depth_per_m2: 0.01,
            filter_points: false,
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
                full_res_normal_deg: 0.0,
                full_res_retry_normal_deg: 0.0,
                huber_m: 0.0,
                noise_weight: false,
                level_iters: vec![10],
                min_increment: 1e-6,
                stop_chi2: 0.0,
                photometric_stop_chi2: 0.0,
                stop_on_reversal: false,
                pyramid: PyramidSettings::default(),
                degenerate_eigen_ratio: 0.0,
                tracking: Tracking::Geometric,
                photometric_weight: PHOTOMETRIC_WEIGHT,
                photometric_levels: PHOTOMETRIC_LEVELS.to_vec(),
            },
            fusion: FusionSettings {
                dist_m: 0.03,
                dist_confident_m: 0.0,
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
                    full_res_normal_deg: ROBUST_ICP_FULL_RES_NORMAL_DEG,
                    full_res_retry_normal_deg: ROBUST_ICP_RETRY_NORMAL_DEG,
                    huber_m: ROBUST_HUBER_M,
                    noise_weight: true,
                    level_iters: ROBUST_ICP_LEVEL_ITERS.to_vec(),
                    min_increment: ROBUST_MIN_INCREMENT,
                    stop_chi2: ROBUST_STOP_CHI2,
                    photometric_stop_chi2: ROBUST_PHOTOMETRIC_STOP_CHI2,
                    stop_on_reversal: true,
                    degenerate_eigen_ratio: ROBUST_DEGENERATE_EIGEN_RATIO,
                    ..assignment.icp
                },
                fusion: FusionSettings {
                    dist_m: ROBUST_FUSE_DIST_M,
                    // Off: narrower gates for confident surfels help single passes and
                    // let a revisiting run's ATE creep up (docs/robust-profile.md).
                    dist_confident_m: 0.0,
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
}
