//! Runs two backends, A (the reference) and B, over the same frames and measures how far
//! apart they are, stage by stage: the frame maps, the first ICP system, the pose, the
//! surfel counts after fusion and after compaction, and the map. Used by `wgslam compare`
//! and by the parity tests (`tests/it/compare.rs`).
//!
//! Two [`Mode`]s. **Lockstep** (the default): before every frame B is put into A's state
//! (A's map uploaded with [`Inspect::upload_map`](crate::slam::backend::Inspect::upload_map) into both, A's last pose given to B's tracker), so
//! a frame's differences come from that frame's kernels alone and the per-frame tolerances
//! ([`tolerance::lockstep`]) can be tight. This is what proves the GPU kernels equal their
//! CPU twins over a whole sequence: on noisy depth two trackers that each keep their own
//! state drift apart chaotically (an ulp today moves a merge decision tomorrow), whatever
//! the kernels. **Free**: each backend tracks on its own state, as two separate runs would;
//! differences accumulate: its pose bound grows as a random walk of per-frame lockstep
//! differences ([`tolerance::pose_max_mm`]); maps are judged by what matters.

mod checks;
pub mod decisions;
mod fusion;
mod map_match;
mod perturbed;

pub use decisions::{DecisionCheck, FusionSide};
pub use fusion::FusionKernelDiff;
pub use map_match::{
    diff_surfel_maps, diff_surfel_maps_within, unexplained_fraction, unmatched_fraction, MapBounds,
    Matches, SurfelMapDiff,
};
pub use perturbed::{PerturbedCpu, Plant, DEFAULT_SEED};

use glam::DMat4;
use serde::Serialize;

use crate::dataset::Sequence;
use crate::layout::map::SurfelMap;
use crate::layout::{ICP_COUNT_INDEX, ICP_SYSTEM_LEN};
use crate::slam::backend::{Backend, FrameMaps, Inspect};
use crate::slam::instrumented::Instrumented;
use crate::slam::params::{Association, ValidParams};
use crate::slam::pipeline::Slam;
use crate::slam::solve::NormalEquations;
use crate::tools::run::packed_rgba;
use crate::{geometry::se3, Result};
use checks::{check_frame, check_map, Limits};

pub mod tolerance;

/// How the two backends are driven (see the module header).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase", tag = "name")]
pub enum Mode {
    /// Before every frame B takes A's map and last pose; the maps after the frame are
    /// compared every `map_every` frames and after the last frame.
    Lockstep { map_every: usize },
    /// Each backend tracks on its own state; the maps are compared after the last frame.
    Free,
}

impl Mode {
    /// Lockstep with the map compared after every frame.
    pub const LOCKSTEP: Mode = Mode::Lockstep { map_every: 1 };

    /// `lockstep` or `free`, for reports.
    pub fn name(&self) -> &'static str {
        match self {
            Mode::Lockstep { .. } => "lockstep",
            Mode::Free => "free",
        }
    }
}

/// Differences of two frame maps.
#[derive(Debug, Clone, Default, Serialize)]
pub struct MapDiff {
    /// Largest |a - b| over pixels valid on both sides, metres: the unfiltered vertex maps
    /// and, when both ran the bilateral filter, the filtered ones.
    pub vertex_max_abs_m: f64,
    /// Largest normal angle over pixels valid on both sides, degrees.
    pub normal_max_deg: f64,
    /// Fraction of pixels valid on one side only (vertex or normal).
    pub validity_mismatch_fraction: f64,
}

