//! The batch job: run the dense pipeline over a sequence, evaluate, write the outputs.
//!
//! Frames are decoded ahead on a pool of worker threads ([`decode_ahead`]), so decoding
//! overlaps the pipeline; the per-frame time reported is the pipeline's (decode excluded),
//! and the wall-clock total and the loop's wait for decoded frames are reported beside it.
//! The per-stage benchmark passes decode each frame before processing it instead
//! ([`Decode::BeforeEachFrame`]): on a machine with few cores a decoder takes a core from
//! the backend beside it, which would charge decoding to one stage's time.
//! Outputs go to `--out DIR`, each file written completely or not at all (`io::atomic`).

use std::path::PathBuf;
use web_time::Instant;

use glam::DMat4;
use serde::{Deserialize, Serialize};

use crate::dataset::{RawFrame, Sequence};
use crate::eval;
use crate::layout::map::SurfelMap;
use crate::layout::pack_rgba8;
use crate::slam::backend::{Backend, Inspect};
use crate::slam::params::{SlamParams, ValidParams};
use crate::slam::pipeline::{FrameReport, Slam};
use crate::Result;

mod counts;
pub mod decode_ahead;
mod outputs;
pub use counts::{tracking_counts, TrackingCounts};
pub use decode_ahead::{for_each_frame, Decode, Decoded};
pub use outputs::{
    output_bytes, read_numbers, write_files_and_pictures, write_json, write_json_to, write_outputs,
    write_pictures, RunNumbers, OUTPUT_FILES,
};

/// One processed frame: where it sits in the sequence and what the pipeline did.
#[derive(Debug, Clone, Serialize)]
pub struct FrameOutcome {
    /// Position in the sequence.
    pub index: usize,
    /// Dataset stamp (seconds, or the frame index for ICL-NUIM).
    pub timestamp: f64,
    /// Pipeline time for this frame, seconds (decode excluded).
    pub seconds: f64,
    /// Time spent loading and decoding this frame's images, seconds (on a worker thread
    /// with [`Decode::Ahead`]).
    pub decode_seconds: f64,
    /// Time the frame loop waited for this frame's decoded images, seconds
    /// ([`Decoded::wait_seconds`]).
    #[serde(default)]
    pub wait_seconds: f64,
    pub report: FrameReport,
}

/// The result of a whole run.
#[derive(Debug)]
pub struct RunResult {
    pub frames: Vec<FrameOutcome>,
    pub map: SurfelMap,
    pub metrics: Metrics,
    /// With loop closure, the tracked frames' poses after every closure `(stamp,
    /// t_cam_to_world)`; `None` without (the trajectory is then the frames' own poses).
    pub optimised: Option<Vec<(f64, DMat4)>>,
}

impl RunResult {
    /// The run's trajectory (`trajectory.tum`): after loop closure when it ran, else as
    /// tracked.
    pub fn trajectory(&self) -> Vec<(f64, DMat4)> {
        match &self.optimised {
            Some(t) => t.clone(),
            None => trajectory(&self.frames),
        }
    }
}

/// Loop closure's part of `metrics.json`.
#[derive(Debug, Clone, Serialize)]
pub struct LoopMetrics {
    /// Loop candidates verified.
    pub candidates: usize,
    /// Accepted ones (a closure each; those above noise optimised the graph).
    pub accepted: usize,
    pub optimisations: usize,
    pub rejected: usize,
    /// Nodes and edges of the pose graph at the end.
    pub graph_nodes: usize,
    pub graph_edges: usize,
    /// ATE/RPE of the trajectory as tracked, before any closure (`trajectory_odometry.tum`;
    /// `accuracy` is the optimised trajectory's).
    pub odometry_accuracy: Option<Accuracy>,
    /// Every verified candidate, accepted or rejected, in order.
    pub loops: Vec<crate::slam::loops::LoopRecord>,
}

