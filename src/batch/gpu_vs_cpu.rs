//! The GPU run of a job against its CPU run, from their output files (`trajectory.tum`,
//! `map.ply`): each backend tracked on its own (end to end), so the numbers say how far
//! the two ends drift apart, not whether one frame's kernels agree (`wgslam compare` does
//! that in lockstep).

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::layout::map::SurfelMap;
use crate::tools::compare::{self, tolerance::MAP_MATCH_RADIUS_M};
use crate::{io, Error, Result};

/// Largest stamp difference, seconds (or frames for ICL-NUIM), for two poses to be the
/// same frame: both runs write the same stamps, so only printing round-off remains.
const SAME_STAMP_MAX_DT: f64 = 1e-4;

/// How far the GPU run is from the CPU run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GpuVsCpu {
    /// Frames present in both trajectories.
    pub poses: usize,
    /// Largest and RMS camera-position difference over those frames, millimetres.
    pub pose_max_mm: f64,
    pub pose_rms_mm: f64,
    /// Largest camera-rotation difference, degrees.
    pub pose_max_deg: f64,
    /// Surfels in the CPU and the GPU map.
    pub map_points: (usize, usize),
    /// The match radius, metres (`compare`'s map tolerance radius).
    pub map_match_radius_m: f64,
    /// Fraction of either map's points with no point of the other within the radius (the
    /// larger side).
    pub map_unmatched_fraction: f64,
    /// Mean distance from CPU points to their matched GPU point, millimetres.
    pub map_mean_match_mm: f64,
}

/// Compares the run outputs in `cpu_dir` and `gpu_dir`.
pub fn compare_outputs(cpu_dir: &Path, gpu_dir: &Path) -> Result<GpuVsCpu> {
    let cpu = io::trajectory::read_tum(&cpu_dir.join("trajectory.tum"))?;
    let gpu = io::trajectory::read_tum(&gpu_dir.join("trajectory.tum"))?;
    let pairs = crate::eval::associate(&cpu, &gpu, SAME_STAMP_MAX_DT);
    if pairs.is_empty() {
        return Err(Error::format(
            gpu_dir.join("trajectory.tum"),
            "no frame in common with the CPU run's trajectory",
        ));
    }
    let (mut max_mm, mut sum_sq, mut max_deg) = (0.0f64, 0.0f64, 0.0f64);
    for &(i, j) in &pairs {
        let (mm, deg) = compare::pose_diff(&cpu[i].1, &gpu[j].1);
        max_mm = max_mm.max(mm);
        max_deg = max_deg.max(deg);
        sum_sq += mm * mm;
    }
    let cpu_map = positions_of(&cpu_dir.join("map.ply"))?;
    let gpu_map = positions_of(&gpu_dir.join("map.ply"))?;
    let maps = compare::diff_surfel_maps(&cpu_map, &gpu_map, MAP_MATCH_RADIUS_M);
    Ok(GpuVsCpu {
        poses: pairs.len(),
        pose_max_mm: max_mm,
        pose_rms_mm: (sum_sq / pairs.len() as f64).sqrt(),
        pose_max_deg: max_deg,
        map_points: maps.surfels,
        map_match_radius_m: MAP_MATCH_RADIUS_M as f64,
        map_unmatched_fraction: maps.unmatched_fraction(),
        map_mean_match_mm: maps.mean_match_m * 1e3,
    })
}

/// A map PLY's positions as a [`SurfelMap`] (normals, frames and colours zero: the map
/// comparison reads positions only).
fn positions_of(path: &Path) -> Result<SurfelMap> {
    let ply = io::read_ply(path)?;
    let n = ply.positions.len();
    Ok(SurfelMap {
        position_weight: ply
            .positions
            .iter()
            .map(|p| [p[0], p[1], p[2], 1.0])
            .collect(),
        normal_frame: vec![[0; 4]; n],
        color: vec![[0.0; 4]; n],
    })
}
