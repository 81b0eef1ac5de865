//! The long-sequence benchmark (`wgslam bench --revisit N`): one backend's `wgslam run
//! --revisit N` (frames played forwards, backwards, ... so the camera sees the same scene
//! again and again) summarised as what a long batch run meets: time per frame early and
//! late, the map's size after each pass, peak memory, and the accuracy on the ground truth.

use std::path::Path;

use serde::Serialize;

use crate::{Error, Result};

/// Frames at each end of the run whose mean time per frame is compared.
pub const END_FRAMES: usize = 100;

/// One backend's long run.
#[derive(Debug, Clone, Serialize)]
pub struct LongRun {
    pub backend: String,
    pub frames: usize,
    /// Frames per pass (one way over the range).
    pub pass_frames: usize,
    /// Mean pipeline time per frame over the first and the last [`END_FRAMES`] frames, ms.
    pub first_mean_ms: f64,
    pub last_mean_ms: f64,
    /// `last_mean_ms / first_mean_ms`.
    pub last_over_first: f64,
    /// Median time per frame over the whole run, ms.
    pub median_ms: f64,
    /// Surfels after each complete pass (and after the last frame if it ends mid-pass).
    pub map_after_pass: Vec<usize>,
    /// Map after the last pass over the map after the first.
    pub map_last_over_first: f64,
    /// Peak resident memory of the run's process, MiB.
    pub peak_memory_mib: Option<f64>,
    /// ATE RMSE after rigid alignment over every frame, mm.
    pub ate_rmse_mm: Option<f64>,
    pub lost_frames: u64,
}

/// Reads `frames.json` and `metrics.json` of a finished `wgslam run --revisit` in `dir`.
pub fn summarise(dir: &Path, backend: &str, pass_frames: usize) -> Result<LongRun> {
    let read = |name: &str| -> Result<serde_json::Value> {
        let path = dir.join(name);
        let text = std::fs::read_to_string(&path).map_err(|e| Error::io(&path, e))?;
        serde_json::from_str(&text).map_err(|e| Error::format(&path, format!("not JSON: {e}")))
    };
    let frames = read("frames.json")?;
    let metrics = read("metrics.json")?;
    let frames = frames
        .as_array()
        .ok_or_else(|| Error::format(dir.join("frames.json"), "not a list of frames"))?;
    let seconds: Vec<f64> = frames
        .iter()
        .map(|f| f["seconds"].as_f64().unwrap_or(f64::NAN))
        .collect();
    let surfels: Vec<usize> = frames
        .iter()
        .map(|f| f["report"]["surfels"].as_u64().unwrap_or(0) as usize)
        .collect();
    if seconds.is_empty() || seconds.iter().any(|s| !s.is_finite()) || pass_frames == 0 {
        return Err(Error::format(dir.join("frames.json"), "no frame times"));
    }
    let n = seconds.len();
    let k = END_FRAMES.min(n);
    let mean_ms = |s: &[f64]| s.iter().sum::<f64>() / s.len() as f64 * 1e3;
    let (first_mean_ms, last_mean_ms) = (mean_ms(&seconds[..k]), mean_ms(&seconds[n - k..]));
    // Pass p ends at frame p x pass_frames (frame 0 starts the first pass).
    let mut map_after_pass: Vec<usize> = (1..)
        .map(|p| p * pass_frames)
        .take_while(|&end| end < n)
        .map(|end| surfels[end])
        .collect();
    if (n - 1) % pass_frames != 0 || map_after_pass.is_empty() {
        map_after_pass.push(surfels[n - 1]);
    }
    let mut sorted = seconds.clone();
    sorted.sort_by(f64::total_cmp);
    Ok(LongRun {
        backend: backend.to_string(),
        frames: n,
        pass_frames,
        first_mean_ms,
        last_mean_ms,
        last_over_first: last_mean_ms / first_mean_ms,
        median_ms: sorted[n / 2] * 1e3,
        map_last_over_first: *map_after_pass.last().unwrap() as f64
            / map_after_pass[0].max(1) as f64,
        map_after_pass,
        peak_memory_mib: metrics["peak_memory_mib"].as_f64(),
        ate_rmse_mm: metrics["accuracy"]["ate_rmse_aligned_m"]
            .as_f64()
            .map(|m| m * 1e3),
        lost_frames: metrics["tracking"]["lost"].as_u64().unwrap_or(0),
    })
}

/// Prints the long runs as a table.
pub fn print(runs: &[LongRun]) {
    println!(
        "{:<8} {:>6} {:>14} {:>14} {:>10} {:>10} {:>12} {:>8} {:>9}  map after each pass",
        "backend",
        "frames",
        "first 100 ms/f",
        "last 100 ms/f",
        "last/first",
        "median ms",
        "peak MiB",
        "ATE mm",
        "map x"
    );
    for r in runs {
        let opt =
            |x: Option<f64>, d: usize| x.map(|v| format!("{v:.d$}")).unwrap_or_else(|| "-".into());
        println!(
            "{:<8} {:>6} {:>14.1} {:>14.1} {:>10.2} {:>10.1} {:>12} {:>8} {:>9.2}  {}",
            r.backend,
            r.frames,
            r.first_mean_ms,
            r.last_mean_ms,
            r.last_over_first,
            r.median_ms,
            opt(r.peak_memory_mib, 0),
            opt(r.ate_rmse_mm, 2),
            r.map_last_over_first,
            r.map_after_pass
                .iter()
                .map(|m| m.to_string())
                .collect::<Vec<_>>()
                .join(" "),
        );
    }
}