/// ATE and RPE against ground truth (TUM benchmark definitions).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Accuracy {
    /// Pose pairs evaluated.
    pub pairs: usize,
    /// Frames of the run without an estimated pose (lost, or without depth): the ATE and
    /// RPE are over the other frames only, so every report of them gives this count too
    /// ([`Accuracy::ate_text`]).
    pub frames_without_pose: usize,
    /// Absolute trajectory error RMSE after a rigid (Horn/Umeyama, no scale) alignment, m.
    pub ate_rmse_aligned_m: f64,
    /// Absolute trajectory error RMSE without alignment, m.
    pub ate_rmse_unaligned_m: f64,
    /// Relative pose error between consecutive frames: translation RMSE, m.
    pub rpe_trans_rmse_m: f64,
    /// Relative pose error between consecutive frames: rotation RMSE, degrees.
    pub rpe_rot_rmse_deg: f64,
}

/// What `metrics.json` holds.
#[derive(Debug, Clone, Serialize)]
pub struct Metrics {
    pub backend: String,
    pub dataset: PathBuf,
    pub first_frame: usize,
    pub last_frame: usize,
    pub frames: usize,
    pub width: u32,
    pub height: u32,
    /// The raw frames' intrinsics the run used (pixels of the raw frames, before
    /// `input.downsample`): the command line's over the parameter file's over the dataset's
    /// (docs/params-file.md, "Precedence").
    pub intrinsics: crate::geometry::camera::Intrinsics,
    /// The lens removed from the raw frames as they were decoded (`camera.json`'s
    /// `distortion`, a `--camera` preset's); absent for a pinhole camera.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub distortion: Option<crate::geometry::camera::Distortion>,
    pub params: SlamParams,
    /// Where `params.input.downsample` came from: set by the user, or the default of the
    /// backends that ran (`crate::slam::params::resolution`); absent where the caller
    /// passed parameters of its own making (the library, the page).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub downsample_from: Option<crate::slam::params::resolution::DownsampleFrom>,
    pub time_per_frame_median_s: f64,
    pub time_per_frame_mean_s: f64,
    pub time_total_s: f64,
    pub wall_total_s: f64,
    /// Time the frame loop waited for decoded frames, seconds (part of `wall_total_s`).
    pub decode_wait_s: f64,
    /// Worker threads that decoded ahead of the loop (0: each frame before it).
    pub decode_threads: usize,
    pub map_points: usize,
    /// Map points / (frames x H x W) of the downsampled maps.
    pub compression_ratio: f64,
    pub tracking: TrackingCounts,
    pub accuracy: Option<Accuracy>,
    /// Loop closure's loops and the odometry's accuracy; `None` without loop closure.
    pub loop_closure: Option<LoopMetrics>,
    /// Peak resident memory of the process (VmHWM), MiB; None where not available.
    pub peak_memory_mib: Option<f64>,
}

/// Packs a frame's RGB into the RGBA8 words the pipeline takes.
pub fn packed_rgba(frame: &RawFrame) -> Vec<u32> {
    frame.rgb.iter().map(|&c| pack_rgba8(c)).collect()
}

/// Peak resident set size of this process in MiB (Linux `/proc/self/status` VmHWM).
pub fn peak_memory_mib() -> Option<f64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = s.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb / 1024.0)
}

/// Runs `slam` over frames `first..=last` of `seq`, calling `on_frame` after each frame
/// (for progress). Frames are decoded ahead on one worker per core.
pub fn run_frames<B: Backend + Inspect>(
    slam: &mut Slam<B>,
    seq: &Sequence,
    first: usize,
    last: usize,
    on_frame: impl FnMut(&FrameOutcome),
) -> Result<(Vec<FrameOutcome>, f64)> {
    run_frames_with(
        slam,
        seq,
        first,
        last,
        Decode::ahead_on_every_core(),
        on_frame,
    )
}

/// Watches a run frame by frame with more than [`FrameOutcome`] holds: the decoded images,
/// and the map when it asks for it (`wgslam run --rerun`). Called on the pipeline's thread
/// after each frame's `on_frame`, outside the frame's timed work (its time shows in the
/// wall-clock total only).
pub trait FrameObserver {
    /// True when [`FrameObserver::frame`] wants the map after the frame at sequence position
    /// `index`: a whole-map download from the backend (on the GPU a read-back of 48 bytes per
    /// surfel), so ask every few frames, not every frame.
    fn wants_map(&mut self, index: usize) -> bool;
    /// After frame `outcome.index`: its raw images (full resolution, as decoded), what the
    /// pipeline did, and the map after the frame when [`FrameObserver::wants_map`] said so.
    fn frame(
        &mut self,
        raw: &RawFrame,
        outcome: &FrameOutcome,
        map: Option<&SurfelMap>,
    ) -> Result<()>;
}