/// Per-frame differences between backend A (reference) and B.
#[derive(Debug, Clone, Serialize)]
pub struct FrameDiff {
    pub index: usize,
    pub maps: MapDiff,
    /// Relative difference of the first ICP iteration's AᵀA and Aᵀb (see
    /// [`system_rel_diff`]; None on frames without tracking).
    pub system_rel_diff: Option<f64>,
    /// Inlier counts of the first ICP iteration (A, B).
    pub inliers: Option<(u64, u64)>,
    /// Pose after the frame (after ICP), A against B.
    pub pose_diff_mm: f64,
    pub pose_diff_deg: f64,
    /// Surfels after fusion (A, B); None when a backend did not fuse (tracking lost, no
    /// depth).
    pub fused_surfels: Option<(usize, usize)>,
    /// Surfels after the frame (after compaction when the profile removes unstable surfels).
    pub surfels: (usize, usize),
    /// The maps after this frame (lockstep mode, on the frames whose map is compared).
    pub map: Option<SurfelMapDiff>,
    /// Fusion kernel by kernel (lockstep mode, frames both backends fused).
    pub fusion: Option<FusionKernelDiff>,
    /// The pixels whose fusion decision differs, judged against their knife edges
    /// (lockstep mode, frames both backends fused; see [`decisions`]).
    pub decisions: Option<DecisionCheck>,
}

/// The largest difference of each kind over the frames compared (and the maps).
#[derive(Debug, Clone, Default, Serialize)]
pub struct Worst {
    pub vertex_max_abs_m: f64,
    pub normal_max_deg: f64,
    pub validity_mismatch_fraction: f64,
    pub system_rel_diff: f64,
    pub pose_diff_mm: f64,
    pub pose_diff_deg: f64,
    /// Relative surfel-count differences after fusion and after the frame.
    pub fused_surfels_rel_diff: f64,
    pub surfels_rel_diff: f64,
    /// Unmatched fraction (larger side) and largest match distance (m) over the map
    /// comparisons.
    pub map_unmatched_fraction: f64,
    pub map_max_match_m: f64,
    /// Unexplained fraction (larger side) and relative total-weight difference over the
    /// map comparisons.
    pub map_unexplained_fraction: f64,
    pub map_weight_sum_rel_diff: f64,
    /// Most fusion decisions taken the other way clear of their knife edge in a frame, and
    /// the largest such margin relative to its gate (lockstep; see [`decisions`]).
    pub fusion_clear_flips: usize,
    pub fusion_clear_flip_relative_margin: f64,
}

impl Worst {
    fn add_frame(&mut self, d: &FrameDiff) {
        self.vertex_max_abs_m = self.vertex_max_abs_m.max(d.maps.vertex_max_abs_m);
        self.normal_max_deg = self.normal_max_deg.max(d.maps.normal_max_deg);
        self.validity_mismatch_fraction = self
            .validity_mismatch_fraction
            .max(d.maps.validity_mismatch_fraction);
        self.system_rel_diff = self.system_rel_diff.max(d.system_rel_diff.unwrap_or(0.0));
        self.pose_diff_mm = self.pose_diff_mm.max(d.pose_diff_mm);
        self.pose_diff_deg = self.pose_diff_deg.max(d.pose_diff_deg);
        if let Some(f) = d.fused_surfels {
            self.fused_surfels_rel_diff = self.fused_surfels_rel_diff.max(count_rel_diff(f));
        }
        self.surfels_rel_diff = self.surfels_rel_diff.max(count_rel_diff(d.surfels));
        if let Some(m) = &d.map {
            self.add_map(m);
        }
        if let Some(c) = &d.decisions {
            self.fusion_clear_flips = self.fusion_clear_flips.max(c.clear_flips);
            self.fusion_clear_flip_relative_margin = self
                .fusion_clear_flip_relative_margin
                .max(c.worst_relative_margin);
        }
    }

    fn add_map(&mut self, m: &SurfelMapDiff) {
        self.map_unmatched_fraction = self.map_unmatched_fraction.max(m.unmatched_fraction());
        self.map_max_match_m = self.map_max_match_m.max(m.max_match_m);
        self.map_unexplained_fraction = self.map_unexplained_fraction.max(m.unexplained_fraction());
        self.map_weight_sum_rel_diff = self.map_weight_sum_rel_diff.max(m.weight_sum_rel_diff());
    }
}

