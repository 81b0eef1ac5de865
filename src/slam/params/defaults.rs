//! The profiles' measured constants and the ranges' limits: the reason for each value in a
//! line, the measurements behind them in `docs/robust-profile.md`, `slam::health` and
//! `docs/loop-closure.md`; and the `Default`s of the sections made of them alone (health,
//! relocalisation, loop closure).

use super::{HealthSettings, LoopSettings, RelocalisationSettings};

/// Stable weight of the robust profile's removal rule (see
/// [`UnstableRemoval`](super::UnstableRemoval)), in the units of the surfel weight: summed
/// `pixel_confidence`s, at most 1 per observation. It trims the copies seen a few times and
/// never again without moving the ATE; the longest window (20 / 20) that removes the most
/// (measurements: `docs/robust-profile.md`).
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

/// Largest [`InputSettings::downsample`](super::InputSettings::downsample): 16 is 40x30
/// maps from 640x480 frames.
pub const MAX_DOWNSAMPLE: u32 = 16;

/// Ferns per code at most (the database stores a byte per fern per keyframe).
pub const MAX_FERNS: usize = 4096;

/// Largest [`BilateralSettings::radius_px`](super::BilateralSettings::radius_px) and
/// [`PyramidSettings::radius_px`](super::PyramidSettings::radius_px): a 33x33 window is
/// already far past any useful one.
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

/// The robust profile's noise stop test (`icp.stop_chi2`): a level stops when the
/// increment's squared length in the pose's own covariance is below this, the mean of a
/// χ² with 6 degrees of freedom (a step the size noise alone gives). Measured (release,
/// CPU, frames at the iteration limit / ATE, the test off -> 2 -> 6 -> 20): 7-Scenes
/// 0..299 170/300 -> 1 -> 0 -> 0 frames, 20.20 -> 20.19 -> 20.20 -> 20.17 mm; SUN3D frag2
/// 26/50 -> 0 -> 0, 7.99 mm throughout; clean ICL-NUIM 1..200 0/200, 0.217 -> 0.216 mm;
/// noisy ICL-NUIM 1..200 at 640x480 129/200 -> 5 (at 6), 7.60 mm. Iterations per frame
/// halve (14 -> 6.6 on 7-Scenes); the ATE does not move: the last 10-50 micrometre steps
/// the test cuts only followed the noise.
pub const ROBUST_STOP_CHI2: f64 = 6.0;

/// `icp.photometric_stop_chi2` in the robust profile: the noise stop's bar at the
/// iterations with the photometric term. At [`ROBUST_STOP_CHI2`] the full maps of RGB-D
/// frames ran to their budget on a third of the real sensors' frames (7-Scenes 28 %,
/// SUN3D 40 %: 3.4-3.7 level-0 iterations per frame against geometric tracking's 2.0),
/// each iteration two reductions. Measured (release, CPU, ATE and user time against
/// geometric tracking, bar 6 -> 20 -> 60): 7-Scenes 0..299 21.67 -> 21.55 -> 21.20 mm,
/// 1.47x -> 1.37x -> 1.23-1.33x; SUN3D frag2 7.31 -> 7.35 -> 7.31 mm, 1.52x -> 1.44x ->
/// 1.19-1.38x; noisy ICL-NUIM 1..200 at 640x480 3.45 -> 3.46 -> 3.53 mm, 1.30x -> 1.24x
/// -> 1.17-1.21x (`docs/rgbd-tracking.md`).
pub const ROBUST_PHOTOMETRIC_STOP_CHI2: f64 = 60.0;

/// The robust profile's ICP angle gate at full resolution (`icp.full_res_normal_deg`),
/// degrees; 20 at every coarser level. At 640x480 the level-0 normals come from neighbours
/// 1 pixel apart instead of 2, and the 20 degree gate cut the inlier fraction of ordinary
/// frames of Kinect v1 depth to 0.7x its value at 320x240 (TUM fr1/rpy frame 30: 0.52
/// against 0.71), so during fast motion frames fell under the health test's 30 % and were
/// lost (fr1/rpy 0..399: 37 frames) though they track at 320x240. 25 degrees, with a
/// second attempt at 30 ([`ROBUST_ICP_RETRY_NORMAL_DEG`]) for a frame that fails, met every
/// target of issue 45 at 640x480 but fr1/rpy's 15 mm (release, GPU on lavapipe): fr1/rpy
/// 0..399 0 lost, 30.32 mm; 7-Scenes 0..299 20.49 mm; noisy ICL-NUIM 1..200 5.76 mm;
/// noise-free 0.098 mm; SUN3D frag2 8.30 mm. 30 degrees alone gave noise-free ICL-NUIM
/// 0.114 mm, 25 alone lost 13 fr1/rpy frames (`docs/full-resolution.md`).
pub const ROBUST_ICP_FULL_RES_NORMAL_DEG: f32 = 25.0;

/// The robust profile's angle gate at level 0 of the second attempt at full resolution
/// (`icp.full_res_retry_normal_deg`), degrees: a frame whose first attempt failed the
/// health test is tracked again from the last pose with this wider gate before it is
/// declared lost (and relocalised): 6 frames of fr1/rpy 0..399 (41-51), none of 7-Scenes
/// 0..299, SUN3D or ICL-NUIM. Measured: see [`ROBUST_ICP_FULL_RES_NORMAL_DEG`].
pub const ROBUST_ICP_RETRY_NORMAL_DEG: f32 = 30.0;