/// [`run_frames`] with a choice of where frames are decoded.
pub fn run_frames_with<B: Backend + Inspect>(
    slam: &mut Slam<B>,
    seq: &Sequence,
    first: usize,
    last: usize,
    decode: Decode,
    on_frame: impl FnMut(&FrameOutcome),
) -> Result<(Vec<FrameOutcome>, f64)> {
    run_frames_observed(slam, seq, first..=last, decode, on_frame, None)
}

/// [`run_frames_with`] over `frames`, showing each frame to `observer` when there is one.
fn run_frames_observed<B: Backend + Inspect>(
    slam: &mut Slam<B>,
    seq: &Sequence,
    frames: std::ops::RangeInclusive<usize>,
    decode: Decode,
    mut on_frame: impl FnMut(&FrameOutcome),
    mut observer: Option<&mut dyn FrameObserver>,
) -> Result<(Vec<FrameOutcome>, f64)> {
    let wall = Instant::now();
    let mut outcomes = Vec::with_capacity(frames.clone().count());
    for_each_frame(seq, frames, decode, |decoded, next| {
        let Decoded {
            index: i,
            frame,
            rgba,
            decode_seconds,
            wait_seconds,
        } = decoded;
        let rec = &seq.frames[i];
        let t0 = Instant::now();
        let gt = rec.gt_cam_to_world.as_ref();
        let next = next.map(Decoded::as_next);
        let report = slam.process_before(i as u32, &frame.depth, &rgba, gt, next)?;
        let out = FrameOutcome {
            index: i,
            timestamp: rec.timestamp,
            seconds: t0.elapsed().as_secs_f64(),
            decode_seconds,
            wait_seconds,
            report,
        };
        on_frame(&out);
        if let Some(observer) = observer.as_deref_mut() {
            let map = match observer.wants_map(i) {
                true => Some(slam.backend.download_map()?),
                false => None,
            };
            observer.frame(&frame, &out, map.as_ref())?;
        }
        outcomes.push(out);
        Ok(())
    })?;
    Ok((outcomes, wall.elapsed().as_secs_f64()))
}

/// The estimated trajectory `(stamp, t_cam_to_world)`: the tracked frames only (a lost
/// frame or one without depth has no pose; see [`crate::slam::pipeline::TrackStatus::is_tracked`]).
pub fn trajectory(frames: &[FrameOutcome]) -> Vec<(f64, DMat4)> {
    frames
        .iter()
        .filter(|f| f.report.status.is_tracked())
        .map(|f| (f.timestamp, f.report.t_cam_to_world))
        .collect()
}

impl Accuracy {
    /// The aligned ATE with the count it is over: "12.345 mm over 398 poses, 2 frames
    /// without a pose".
    pub fn ate_text(&self) -> String {
        format!(
            "{:.3} mm over {} poses, {}",
            self.ate_rmse_aligned_m * 1e3,
            self.pairs,
            without_pose_text(self.frames_without_pose)
        )
    }
}

/// "1 frame without a pose", "2 frames without a pose".
fn without_pose_text(frames: usize) -> String {
    let s = if frames == 1 { "" } else { "s" };
    format!("{frames} frame{s} without a pose")
}

/// An aligned ATE as the benchmarks print it, with the frames it leaves out: "12.345 mm
/// (2 frames without a pose)", or "n/a" without ground truth.
pub fn ate_mm_text(accuracy: Option<&Accuracy>) -> String {
    accuracy.map_or("n/a".into(), |a| {
        format!(
            "{:.3} mm ({})",
            a.ate_rmse_aligned_m * 1e3,
            without_pose_text(a.frames_without_pose)
        )
    })
}

