//! The long-sequence benchmark (`wgslam bench --revisit N`): one backend's `wgslam run
//! --revisit N` (frames played forwards, backwards, ... so the camera sees the same scene
//! again and again) summarised as what a long batch run meets: time per frame early and
//! late, the map's size after each pass, peak memory, and the accuracy on the ground truth.

use std::path::Path;

use serde::Serialize;

use crate::tools::run::read_numbers;
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

/// Runs `wgslam RUN_ARGS --out TMP` (a `wgslam run --revisit ...` of one backend) in a
/// child process of this executable, so its peak memory is its own, and summarises it;
/// the outputs go to a temporary folder, removed afterwards.
pub fn run_in_child(run_args: &[String], backend: &str, pass_frames: usize) -> Result<LongRun> {
    let exe = std::env::current_exe().map_err(|e| Error::io("the wgslam executable", e))?;
    let out = std::env::temp_dir().join(format!(
        "wgslam-bench-revisit-{}-{backend}",
        std::process::id()
    ));
    let o = std::process::Command::new(&exe)
        .args(run_args)
        .arg("--out")
        .arg(&out)
        .stdin(std::process::Stdio::null())
        .output()
        .map_err(|e| Error::io(&exe, e));
    let result = o.and_then(|o| {
        if o.status.success() {
            summarise(&out, backend, pass_frames)
        } else {
            Err(Error::Numerical(format!(
                "the {backend} long run failed ({}): {}",
                o.status,
                String::from_utf8_lossy(&o.stderr).trim()
            )))
        }
    });
    let _ = std::fs::remove_dir_all(&out);
    result
}

/// Reads `frames.json` and `metrics.json` of a finished `wgslam run --revisit` in `dir`.
pub fn summarise(dir: &Path, backend: &str, pass_frames: usize) -> Result<LongRun> {
    let path = dir.join("frames.json");
    let text = std::fs::read_to_string(&path).map_err(|e| Error::io(&path, e))?;
    let frames: serde_json::Value =
        serde_json::from_str(&text).map_err(|e| Error::format(&path, format!("not JSON: {e}")))?;
    let numbers = read_numbers(&dir.join("metrics.json"))?;
    let frames = frames
        .as_array()
        .ok_or_else(|| Error::format(&path, "not a list of frames"))?;
    let seconds: Vec<f64> = frames
        .iter()
        .map(|f| f["seconds"].as_f64().unwrap_or(f64::NAN))
        .collect();
    let surfels: Vec<usize> = frames
        .iter()
        .map(|f| f["report"]["surfels"].as_u64().unwrap_or(0) as usize)
        .collect();
    if seconds.is_empty() || seconds.iter().any(|s| !s.is_finite()) || pass_frames == 0 {
        return Err(Error::format(&path, "no frame times"));
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
    Ok(LongRun {
        backend: backend.to_string(),
        frames: n,
        pass_frames,
        first_mean_ms,
        last_mean_ms,
        last_over_first: last_mean_ms / first_mean_ms,
        median_ms: crate::stats::median(&seconds) * 1e3,
        map_last_over_first: *map_after_pass.last().unwrap() as f64
            / map_after_pass[0].max(1) as f64,
        map_after_pass,
        peak_memory_mib: numbers.peak_memory_mib,
        ate_rmse_mm: numbers.ate_rmse_mm,
        lost_frames: numbers.lost_frames,
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