/// The whole comparison.
#[derive(Debug, Clone, Serialize)]
pub struct Comparison {
    /// How the backends were driven.
    pub mode: Mode,
    pub backends: (String, String),
    pub frames: Vec<FrameDiff>,
    /// The maps after the last frame.
    pub map: SurfelMapDiff,
    pub worst: Worst,
    /// Every tolerance exceeded, in words, each naming its frame and stage (empty when the
    /// backends agree).
    pub violations: Vec<String>,
}

/// Compares two frame maps (vertex, normal) pixel by pixel.
pub fn diff_frame_maps(a: &FrameMaps, b: &FrameMaps) -> MapDiff {
    let mut d = MapDiff::default();
    let mut mismatched = 0usize;
    let n = a.vertex.len().max(1);
    let (normal_a, normal_b) = (a.normal_map(), b.normal_map());
    for i in 0..a.vertex.len() {
        let (va, vb) = (a.vertex[i], b.vertex[i]);
        let (na, nb) = (normal_a[i], normal_b[i]);
        if (va[3] > 0.0) != (vb[3] > 0.0) || (na[3] > 0.0) != (nb[3] > 0.0) {
            mismatched += 1;
        }
        if va[3] > 0.0 && vb[3] > 0.0 {
            for k in 0..3 {
                d.vertex_max_abs_m = d.vertex_max_abs_m.max((va[k] - vb[k]).abs() as f64);
            }
        }
        if na[3] > 0.0 && nb[3] > 0.0 {
            // atan2(|a x b|, a . b): accurate near 0, where acos(dot) has a ~0.03 deg floor
            // for f32 unit vectors.
            let a = glam::DVec3::new(na[0] as f64, na[1] as f64, na[2] as f64);
            let b = glam::DVec3::new(nb[0] as f64, nb[1] as f64, nb[2] as f64);
            let angle = a.cross(b).length().atan2(a.dot(b));
            d.normal_max_deg = d.normal_max_deg.max(angle.to_degrees());
        }
    }
    if a.filtered_vertex.len() == b.filtered_vertex.len() {
        for (fa, fb) in a.filtered_vertex.iter().zip(&b.filtered_vertex) {
            if fa[3] > 0.0 && fb[3] > 0.0 {
                for k in 0..3 {
                    d.vertex_max_abs_m = d.vertex_max_abs_m.max((fa[k] - fb[k]).abs() as f64);
                }
            }
        }
    }
    d.validity_mismatch_fraction = mismatched as f64 / n as f64;
    d
}

/// Relative differences of two 29-entry systems, `(AᵀA, Aᵀb)`, `a` the reference: AᵀA's
/// Frobenius difference over its norm; Aᵀb's difference over the Cauchy-Schwarz bound of
/// its terms, `sqrt(trace(AᵀA) Σb²)`, not over itself, because Aᵀb nearly cancels near the
/// optimum (a tiny denominator would make rounding look like a disagreement).
pub fn system_rel_diffs(a: &[f64; ICP_SYSTEM_LEN], b: &[f64; ICP_SYSTEM_LEN]) -> (f64, f64) {
    let (ea, eb) = (NormalEquations::decode(a), NormalEquations::decode(b));
    let h = (ea.ata - eb.ata).norm() / ea.ata.norm().max(f64::MIN_POSITIVE);
    let bound = (ea.ata.trace() * ea.residual_sq_sum).sqrt();
    let g = (ea.atb - eb.atb).norm() / bound.max(f64::MIN_POSITIVE);
    (h, g)
}

/// The larger of [`system_rel_diffs`]' two.
pub fn system_rel_diff(a: &[f64; ICP_SYSTEM_LEN], b: &[f64; ICP_SYSTEM_LEN]) -> f64 {
    let (h, g) = system_rel_diffs(a, b);
    h.max(g)
}

/// Pose difference of two camera-to-world poses: translation (mm) and rotation (degrees).
pub fn pose_diff(a: &DMat4, b: &DMat4) -> (f64, f64) {
    let e = se3::inverse_rigid(a) * *b;
    (
        se3::translation_norm(&e) * 1e3,
        se3::rotation_angle(&e).to_degrees(),
    )
}