/// ATE/RPE of an estimated trajectory of a run of `frames` frames against ground truth,
/// `None` with fewer than two estimated poses that have ground truth (one pose aligns onto
/// any ground truth, and a run over frames 0..1 of ICL-NUIM, whose frame 0 has none, failed
/// after its last frame).
pub fn accuracy(
    est: &[(f64, DMat4)],
    gt: &[(f64, DMat4)],
    frames: usize,
) -> Result<Option<Accuracy>> {
    if gt.is_empty() || est.len() < 2 || eval::associate(est, gt, eval::DEFAULT_MAX_DT).len() < 2 {
        return Ok(None);
    }
    let aligned = eval::ate(est, gt, true)?;
    let unaligned = eval::ate(est, gt, false)?;
    let rpe = eval::rpe(est, gt, 1)?;
    Ok(Some(Accuracy {
        pairs: aligned.pairs,
        frames_without_pose: frames.saturating_sub(est.len()),
        ate_rmse_aligned_m: aligned.rmse_m,
        ate_rmse_unaligned_m: unaligned.rmse_m,
        rpe_trans_rmse_m: rpe.trans_rmse_m,
        rpe_rot_rmse_deg: rpe.rot_rmse_deg,
    }))
}

/// Runs the whole job on `backend` and computes the metrics (no files written).
pub fn run<B: Backend + Inspect>(
    backend: B,
    seq: &Sequence,
    first: usize,
    last: usize,
    params: ValidParams,
    on_frame: impl FnMut(&FrameOutcome),
) -> Result<RunResult> {
    run_with(
        backend,
        seq,
        first,
        last,
        params,
        Decode::ahead_on_every_core(),
        on_frame,
    )
}

/// [`run`] with a choice of where frames are decoded.
pub fn run_with<B: Backend + Inspect>(
    backend: B,
    seq: &Sequence,
    first: usize,
    last: usize,
    params: ValidParams,
    decode: Decode,
    on_frame: impl FnMut(&FrameOutcome),
) -> Result<RunResult> {
    run_observed(backend, seq, first..=last, params, decode, on_frame, None)
}

/// [`run_with`] over `frames`, showing each frame (images, outcome, and the map when it
/// asks) to `observer` when there is one; the final map is in the [`RunResult`]. The
/// parameters were validated when they were made ([`SlamParams::validate`] makes
/// [`ValidParams`]), and are not checked again.
pub fn run_observed<B: Backend + Inspect>(
    backend: B,
    seq: &Sequence,
    frames: std::ops::RangeInclusive<usize>,
    params: ValidParams,
    decode: Decode,
    on_frame: impl FnMut(&FrameOutcome),
    observer: Option<&mut dyn FrameObserver>,
) -> Result<RunResult> {
    if seq.root.to_str().is_none() {
        // metrics.json records the dataset's path as JSON text, which must be UTF-8; found
        // only after the last frame, this cost a whole run.
        return Err(crate::Error::format(
            &seq.root,
            "the dataset's path is not UTF-8, which metrics.json cannot record; rename the \
             folder or link to it from a UTF-8 path",
        ));
    }
    let (first, last) = (*frames.start(), *frames.end());
    let mut slam = Slam::for_sequence(backend, seq, params)?;
    let (frames, wall) = run_frames_observed(&mut slam, seq, frames, decode, on_frame, observer)?;
    let map = slam.backend.download_map()?;
    let counts = tracking_counts(&frames, slam.keyframe_count());
    let times: Vec<f64> = frames.iter().map(|f| f.seconds).collect();
    let total: f64 = times.iter().sum();
    let gt = seq.ground_truth();
    let odometry = trajectory(&frames);
    let (optimised, loop_closure) = match slam.loop_closure() {
        Some(lc) => {
            let stamp: std::collections::HashMap<usize, f64> =
                frames.iter().map(|f| (f.index, f.timestamp)).collect();
            let est: Vec<(f64, DMat4)> = lc
                .poses()
                .iter()
                .map(|p| (stamp[&(p.frame as usize)], p.estimate))
                .collect();
            let loops = lc.loops().to_vec();
            let accepted = loops.iter().filter(|l| l.rejected.is_none()).count();
            let metrics = LoopMetrics {
                candidates: loops.len(),
                accepted,
                optimisations: loops.iter().filter(|l| l.optimised.is_some()).count(),
                rejected: loops.len() - accepted,
                graph_nodes: lc.graph().nodes().len(),
                graph_edges: lc.graph().edges().len(),
                odometry_accuracy: accuracy(&odometry, &gt, frames.len())?,
                loops,
            };
            (Some(est), Some(metrics))
        }
        None => (None, None),
    };
    let est = optimised.clone().unwrap_or(odometry);
    let accuracy = accuracy(&est, &gt, frames.len())?;
    let k = slam.intrinsics;
    let metrics = Metrics {
        backend: slam.backend.name().to_string(),
        dataset: seq.root.clone(),
        first_frame: first,
        last_frame: last,
        frames: frames.len(),
        width: k.width,
        height: k.height,
        intrinsics: seq.intrinsics,
        distortion: seq.conventions.distortion,
        downsample_from: None,
        params: SlamParams::clone(&slam.params),
        time_per_frame_median_s: crate::stats::median(&times),
        time_per_frame_mean_s: total / frames.len().max(1) as f64,
        time_total_s: total,
        wall_total_s: wall,
        decode_wait_s: frames.iter().map(|f| f.wait_seconds).sum(),
        decode_threads: decode.threads(),
        map_points: map.len(),
        compression_ratio: map.len() as f64 / (frames.len().max(1) * k.pixels()) as f64,
        tracking: counts,
        accuracy,
        loop_closure,
        peak_memory_mib: peak_memory_mib(),
    };
    Ok(RunResult {
        frames,
        map,
        metrics,
        optimised,
    })
}