/// ICP iterations per pyramid level of the robust profile, coarse to fine (level 2 at
/// 80x60, level 1 at 160x120, level 0 at 320x240 with the default downsampling):
/// KinectFusion's schedule, the cheapest measured that keeps tracking at every 12th frame
/// of ICL kt2 (measurements: `docs/robust-profile.md`).
pub const ROBUST_ICP_LEVEL_ITERS: [usize; 3] = [10, 5, 4];

/// Most pyramid levels a schedule may have (`--icp-level-iters`): a fourth level is 40x30
/// at the default 320x240, a fifth would be 20x15, too few pixels to constrain a pose
/// ([`crate::slam::solve::MIN_INLIERS`] correspondences at the least).
pub const MAX_ICP_LEVELS: usize = 4;

/// Most ICP iterations at one pyramid level (`--icp-level-iters`): the defaults use 4 to
/// 10 and converge in fewer; 1000 at 640x480 is already minutes a frame on a CPU, and
/// 4e9 never ends.
pub const MAX_ICP_ITERS_PER_LEVEL: usize = 1000;

/// Smallest accepted `icp.min_increment` (pose-update norm, metres and radians mixed):
/// an f64 pose update cannot resolve a change below ~1e-15 of a metre-scale pose, so a
/// smaller threshold only means "never stop early".
pub const MIN_ICP_MIN_INCREMENT: f64 = 1e-15;

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
/// `slam::recovery::FEATURE_ICP_AGREEMENT_M`) of the frame's pose as estimated.
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
/// A correction above noise is applied only when a second verification, at one of the
/// next [`LOOP_CONFIRM_WITHIN_SEARCHES`] searches, measures the same correction within
/// these (metres, degrees): a single frame-to-keyframe registration at the snapshots' level
/// is off by 5-20 mm and 1-4 degrees now and then (7-Scenes, against the reference poses),
/// and bending the map by such an error tears it (a 1,000-frame revisiting run of
/// 7-Scenes grew its map by a third and its ATE from 21 to 25 mm without this test).
pub const LOOP_CONFIRM_AGREEMENT_M: f64 = 0.010;
pub const LOOP_CONFIRM_AGREEMENT_DEG: f64 = 1.0;
pub const LOOP_CONFIRM_WITHIN_SEARCHES: u32 = 2;
/// A bend must take at least half of the disagreement it was measured from off its loop
/// edge: with odometry and loop edges weighted alike, a cycle of `k` odometry edges leaves
/// about `1 / (k + 1)` of it (a tenth or less for the 60-frame minimum gap at a node per 10
/// frames); leaving half or more means other loop edges hold the trajectory where it is,
/// i.e. the graph contradicts the new loop.
pub const LOOP_MAX_LEFT_FRACTION: f64 = 0.5;
/// Another loop edge's disagreement may grow by at most 1 mm (graph metric) when a new
/// loop bends the graph: a tenth of the smallest correction that bends anything
/// ([`LOOP_MIN_CORRECTION_M`]), so a bend may redistribute rounding but never undo what an
/// earlier loop that bent the map measured.
pub const LOOP_OTHER_EDGE_SLACK_M: f64 = 0.001;

/// `icp.photometric_weight`: the photometric term's weight relative to the geometric one,
/// both normalised by their mean squared residuals (see
/// [`super::IcpSettings::photometric_weight`]). Measured (release, CPU, ATE geometric ->
/// w = 0.3 -> w = 1): SUN3D frag2 7.99 -> 7.31 -> 7.87 mm; 7-Scenes 0..299 (colour not
/// registered to depth) 20.80 -> 21.67 -> 23.52 mm; noisy ICL-NUIM 1..200 at 640x480
/// 7.60 -> 3.45 -> 1.81 mm: 0.3 is the best of the two real sensors
/// (`docs/rgbd-tracking.md`).
pub const PHOTOMETRIC_WEIGHT: f64 = 0.3;

/// `icp.photometric_levels`: the pyramid levels with the photometric term, the full maps
/// only. Measured (release, CPU, robust profile, ATE at `[0]` -> `[0, 1]` -> `[0, 1, 2]`):
/// SUN3D frag2 7.31 -> 7.53 -> 7.55 mm; 7-Scenes 0..299 21.67 -> 21.69 -> 21.66 mm; noisy
/// ICL-NUIM 1..200 at 640x480 3.45 -> 3.43 -> 3.43 mm, for about the same time; the
/// coarse levels alone (`[1, 2]`) track as the geometric term does (7.99, 20.79, 7.54 mm):
/// the term's gain is all at the full maps (`docs/rgbd-tracking.md`).
pub const PHOTOMETRIC_LEVELS: &[usize] = &[0];

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
            confirm_agreement_m: LOOP_CONFIRM_AGREEMENT_M,
            confirm_agreement_deg: LOOP_CONFIRM_AGREEMENT_DEG,
            confirm_within_searches: LOOP_CONFIRM_WITHIN_SEARCHES,
            max_left_fraction: LOOP_MAX_LEFT_FRACTION,
            other_edge_slack_m: LOOP_OTHER_EDGE_SLACK_M,
        }
    }
}
