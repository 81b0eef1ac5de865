//! Documented tolerances; `wgslam compare` exits non-zero beyond any of them. The frame-map
//! bounds hold in both modes (the inputs are the same raw frame); the rest are for the
//! free (end-to-end) mode, and [`lockstep`] has the per-frame ones.

/// Vertex maps, metres. WGSL's accuracy table bounds it (an ULP of `x` is at most
/// `|x| 2^-23`): `z = depth / scale` is within 2.5 ULP of exact on a GPU, 0.5 on the CPU,
/// so the two differ by at most 3 ULP of z; `x = (u - cx) z / fx` adds a subtraction and a
/// product (0.5 ULP each, fused or not) and a division (3 between backends): at most 7 ULP
/// of `|x| <= 0.6 z` (half the image over the focal length), 4 ULP of z. Depth sensors
/// here read at most 8 m: 4 ULP of 8 m is 3.8e-6 m. The bilateral filter's average moves
/// by the weights' relative error (`exp`: 3 + 2|x| ULP, under 30 ULP for its arguments)
/// times the window's spread inside the range kernel (a few cm): under 1e-7 m. 1e-5 m is
/// 2.6x the bound (measured: 1.9e-6 m with the perturbed twins).
pub const VERTEX_MAX_ABS_M: f64 = 1e-5;
/// Normals, degrees: central differences `v(u+1) - v(u-1)` over a baseline of `2 z / fx`,
/// each endpoint within `sqrt(3^2 + 4^2 + 4^2) = 6.4` ULP of z of the other backend's
/// (see [`VERTEX_MAX_ABS_M`]), turn each edge by at most `6.4 fx 2^-23` rad whatever the
/// depth, and the normal (their cross product, normalised: a few ULP of 1 more) by the
/// sum of the two: 8.9e-4 rad = 0.051 deg at `fx` = 585 px, the largest focal length of
/// the datasets (7-Scenes). 0.1 deg gives 2x headroom and holds up to `fx` = 1100 px
/// (measured: 0.0055 deg with the perturbed twins).
pub const NORMAL_MAX_DEG: f64 = 0.1;
/// Pixels whose validity differs (a neighbour's depth jump exactly at the threshold).
pub const VALIDITY_MISMATCH_MAX_FRACTION: f64 = 1e-3;
/// Relative difference of AᵀA and Aᵀb (see `system_rel_diffs`), free mode:
/// [`lockstep::SYSTEM_REL_DIFF_MAX`] plus what the two starting poses' difference adds.
/// The backends run apart, so each frame starts from the pose its own backend reached: a
/// pose offset `δ` moves Aᵀb by about `AᵀA δ`, which over the measure's denominator
/// `sqrt(trace(AᵀA) Σr²)` is `δ / r_rms`, the offset over the residuals' RMS. Since ICP
/// stops within the pose's own noise (`icp.stop_chi2`) the two runs' poses differ by up to
/// 0.015 mm after 20 frames of 7-Scenes with the perturbed twins, whose residuals' RMS is
/// about 10 mm: 1.5e-3 (measured 1.28e-3, frame 20). 5e-3 is the lockstep bound plus room
/// for a pose difference of 0.04 mm at 10 mm RMS; larger pose differences are the pose
/// check's ([`pose_max_mm`]), and a real error in a row of the system (a wrong sign: 0.47)
/// stays two orders of magnitude above it.
pub const SYSTEM_REL_DIFF_MAX: f64 = 5e-3;
/// Pose difference, end to end, floor of [`pose_max_mm`]: on noise-free frames ICP pulls
/// both backends back onto the same surface, so the difference does not grow with the run
/// (measured on ICL kt2 1..200, lavapipe) and stays under this.
pub const POSE_MAX_MM: f64 = 0.1;
/// The rotation floor of [`pose_max_deg`], degrees.
pub const POSE_MAX_DEG: f64 = 0.01;

/// The free mode's pose bound (mm) over a run of `frames` frames. Each frame's tracking
/// may differ by up to the lockstep bound ([`lockstep::POSE_MAX_MM`], derived from the
/// accuracy rules) and the next frame tracks from there; on noisy depth ICP does not pull
/// the two back (its minimum moves with the noise it sees), so the per-frame differences,
/// independent in sign, add up as a random walk: `lockstep bound x sqrt(frames)`, never
/// below the noise-free floor [`POSE_MAX_MM`]. Measured on an NVIDIA H200 (noisy ICL-NUIM
/// 1..40, assignment profile, 320x240): 0.137 mm at frame 40 against 0.63 mm; a wrong
/// sign in one row of the system moves the pose by centimetres in the first frame.
pub fn pose_max_mm(frames: usize) -> f64 {
    POSE_MAX_MM.max(lockstep::POSE_MAX_MM * (frames.max(1) as f64).sqrt())
}