/// The run's summary as `wgslam run` prints it (time per frame, map size, tracking, ATE
/// and RPE, peak memory), one line each; the browser page shows the same lines.
pub fn summary_lines(m: &Metrics) -> Vec<String> {
    let mut lines = Vec::new();
    let why = m.downsample_from.and_then(|f| f.describe());
    lines.push(format!(
        "{} frames {}..{} on {} ({}x{}{}): {:.1} ms/frame median, {:.2} s total",
        m.frames,
        m.first_frame,
        m.last_frame,
        m.backend,
        m.width,
        m.height,
        why.map(|w| format!(", {w}")).unwrap_or_default(),
        m.time_per_frame_median_s * 1e3,
        m.time_total_s
    ));
    lines.push(format!(
        "map: {} points, compression ratio {:.4}",
        m.map_points, m.compression_ratio
    ));
    let t = &m.tracking;
    lines.push(format!(
        "tracking: {} given, {} converged, {} at max iterations, {} stopped early, {} \
         relocalised, {} lost, {} empty; {} keyframes",
        t.given,
        t.converged,
        t.max_iterations,
        t.stopped,
        t.relocalised,
        t.lost,
        t.empty_depth,
        t.keyframes
    ));
    lines.push(format!("tracking health: {}", t.verdict()));
    if let Some(l) = &m.loop_closure {
        lines.push(format!(
            "loop closure: {} candidate(s) verified, {} accepted ({} bent the map), {} rejected; \
             pose graph {} nodes, {} edges{}",
            l.candidates,
            l.accepted,
            l.optimisations,
            l.rejected,
            l.graph_nodes,
            l.graph_edges,
            match &l.odometry_accuracy {
                Some(a) => format!("; ATE before closures {} (aligned)", a.ate_text()),
                None => String::new(),
            }
        ));
    }
    if let Some(acc) = &m.accuracy {
        lines.push(format!(
            "ATE RMSE {} (aligned), {:.3} mm unaligned; RPE {:.3} mm, {:.4} deg",
            acc.ate_text(),
            acc.ate_rmse_unaligned_m * 1e3,
            acc.rpe_trans_rmse_m * 1e3,
            acc.rpe_rot_rmse_deg,
        ));
    }
    if let Some(mem) = m.peak_memory_mib {
        lines.push(format!("peak memory {mem:.0} MiB"));
    }
    lines
}
