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
    /// Per pass (as `map_after_pass`): loops accepted in it (empty without loop closure).
    pub loops_per_pass: Vec<usize>,
    /// Per pass: ATE RMSE of its frames after one rigid alignment of the whole run, mm
    /// (drift shows as growth from pass to pass).
    pub ate_per_pass_mm: Vec<f64>,
}

/// Runs `wgslam RUN_ARGS --out TMP` (a `wgslam run --revisit ...` of one backend) in a
/// child process of this executable, so its peak memory is its own, and summarises it;
/// the outputs go to a temporary folder, removed afterwards.
pub fn run_in_child(
    run_args: &[String],
    backend: &str,
    pass_frames: usize,
    gt: &[(f64, glam::DMat4)],
) -> Result<LongRun> {
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
            summarise(&out, backend, pass_frames, gt)
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

/// The map's size after each of a run's `frames` (`frames.json`'s records): after frame k
/// the one frame k + 1 was tracked against, after the last frame the map written
/// (`metrics.json`'s `map_points`).
fn map_after_frames(frames: &[serde_json::Value], metrics: &serde_json::Value) -> Vec<usize> {
    frames[1..]
        .iter()
        .map(|f| f["report"]["surfels_before"].as_u64().unwrap_or(0))
        .chain([metrics["map_points"].as_u64().unwrap_or(0)])
        .map(|n| n as usize)
        .collect()
}

/// Reads `frames.json`, `metrics.json` and `trajectory.tum` of a finished `wgslam run
/// --revisit` in `dir`; `gt` is the revisiting sequence's ground truth (stamps = positions).
pub fn summarise(
    dir: &Path,
    backend: &str,
    pass_frames: usize,
    gt: &[(f64, glam::DMat4)],
) -> Result<LongRun> {
    let path = dir.join("frames.json");
    let text = crate::io::input::read_kind_string(&path, crate::io::input::InputKind::List)?;
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
    if seconds.is_empty() || seconds.iter().any(|s| !s.is_finite()) || pass_frames == 0 {
        return Err(Error::format(&path, "no frame times"));
    }
    let metrics_path = dir.join("metrics.json");
    let metrics_text =
        crate::io::input::read_kind_string(&metrics_path, crate::io::input::InputKind::List)?;
    let metrics: serde_json::Value = serde_json::from_str(&metrics_text)
        .map_err(|e| Error::format(&metrics_path, format!("not JSON: {e}")))?;
    let surfels = map_after_frames(frames, &metrics);
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
    let passes = map_after_pass.len();
    // Frame k belongs to pass (k - 1) / pass_frames (frame 0 to the first).
    let pass_of = |k: usize| (k.saturating_sub(1) / pass_frames).min(passes - 1);
    let mut loops_per_pass = Vec::new();
    if let Some(loops) = metrics["loop_closure"]["loops"].as_array() {
        loops_per_pass = vec![0; passes];
        for l in loops.iter().filter(|l| l["rejected"].is_null()) {
            if let Some(frame) = l["frame"].as_u64() {
                loops_per_pass[pass_of(frame as usize)] += 1;
            }
        }
    }
    let est = crate::io::trajectory::read_tum(&dir.join("trajectory.tum"))?;
    let mut ate_per_pass_mm = Vec::new();
    let pairs = crate::eval::associate(&est, gt, crate::eval::DEFAULT_MAX_DT);
    if pairs.len() >= 3 {
        // One rigid alignment of the whole run, then each pass's error: drift shows as
        // growth from pass to pass, whatever the first pose.
        let position = |t: &glam::DMat4| t.w_axis.truncate();
        let (e, g): (Vec<_>, Vec<_>) = pairs
            .iter()
            .map(|&(i, j)| (position(&est[i].1), position(&gt[j].1)))
            .unzip();
        let align = crate::eval::align_rigid(&e, &g)?;
        let est: Vec<(f64, glam::DMat4)> = est.iter().map(|(s, t)| (*s, align * *t)).collect();
        for p in 0..passes {
            let pass: Vec<(f64, glam::DMat4)> = est
                .iter()
                .copied()
                .filter(|(stamp, _)| pass_of(*stamp as usize) == p)
                .collect();
            if pass.len() >= 2 {
                ate_per_pass_mm.push(crate::eval::ate(&pass, gt, false)?.rmse_m * 1e3);
            }
        }
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
        loops_per_pass,
        ate_per_pass_mm,
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
    for r in runs {
        let join = |v: Vec<String>| v.join(" ");
        println!(
            "{}: loops accepted per pass [{}]; ATE per pass (one alignment of the run, mm) [{}]",
            r.backend,
            join(r.loops_per_pass.iter().map(|n| n.to_string()).collect()),
            join(
                r.ate_per_pass_mm
                    .iter()
                    .map(|a| format!("{a:.1}"))
                    .collect()
            ),
        );
    }
}