/// The free mode's rotation bound (degrees), as [`pose_max_mm`].
pub fn pose_max_deg(frames: usize) -> f64 {
    POSE_MAX_DEG.max(lockstep::POSE_MAX_DEG * (frames.max(1) as f64).sqrt())
}
/// Fusion decisions (lockstep): see [`crate::tools::compare::decisions`]'s bounds; none
/// may be taken the other way clear of its knife edge.
pub use super::decisions::CLEAR_FLIPS_MAX as FUSION_CLEAR_FLIPS_MAX;
/// Surfel counts: pixels at a filter boundary may be merged on one side, added on the other.
pub const SURFEL_COUNT_REL_DIFF_MAX: f64 = 1e-3;
/// Map points of one backend farther than this from every point of the other.
pub const MAP_MATCH_RADIUS_M: f32 = 1e-3;
/// Fraction of map points allowed to have no match within the radius, for short runs.
pub const MAP_UNMATCHED_MAX_FRACTION: f64 = 1e-3;
/// ...and per frame compared, for long ones: a surfel whose projection lands exactly
/// on a pixel boundary may be moved to the neighbouring pixel by a fused multiply-add
/// on one backend only, and then averages in a different frame point; such surfels
/// accumulate over a run. Measured on ICL kt2 (320x240, both backends tracking):
/// unmatched 0.017 % after 20 frames, 0.062 % after 50, 0.10 % after 100, 0.13 %
/// after 150, 0.14 % after 200, while within 1 cm only 0.001 % are unmatched after 200
/// (the maps are the same surface). That was lavapipe, whose rounding is the CPU's;
/// WGSL allows more (see `crate::cpu::arith`), and a knife-edge decision taken the
/// other way leaves a surfel unmatched within 1 mm however right both backends are:
/// the NVIDIA H200 ended noisy ICL-NUIM 1..40 (assignment profile) 2.05 % unmatched,
/// 5.1e-4 per frame, the perturbed twins 0.14 % over the bundled 23 noisy frames. So
/// this bound only catches gross disagreement (2x the H200's rate); the map's real
/// checks are [`MAP_UNEXPLAINED_MAX_FRACTION`] and [`MAP_WEIGHT_SUM_REL_DIFF_MAX`].
pub const MAP_UNMATCHED_MAX_FRACTION_PER_FRAME: f64 = 1e-3;

/// Surfels of either map that no surfel of the other explains: none within fusion's
/// distance gate (plus [`MAP_MATCH_RADIUS_M`]) with a normal within fusion's angle gate.
/// A knife-edge decision moves a surfel by less than this: a pixel `q` merged into a
/// surfel `p` on one side only moves it by `wq / (w + wq) |q - p|`, under half the
/// distance gate (`w >= wq`), and turns its normal by less than the angle gate; a
/// pixel added as a new surfel on one side lies within the gate of the surfel it merged
/// into on the other. So every surfel of one map has a surfel of the other within the
/// gates, whatever the rounding; a surfel that has none is a bug (measured 0 with the
/// perturbed twins, lockstep and free). The allowance is for surfels at the map's
/// border that a pose difference moves in or out of view.
pub const MAP_UNEXPLAINED_MAX_FRACTION: f64 = 1e-3;
/// Total map weight, free mode: every valid pixel adds its confidence (at most 1) to
/// the map once, merged or added, so choosing another surfel leaves the sum unchanged;
/// only a pixel that one side counts as covered (neither merged nor added) and the
/// other does not, or a surfel compaction keeps on one side only, changes it. Measured
/// 9.9e-6 with the perturbed twins over 23 noisy frames; 1 % keeps the bound far above
/// knife-edge flips and below a skipped merge in 16 (1.0e-2 .. 1.5e-2 per frame).
pub const MAP_WEIGHT_SUM_REL_DIFF_MAX: f64 = 1e-2;

/// The unmatched-fraction limit for a comparison over `frames` frames.
pub fn map_unmatched_max_fraction(frames: usize) -> f64 {
    MAP_UNMATCHED_MAX_FRACTION.max(MAP_UNMATCHED_MAX_FRACTION_PER_FRAME * frames as f64)
}

