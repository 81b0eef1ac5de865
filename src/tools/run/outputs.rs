//! The outputs of a run in its `--out` folder (trajectories, map, metrics, per-frame
//! records, pictures), each written completely or not at all, and the numbers read back
//! from a finished run's `metrics.json` (`batch`, `bench`).

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use super::{trajectory, RunResult};
use crate::dataset::Sequence;
use crate::io;
use crate::{Error, Result};

/// Every file `wgslam run` writes into its `--out` folder: [`write_outputs`]'s and
/// [`write_pictures`]'s.
pub const OUTPUT_FILES: [&str; 10] = [
    "trajectory.tum",
    "trajectory_odometry.tum",
    "map.ply",
    "metrics.json",
    "frames.json",
    "trajectory.png",
    "map_color.png",
    "map_normals.png",
    "last_camera_color.png",
    "last_camera_normals.png",
];

/// Writes `trajectory.tum`, `trajectory_odometry.tum`, `map.ply`, `metrics.json` and
/// `frames.json` into `out`
/// (created if missing), each file completely or not at all.
pub fn write_outputs(out: &Path, result: &RunResult) -> Result<()> {
    std::fs::create_dir_all(out).map_err(|e| crate::Error::write(out, e))?;
    io::trajectory::write_tum(&out.join("trajectory.tum"), &result.trajectory())?;
    // As tracked, before any loop closure (the same poses without loop closure).
    io::trajectory::write_tum(
        &out.join("trajectory_odometry.tum"),
        &trajectory(&result.frames),
    )?;
    io::ply::write_surfel_map(&out.join("map.ply"), &result.map)?;
    write_json(&out.join("metrics.json"), &result.metrics)?;
    write_json(&out.join("frames.json"), &result.frames)?;
    Ok(())
}

/// Writes any serialisable value as pretty JSON, atomically.
pub fn write_json<T: Serialize>(path: &Path, value: &T) -> Result<()> {
    io::atomic::write_atomic(path, |w| write_json_to(w, path, value))
}

/// The bytes of [`write_json`] into any writer; `path` names the file in errors.
pub fn write_json_to<T: Serialize>(
    w: &mut dyn std::io::Write,
    path: &Path,
    value: &T,
) -> Result<()> {
    serde_json::to_writer_pretty(&mut *w, value).map_err(|e| {
        if e.is_io() {
            crate::Error::write(path, e.into())
        } else {
            crate::Error::encode(path.display().to_string(), e)
        }
    })?;
    writeln!(w).map_err(|e| crate::Error::write(path, e))
}

/// The files [`write_outputs`] writes, as `(name, bytes)` in the same order and with the
/// same bytes (the same writers into memory): the browser build's downloads.
pub fn output_bytes(result: &RunResult) -> Result<Vec<(&'static str, Vec<u8>)>> {
    let mut out = Vec::new();
    let mut put = |name: &'static str, fill: &dyn Fn(&mut Vec<u8>, &Path) -> Result<()>| {
        let mut bytes = Vec::new();
        fill(&mut bytes, Path::new(name))?;
        out.push((name, bytes));
        Ok::<(), crate::Error>(())
    };
    let (est, odometry) = (result.trajectory(), trajectory(&result.frames));
    let frames = io::trajectory::TUM_CAMERA_FRAMES;
    put("trajectory.tum", &|w, p| {
        io::trajectory::write_tum_to(w, p, frames, &est)
    })?;
    put("trajectory_odometry.tum", &|w, p| {
        io::trajectory::write_tum_to(w, p, frames, &odometry)
    })?;
    put("map.ply", &|w, p| {
        io::ply::write_surfel_map_to(w, p, &result.map)
    })?;
    put("metrics.json", &|w, p| write_json_to(w, p, &result.metrics))?;
    put("frames.json", &|w, p| write_json_to(w, p, &result.frames))?;
    Ok(out)
}

/// Writes the pictures of a run into `out`: `trajectory.png` (with ground truth) and the
/// map renders (`map_{color,normals}.png`, `last_camera_{color,normals}.png`). Drawn by the
/// CPU renderer, which needs no device and takes tens of milliseconds at this size.
pub fn write_pictures(out: &Path, result: &RunResult, seq: &Sequence) -> Result<Vec<PathBuf>> {
    let est = result.trajectory();
    if result.map.is_empty() {
        eprintln!("note: the map is empty; no renders written");
        return Ok(vec![]);
    }
    let mut written = crate::render::outputs::write_map_renders(
        &crate::render::RenderBackend::Cpu,
        out,
        &result.map,
        &est,
        &seq.intrinsics,
        crate::render::DEFAULT_SIZE,
    )?;
    let gt = seq.ground_truth();
    if !gt.is_empty() && !est.is_empty() {
        let path = out.join("trajectory.png");
        crate::render::plot::write_trajectory_plot(&path, &est, &gt)?;
        written.push(path);
    }
    Ok(written)
}