/// |a - b| / a for a pair of surfel counts (A the reference).
fn count_rel_diff((a, b): (usize, usize)) -> f64 {
    a.abs_diff(b) as f64 / a.max(1) as f64
}

/// Runs `a` (the reference) and `b` over frames `first..=last` in `mode` and compares them.
pub fn compare<A: Backend + Inspect, B: Backend + Inspect>(
    a: A,
    b: B,
    seq: &Sequence,
    first: usize,
    last: usize,
    params: ValidParams,
    mode: Mode,
) -> Result<Comparison> {
    let names = (a.name().to_string(), b.name().to_string());
    let compacts = params.fusion.unstable_removal.is_some();
    let best_candidate = params.fusion.association == Association::BestCandidate;
    let limits = Limits::of(mode, (first..=last).count(), &params);
    let mut sa = Slam::for_sequence(Instrumented::recording(a), seq, params.clone())?;
    let mut sb = Slam::for_sequence(Instrumented::recording(b), seq, params)?;
    let mut frames = Vec::new();
    let mut violations = Vec::new();
    let mut worst = Worst::default();
    // Lockstep: A's map as B is to start the next frame from.
    let mut a_map = match mode {
        Mode::Lockstep { .. } => Some(sa.backend.download_map()?),
        Mode::Free => None,
    };
    for (k, i) in (first..=last).enumerate() {
        // Lockstep: the map both backends fuse into this frame, for judging their decisions.
        let before = a_map.clone();
        if let Some(map) = &a_map {
            // A too starts from its map as uploaded: a backend predicts from the index map
            // its last fusion built (see `FusedView`), B from a fresh projection of the
            // uploaded map, and the two differ at a few pixels.
            sa.backend.upload_map(map)?;
            sb.backend.upload_map(map)?;
            sb.set_t_world_to_cam(sa.t_world_to_cam());
        }
        let mut d = diff_frame(&mut sa, &mut sb, seq, i, before.as_ref(), best_candidate)?;
        d.map = match (&mut a_map, mode) {
            (Some(a_map), Mode::Lockstep { map_every }) => {
                *a_map = sa.backend.download_map()?;
                if (k + 1) % map_every.max(1) == 0 || i == last {
                    let b_map = sb.backend.download_map()?;
                    Some(diff_surfel_maps_within(a_map, &b_map, &limits.map_bounds()))
                } else {
                    None
                }
            }
            _ => None,
        };
        check_frame(&d, &limits, compacts, best_candidate, &mut violations);
        worst.add_frame(&d);
        frames.push(d);
    }
    let map = match frames.last().and_then(|f| f.map.clone()) {
        Some(m) => m,
        None => {
            let (ma, mb) = (sa.backend.download_map()?, sb.backend.download_map()?);
            let m = diff_surfel_maps_within(&ma, &mb, &limits.map_bounds());
            check_map(&m, &limits, &mut |ok, what| {
                if !ok {
                    violations.push(format!("final map: {what} ({} frames)", frames.len()));
                }
            });
            worst.add_map(&m);
            m
        }
    };
    Ok(Comparison {
        mode,
        backends: names,
        frames,
        map,
        worst,
        violations,
    })
}