/// Per-frame tolerances of the lockstep mode: both backends start each frame from the
/// same map and pose, so a bound is what one frame's kernels may differ by; nothing
/// accumulates. Measured with `wgslam compare DATA --frames 1..200` (320x240, every
/// frame's map compared) on the noisy and the noise-free ICL kt2 with `--profile
/// robust` and `--profile assignment`; each comment gives the worst frame of the four
/// runs. The frame-map bounds and the match radius are the ones above.
pub mod lockstep {
    /// The first ICP system at the finest pyramid level, from the same map and starting
    /// pose. Three sources, from the accuracy table and the step: (1) the sum's order:
    /// f32 partial sums of at most ~1,000 rows each (a GPU thread's, or the perturbed
    /// twins' 64 partials) are within `1000 * 2^-24` = 6e-5 of exact relative to the sum
    /// of absolute values, which for AᵀA is its norm; (2) each row's own rounding: its
    /// residual `n . (p - q)` carries [`super::super::decisions::POSITION_ULPS`] ULP of the
    /// positions (~4e-6 m at 1 m), independent from row to row, so Aᵀb moves by that
    /// over the rows' RMS residual (mm) divided by the square root of the row count
    /// (1e4..1e5): under 1e-5; (3) rows whose gate (distance, angle) falls the other way
    /// on a knife edge, and the pose the coarser levels reached, which differs by up to
    /// [`POSE_MAX_MM`]'s rounding share: these are the step's own sensitivity, not
    /// arithmetic, and were measured: worst 4.4e-4 over ICL kt2 1..200 (noisy and
    /// noise-free, robust and assignment profiles, lavapipe), 1.5e-4 with the perturbed
    /// twins. 1e-3 is 1.6x (1) + (2) + the worst of (3).
    pub const SYSTEM_REL_DIFF_MAX: f64 = 1e-3;
    /// The pose after ICP, from the same starting pose. Propagated from the systems: each
    /// increment solves `H x = g`, so systems [`SYSTEM_REL_DIFF_MAX`] apart give
    /// increments that far apart relative to the frame's motion (under 3 cm and 1 deg
    /// between frames here): 0.03 mm and 0.001 deg; and one side may stop an iteration
    /// earlier (its increment just below the convergence threshold, 1e-5 for the robust
    /// profile: 0.01 mm, 0.0006 deg). 0.04 mm / 0.0016 deg in all; 0.1 mm / 0.003 deg is
    /// 2.5x / 1.9x that (measured worst: 0.031 mm / 0.00078 deg, ICL kt2 noisy,
    /// assignment profile; the NVIDIA H200 0.009 mm on 7-Scenes).
    pub const POSE_MAX_MM: f64 = 0.1;
    pub const POSE_MAX_DEG: f64 = 0.003;
    /// Surfel counts after fusion and after compaction: pixels at a fusion gate may
    /// merge on one side and be added on the other (and the pose differs by the amount
    /// above). Worst 3.8e-5 (noisy robust, 5 surfels of 132k); at most 14 surfels in
    /// any run; 1.3e-5 noise-free. 5x headroom.
    pub const SURFEL_COUNT_REL_DIFF_MAX: f64 = 2e-4;
    /// The map after the frame: fraction of surfels (the larger side) with no surfel
    /// of the other map within [`super::MAP_MATCH_RADIUS_M`]. From the same map, the
    /// pose difference moves surfels by less than 3e-5 m (noisy frame 91, 0.013 mm
    /// apart: 8786 surfels have no partner within 0.01 mm, 64 none within 0.03 mm, the
    /// same 64 none within 1 mm), so the unmatched ones are the fusion-gate decisions
    /// that differ. Worst 6.3e-4
    /// (noisy assignment, frame 3: 87 of 139k; its noisy normals sit at the 5 degree
    /// gate), 1.8e-4 noisy robust, 8e-5 noise-free on lavapipe; 1.1e-4 with the perturbed
    /// twins; 6.9e-3 on the NVIDIA H200 (7-Scenes frame 2, 640x480: its pose 0.009 mm
    /// off moves every fusion gate's input by that much, which is the knife edge's
    /// width, far wider than an ulp). 2 % is 2.9x the H200; the unexplained surfels
    /// and the total weight are the tight checks.
    pub const MAP_UNMATCHED_MAX_FRACTION: f64 = 2e-2;
    /// Total map weight after the frame (see [`super::MAP_WEIGHT_SUM_REL_DIFF_MAX`]):
    /// measured 2.1e-6 with the perturbed twins; a skipped merge in 16 gives 1.0e-2 to
    /// 1.5e-2. 5e-3 is a knife-edge flip between covered and added on 0.5 % of a map's
    /// worth of pixels.
    pub const MAP_WEIGHT_SUM_REL_DIFF_MAX: f64 = 5e-3;
}