/// [`write_outputs`] and [`write_pictures`] at once, the pictures on a second thread where
/// there are threads: neither reads the other's files, and after the last frame the map's
/// PLY and the renders are most of what a run still waits for. Returns the pictures
/// written; the files' error first when both fail.
pub fn write_files_and_pictures(
    out: &Path,
    result: &RunResult,
    seq: &Sequence,
) -> Result<Vec<PathBuf>> {
    std::fs::create_dir_all(out).map_err(|e| crate::Error::write(out, e))?;
    #[cfg(not(target_arch = "wasm32"))]
    let (files, pictures) = std::thread::scope(|s| {
        let pictures = s.spawn(|| write_pictures(out, result, seq));
        let files = write_outputs(out, result);
        let pictures = pictures
            .join()
            .unwrap_or_else(|panic| std::panic::resume_unwind(panic));
        (files, pictures)
    });
    #[cfg(target_arch = "wasm32")]
    let (files, pictures) = (write_outputs(out, result), write_pictures(out, result, seq));
    files?;
    pictures
}

/// A finished run's headline numbers, read back from its `metrics.json` (by `wgslam batch`
/// per job and backend, and by the long-sequence benchmark).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunNumbers {
    pub frames: u64,
    pub map_points: u64,
    /// Frames whose tracking was lost (not fused).
    pub lost_frames: u64,
    /// Frames placed by relocalisation (0 in outputs from before relocalisation).
    #[serde(default)]
    pub relocalised_frames: u64,
    /// The run's tracking health: `ok`, `recovered` or `LOST` (see
    /// [`super::TrackingCounts::flag`]; empty in outputs from before the health test).
    #[serde(default)]
    pub health: String,
    /// ATE RMSE after rigid alignment, and RPE between consecutive frames (None without
    /// ground truth), millimetres and degrees.
    pub ate_rmse_mm: Option<f64>,
    /// Frames without a pose, which the ATE and RPE leave out (None without ground truth,
    /// or in outputs from before the count).
    #[serde(default)]
    pub frames_without_pose: Option<u64>,
    pub rpe_trans_rmse_mm: Option<f64>,
    pub rpe_rot_rmse_deg: Option<f64>,
    /// Pipeline time per frame (median), milliseconds; whole-run wall time, seconds.
    pub time_per_frame_median_ms: f64,
    pub wall_s: f64,
    /// Peak resident memory of the run's process, MiB (None where the OS does not say).
    pub peak_memory_mib: Option<f64>,
}

/// A run's numbers from its `metrics.json`.
pub fn read_numbers(path: &Path) -> Result<RunNumbers> {
    let text = crate::io::input::read_kind_string(path, crate::io::input::InputKind::List)?;
    let m: serde_json::Value =
        serde_json::from_str(&text).map_err(|e| Error::format(path, format!("not JSON: {e}")))?;
    let num = |v: &serde_json::Value, what: &str| {
        v.as_f64()
            .ok_or_else(|| Error::format(path, format!("no number `{what}`")))
    };
    let acc = &m["accuracy"];
    let opt = |k: &str, scale: f64| acc[k].as_f64().map(|x| x * scale);
    Ok(RunNumbers {
        frames: num(&m["frames"], "frames")? as u64,
        map_points: num(&m["map_points"], "map_points")? as u64,
        lost_frames: num(&m["tracking"]["lost"], "tracking.lost")? as u64,
        relocalised_frames: m["tracking"]["relocalised"].as_u64().unwrap_or(0),
        health: m["tracking"]["health"]
            .as_str()
            .unwrap_or_default()
            .to_string(),
        ate_rmse_mm: opt("ate_rmse_aligned_m", 1e3),
        frames_without_pose: acc["frames_without_pose"].as_u64(),
        rpe_trans_rmse_mm: opt("rpe_trans_rmse_m", 1e3),
        rpe_rot_rmse_deg: opt("rpe_rot_rmse_deg", 1.0),
        time_per_frame_median_ms: num(&m["time_per_frame_median_s"], "time_per_frame_median_s")?
            * 1e3,
        wall_s: num(&m["wall_total_s"], "wall_total_s")?,
        peak_memory_mib: m["peak_memory_mib"].as_f64(),
    })
}