/// Runs frame `i` on both backends and measures how far apart they are at each stage: the
/// frame maps, the first ICP system, the pose, the surfel counts and (when `before`, the
/// map both fused into in lockstep, is given) fusion. The maps after the frame are the
/// caller's to compare (`map` is None).
fn diff_frame<A: Backend + Inspect, B: Backend + Inspect>(
    sa: &mut Slam<Instrumented<A>>,
    sb: &mut Slam<Instrumented<B>>,
    seq: &Sequence,
    i: usize,
    before: Option<&SurfelMap>,
    best_candidate: bool,
) -> Result<FrameDiff> {
    let raw = seq.load(i)?;
    let rgba = packed_rgba(&raw);
    let gt = seq.frames[i].gt_cam_to_world;
    sa.backend.clear_frame();
    sb.backend.clear_frame();
    let ra = sa.process(i as u32, &raw.depth, &rgba, gt.as_ref())?;
    let rb = sb.process(i as u32, &raw.depth, &rgba, gt.as_ref())?;
    let (frame_a, frame_b) = (sa.backend.download_frame()?, sb.backend.download_frame()?);
    let maps = diff_frame_maps(&frame_a, &frame_b);
    let (system_rel_diff, inliers) =
        diff_first_systems(&sa.backend.frame_systems, &sb.backend.frame_systems);
    let (mm, deg) = pose_diff(&ra.t_cam_to_world, &rb.t_cam_to_world);
    let fused_surfels = sa.backend.fused_surfels.zip(sb.backend.fused_surfels);
    let (fusion, decisions) = match (before, fused_surfels) {
        (Some(before), Some(_)) => {
            let frames = (&frame_a, &frame_b);
            diff_fusion(sa, sb, i, before, frames, best_candidate)?
        }
        _ => (None, None),
    };
    Ok(FrameDiff {
        index: i,
        maps,
        system_rel_diff,
        inliers,
        pose_diff_mm: mm,
        pose_diff_deg: deg,
        fused_surfels,
        // After the frame (its report has the count before it): on a GPU a wait for the
        // fusion, which `compare`'s lockstep makes anyway.
        surfels: (sa.backend.surfel_count()?, sb.backend.surfel_count()?),
        map: None,
        fusion,
        decisions,
    })
}

/// The relative difference and the inlier counts (A, B) of the two backends' first ICP
/// systems of a frame at the finest level; None on a frame without tracking.
fn diff_first_systems(
    a: &[(usize, [f64; ICP_SYSTEM_LEN])],
    b: &[(usize, [f64; ICP_SYSTEM_LEN])],
) -> (Option<f64>, Option<(u64, u64)>) {
    // The first system at the finest level: the most rows, so a row whose gate one
    // backend decides the other way by an ulp moves it least (at the coarsest level,
    // 80x60, one such row of a large residual moved it by 2.3e-3 on noisy frame 40).
    let finest = |s: &[(usize, [f64; ICP_SYSTEM_LEN])]| {
        s.iter().find(|(level, _)| *level == 0).map(|(_, sys)| *sys)
    };
    match (finest(a), finest(b)) {
        (Some(x), Some(y)) => (
            Some(system_rel_diff(&x, &y)),
            Some((x[ICP_COUNT_INDEX] as u64, y[ICP_COUNT_INDEX] as u64)),
        ),
        _ => (None, None),
    }
}

/// Frame `i`'s fusion on both backends, which both fused into `before`: kernel by kernel,
/// and the pixels whose decision differs judged against their knife edges (when both
/// backends have a pose). `frames`: the two backends' frame maps (A, B).
fn diff_fusion<A: Backend + Inspect, B: Backend + Inspect>(
    sa: &mut Slam<Instrumented<A>>,
    sb: &mut Slam<Instrumented<B>>,
    i: usize,
    before: &SurfelMap,
    (frame_a, frame_b): (&FrameMaps, &FrameMaps),
    best_candidate: bool,
) -> Result<(Option<FusionKernelDiff>, Option<DecisionCheck>)> {
    let (fa, fb) = (sa.backend.download_fusion()?, sb.backend.download_fusion()?);
    let (ta, tb) = (sa.t_world_to_cam(), sb.t_world_to_cam());
    let pa = ta.map(|t| sa.fuse_params(&t, i as u32));
    let pb = tb.map(|t| sb.fuse_params(&t, i as u32));
    let decisions = match (pa, pb) {
        (Some(pa), Some(pb)) => Some(decisions::check(
            before,
            &FusionSide {
                params: &pa,
                normal_depth: &frame_a.normal_depth,
                assoc: &fa.assoc,
            },
            &FusionSide {
                params: &pb,
                normal_depth: &frame_b.normal_depth,
                assoc: &fb.assoc,
            },
            best_candidate,
        )),
        _ => None,
    };
    Ok((
        Some(FusionKernelDiff::of(&fa, &fb, best_candidate)),
        decisions,
    ))
}
