//! Benchmark of the dense pipeline: whole-frame and per-stage times, frames per second,
//! peak memory, readback bytes and submissions per frame, for each backend.
//!
//! Each backend runs in its own child process (`wgslam bench-one`), so peak memory (VmHWM)
//! is that backend's alone, and both are measured in the same `wgslam bench` invocation so
//! the GPU/CPU ratio compares like with like. Per-stage times come from a second pass with
//! `crate::slam::instrumented::Instrumented`, which waits for the device after each stage; frame times come
//! from the first pass, which does not. The first pass decodes ahead as `run` does
//! (`--decode-threads`, [`run::Decode`]) and also gives the end-to-end figures: frames per
//! second of its wall time, start-up (device, pipelines) and decoding included, and how
//! long the frame loop waited for decoded frames. The per-stage and kernel passes decode
//! each frame before processing it ([`run::Decode::BeforeEachFrame`]), so decoding never
//! competes with a stage for a core.

use serde::{Deserialize, Serialize};

use crate::dataset::Sequence;
use crate::gpu::backend::GpuBackend;
use crate::slam::any_backend;
use crate::slam::backend::{Backend, Inspect};
use crate::slam::instrumented::Instrumented;
use crate::slam::params::ValidParams;
use crate::slam::pipeline::Slam;
use crate::tools::round_trips::{FrameCounts, RoundTrips};
use crate::tools::run;
use crate::Result;

/// The per-stage and kernel passes decode on the pipeline's thread, outside the timed
/// frame (see the header).
const BEFORE: run::Decode = run::Decode::BeforeEachFrame;

/// One backend's figures.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct BenchResult {
    pub backend: String,
    pub frames: usize,
    pub width: u32,
    pub height: u32,
    /// Pipeline time per frame (decode excluded), median and mean, seconds.
    pub frame_median_s: f64,
    pub frame_mean_s: f64,
    pub fps: f64,
    /// Mean wall time per frame and stage call from the timed pass, milliseconds:
    /// (stage, calls per frame, ms per call).
    pub stages: Vec<(String, f64, f64)>,
    pub readback_bytes_per_frame: f64,
    pub submissions_per_frame: f64,
    pub peak_memory_mib: Option<f64>,
    pub map_points: usize,
    pub ate_rmse_aligned_m: Option<f64>,
    /// The ATE's and RPE's whole record, with the frames without a pose they leave out.
    #[serde(default)]
    pub accuracy: Option<run::Accuracy>,
    /// GPU only, with `--kernels`: (kernel, passes per frame, ms per pass) from GPU
    /// timestamps (or wall time per submission without them).
    #[serde(default)]
    pub kernels: Vec<(String, f64, f64)>,
    /// Mean time to load and decode one frame's images (not part of the frame times).
    #[serde(default)]
    pub decode_ms_per_frame: f64,
    /// The first pass end to end ([`EndToEnd`]).
    #[serde(default)]
    pub end_to_end: Option<EndToEnd>,
    /// Round trips and read-back per frame, from the plain pass (`readback_bytes_per_frame`
    /// and `submissions_per_frame` are their means over every frame).
    #[serde(default)]
    pub round_trips: Option<RoundTrips>,
}

/// The first pass as a user waits for it.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct EndToEnd {
    /// Worker threads that decoded ahead (0: each frame on the loop's thread before it).
    pub decode_threads: usize,
    /// Wall time of the pass, seconds: opening the backend (device, pipelines), the
    /// pipeline's set-up and every frame, decoding included.
    pub wall_s: f64,
    /// Frames over `wall_s`.
    pub wall_fps: f64,
    /// Wall time of the frame loop alone (from asking for the first frame to the end of the
    /// last), seconds.
    pub loop_wall_s: f64,
    /// Time the frame loop waited for decoded frames, seconds, and its fraction of
    /// `loop_wall_s`.
    pub decode_wait_s: f64,
    pub decode_wait_fraction: f64,
    /// Frames whose images were uploaded while the frame before them fused
    /// (`Slam::frames_uploaded_ahead`).
    #[serde(default)]
    pub uploaded_ahead: u64,
}

impl EndToEnd {
    /// The line `bench` prints: "end to end 8.1 frames/s of wall time (start-up and decoding
    /// included); the frame loop waited 0.05 s for decoded frames, 1.2 % of its 2.90 s (2
    /// decode threads); 21 frames uploaded during the fusion before them".
    pub fn text(&self) -> String {
        format!(
            "end to end {:.1} frames/s of wall time ({:.2} s, start-up and decoding \
             included); the frame loop waited {:.2} s for decoded frames, {:.1} % of its \
             {:.2} s ({} decode threads); {} frames uploaded during the fusion before them",
            self.wall_fps,
            self.wall_s,
            self.decode_wait_s,
            self.decode_wait_fraction * 100.0,
            self.loop_wall_s,
            self.decode_threads,
            self.uploaded_ahead
        )
    }
}

/// Mean decode time of a run's frames, milliseconds.
fn decode_ms(frames: &[run::FrameOutcome]) -> f64 {
    let n = frames.len().max(1) as f64;
    frames.iter().map(|f| f.decode_seconds).sum::<f64>() * 1e3 / n
}

/// Runs one backend once over the frames without per-stage timing: whole-frame times,
/// the end-to-end figures, peak memory, accuracy, and the round trips and read-back of
/// each frame (`stages` empty). The counters are read between frames of this pass, which
/// adds no synchronisation (the per-stage pass waits after every step, which would add
/// submissions of its own).
pub fn bench_frames<B: Backend + Inspect, F: FnMut() -> Result<B>>(
    mut make: F,
    seq: &Sequence,
    (first, last): (usize, usize),
    params: &ValidParams,
    decode: run::Decode,
) -> Result<BenchResult> {
    let start = web_time::Instant::now();
    let backend = make()?;
    let name = backend.name().to_string();
    let mut slam = Slam::for_sequence(backend, seq, params.clone())?;
    let mut frames = Vec::new();
    let mut counts = Vec::new();
    let loop_start = web_time::Instant::now();
    run::for_each_frame(seq, first..=last, decode, |d, next| {
        let rec = &seq.frames[d.index];
        let before = slam.backend.counters();
        let t0 = web_time::Instant::now();
        let gt = rec.gt_cam_to_world.as_ref();
        let next = next.map(run::Decoded::as_next);
        let report = slam.process_before(d.index as u32, &d.frame.depth, &d.rgba, gt, next)?;
        let seconds = t0.elapsed().as_secs_f64();
        let after = slam.backend.counters();
        counts.push(FrameCounts {
            submissions: after.submissions - before.submissions,
            device_submissions: after.device_submissions - before.device_submissions,
            waits: after.waits - before.waits,
            shared_waits: after.shared_waits - before.shared_waits,
            readback_bytes: after.readback_bytes - before.readback_bytes,
            icp_iterations: report.iterations.len(),
            plain: !report.keyframe && report.relocalisation.is_empty() && report.loops.is_empty(),
        });
        frames.push(run::FrameOutcome {
            index: d.index,
            timestamp: rec.timestamp,
            seconds,
            decode_seconds: d.decode_seconds,
            wait_seconds: d.wait_seconds,
            report,
        });
        Ok(())
    })?;
    let loop_wall_s = loop_start.elapsed().as_secs_f64();
    let wall_s = start.elapsed().as_secs_f64();
    let decode_wait_s: f64 = frames.iter().map(|f| f.wait_seconds).sum();
    let end_to_end = EndToEnd {
        decode_threads: decode.threads(),
        wall_s,
        wall_fps: frames.len() as f64 / wall_s.max(f64::MIN_POSITIVE),
        loop_wall_s,
        decode_wait_s,
        decode_wait_fraction: decode_wait_s / loop_wall_s.max(f64::MIN_POSITIVE),
        uploaded_ahead: slam.frames_uploaded_ahead(),
    };
    let accuracy = slam_accuracy(&slam, &frames, seq)?;
    let camera = seq.intrinsics.downsampled(params.input.downsample);
    let times: Vec<f64> = frames.iter().map(|f| f.seconds).collect();
    let mean = times.iter().sum::<f64>() / times.len().max(1) as f64;
    let mut result = BenchResult {
        backend: name,
        frames: frames.len(),
        width: camera.width,
        height: camera.height,
        frame_median_s: crate::stats::median(&times),
        frame_mean_s: mean,
        fps: 1.0 / mean.max(f64::MIN_POSITIVE),
        stages: Vec::new(),
        readback_bytes_per_frame: 0.0,
        submissions_per_frame: 0.0,
        peak_memory_mib: run::peak_memory_mib(),
        map_points: slam.backend.surfel_count()?,
        ate_rmse_aligned_m: accuracy.as_ref().map(|a| a.ate_rmse_aligned_m),
        accuracy,
        kernels: Vec::new(),
        decode_ms_per_frame: decode_ms(&frames),
        end_to_end: Some(end_to_end),
        round_trips: None,
    };
    result.set_counts(&counts);
    Ok(result)
}

/// The accuracy of a pass: of the poses after loop closure when it ran, else as tracked.
fn slam_accuracy<B: Backend>(
    slam: &crate::slam::pipeline::Slam<B>,
    frames: &[run::FrameOutcome],
    seq: &Sequence,
) -> Result<Option<run::Accuracy>> {
    let est = match slam.loop_closure() {
        Some(lc) => {
            let stamp: std::collections::HashMap<usize, f64> =
                frames.iter().map(|f| (f.index, f.timestamp)).collect();
            lc.poses()
                .iter()
                .map(|p| (stamp[&(p.frame as usize)], p.estimate))
                .collect()
        }
        None => run::trajectory(frames),
    };
    run::accuracy(&est, &seq.ground_truth(), frames.len())
}

impl BenchResult {
    /// Fills the per-frame counters from each frame's counts.
    fn set_counts(&mut self, counts: &[FrameCounts]) {
        let n = counts.len().max(1) as f64;
        self.submissions_per_frame = counts.iter().map(|c| c.submissions).sum::<u64>() as f64 / n;
        self.readback_bytes_per_frame =
            counts.iter().map(|c| c.readback_bytes).sum::<u64>() as f64 / n;
        self.round_trips = Some(RoundTrips::of(counts));
    }
}

/// Runs one backend twice over the frames (plain, then timed per stage).
pub fn bench_backend<B: Backend + Inspect, F: FnMut() -> Result<B>>(
    mut make: F,
    seq: &Sequence,
    first: usize,
    last: usize,
    params: &ValidParams,
    decode: run::Decode,
) -> Result<BenchResult> {
    let mut result = bench_frames(&mut make, seq, (first, last), params, decode)?;
    let backend = make()?;
    let mut slam = Slam::for_sequence(Instrumented::timed(backend), seq, params.clone())?;
    let (frames, _) = run::run_frames_with(&mut slam, seq, first, last, BEFORE, |_| {})?;
    let n = frames.len().max(1) as f64;
    result.stages = slam
        .backend
        .stages
        .iter()
        .map(|(k, (calls, secs))| {
            (
                k.to_string(),
                *calls as f64 / n,
                secs * 1e3 / (*calls).max(1) as f64,
            )
        })
        .collect();
    // Peak memory over both passes, read after the second.
    result.peak_memory_mib = run::peak_memory_mib();
    Ok(result)
}

/// One more GPU pass over the frames with per-kernel timing on: (kernel, passes per frame,
/// ms per pass).
pub fn gpu_kernel_times(
    seq: &Sequence,
    first: usize,
    last: usize,
    params: &ValidParams,
) -> Result<Vec<(String, f64, f64)>> {
    let mut gpu = GpuBackend::open()?;
    gpu.enable_kernel_timing();
    let mut slam = Slam::for_sequence(gpu, seq, params.clone())?;
    let (frames, _) = run::run_frames_with(&mut slam, seq, first, last, BEFORE, |_| {})?;
    let n = frames.len().max(1) as f64;
    Ok(slam
        .backend
        .kernel_times()
        .into_iter()
        .map(|(k, (passes, ms))| (k, passes as f64 / n, ms / passes.max(1) as f64))
        .collect())
}

/// Both backends in one process, frame by frame: see [`bench_interleaved`].
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct InterleavedResult {
    pub frames: usize,
    pub width: u32,
    pub height: u32,
    /// Pipeline time per frame (decode excluded), seconds, for each backend.
    pub cpu_frame_mean_s: f64,
    pub gpu_frame_mean_s: f64,
    /// CPU time over GPU time of each frame.
    #[serde(flatten)]
    pub ratios: PerFrameRatios,
    pub cpu_ate_rmse_aligned_m: Option<f64>,
    pub gpu_ate_rmse_aligned_m: Option<f64>,
    /// Each backend's ATE and RPE with the frames without a pose they leave out.
    #[serde(default)]
    pub cpu_accuracy: Option<run::Accuracy>,
    #[serde(default)]
    pub gpu_accuracy: Option<run::Accuracy>,
}

impl InterleavedResult {
    /// Mean CPU frame time over mean GPU frame time.
    pub fn ratio_of_means(&self) -> f64 {
        self.cpu_frame_mean_s / self.gpu_frame_mean_s
    }
}

/// Runs the CPU reference and `gpu` over the same frames in one process, alternating frame
/// by frame (which one goes first alternates too), each frame decoded once beforehand.
/// Both backends then meet the machine in the same state within a fraction of a second,
/// so the per-frame ratio survives other jobs that change the machine's speed from one
/// minute to the next, which separate runs do not (peak memory is not separable here; the
/// per-backend runs measure it).
pub fn bench_interleaved<G: Backend>(
    gpu: G,
    seq: &Sequence,
    first: usize,
    last: usize,
    params: &ValidParams,
) -> Result<InterleavedResult> {
    let mut cpu = Slam::for_sequence(any_backend::cpu_backend(1)?, seq, params.clone())?;
    let mut gpu = Slam::for_sequence(gpu, seq, params.clone())?;
    let (cpu_frames, gpu_frames) = interleave((&mut cpu, &mut gpu), seq, (first, last))?;
    let ratios = PerFrameRatios::of(&cpu_frames, &gpu_frames)?;
    let gt = seq.ground_truth();
    let accuracy = |f: &[run::FrameOutcome]| run::accuracy(&run::trajectory(f), &gt, f.len());
    let (cpu_accuracy, gpu_accuracy) = (accuracy(&cpu_frames)?, accuracy(&gpu_frames)?);
    let ate = |a: &Option<run::Accuracy>| a.as_ref().map(|a| a.ate_rmse_aligned_m);
    let camera = seq.intrinsics.downsampled(params.input.downsample);
    Ok(InterleavedResult {
        frames: cpu_frames.len(),
        width: camera.width,
        height: camera.height,
        cpu_frame_mean_s: mean_seconds(&cpu_frames),
        gpu_frame_mean_s: mean_seconds(&gpu_frames),
        ratios,
        cpu_ate_rmse_aligned_m: ate(&cpu_accuracy),
        gpu_ate_rmse_aligned_m: ate(&gpu_accuracy),
        cpu_accuracy,
        gpu_accuracy,
    })
}

/// Pipelines `a` and `b` over frames `first..=last` of `seq` in one process, alternating
/// frame by frame (which goes first alternates too), each frame decoded beforehand (not
/// timed): each pipeline's frames.
pub(crate) fn interleave<A: Backend, B: Backend>(
    (a, b): (&mut Slam<A>, &mut Slam<B>),
    seq: &Sequence,
    (first, last): (usize, usize),
) -> Result<(Vec<run::FrameOutcome>, Vec<run::FrameOutcome>)> {
    let (mut a_frames, mut b_frames) = (Vec::new(), Vec::new());
    run::for_each_frame(seq, first..=last, BEFORE, |d, _| {
        let (i, frame, rgba) = (d.index, d.frame, d.rgba);
        let rec = &seq.frames[i];
        let gt = rec.gt_cam_to_world.as_ref();
        let outcome = |report, seconds| run::FrameOutcome {
            index: i,
            timestamp: rec.timestamp,
            seconds,
            decode_seconds: 0.0,
            wait_seconds: 0.0,
            report,
        };
        let a_first = (i - first) % 2 == 0;
        for turn in 0..2 {
            let t0 = web_time::Instant::now();
            if (turn == 0) == a_first {
                let report = a.process(i as u32, &frame.depth, &rgba, gt)?;
                a_frames.push(outcome(report, t0.elapsed().as_secs_f64()));
            } else {
                let report = b.process(i as u32, &frame.depth, &rgba, gt)?;
                b_frames.push(outcome(report, t0.elapsed().as_secs_f64()));
            }
        }
        Ok(())
    })?;
    Ok((a_frames, b_frames))
}

/// Mean pipeline time of `frames`, seconds.
pub(crate) fn mean_seconds(frames: &[run::FrameOutcome]) -> f64 {
    frames.iter().map(|o| o.seconds).sum::<f64>() / frames.len().max(1) as f64
}

/// Per frame, `a`'s time over `b`'s: the median and the 10th and 90th percentiles
/// (nearest rank).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct PerFrameRatios {
    #[serde(rename = "ratio_median")]
    pub median: f64,
    #[serde(rename = "ratio_p10")]
    pub p10: f64,
    #[serde(rename = "ratio_p90")]
    pub p90: f64,
}

impl PerFrameRatios {
    /// The ratios of the same frames of two interleaved pipelines; an error without frames.
    pub(crate) fn of(a: &[run::FrameOutcome], b: &[run::FrameOutcome]) -> Result<PerFrameRatios> {
        let mut ratios: Vec<f64> = (a.iter().zip(b))
            .map(|(a, b)| a.seconds / b.seconds.max(f64::MIN_POSITIVE))
            .collect();
        if ratios.is_empty() {
            return Err(crate::Error::Argument("no frames to benchmark".into()));
        }
        ratios.sort_by(f64::total_cmp);
        let pick = |q: f64| ratios[((ratios.len() - 1) as f64 * q).round() as usize];
        Ok(PerFrameRatios {
            median: crate::stats::median(&ratios),
            p10: pick(0.1),
            p90: pick(0.9),
        })
    }
}

/// Prints an interleaved result.
pub fn print_interleaved(r: &InterleavedResult) {
    println!(
        "interleaved, frame by frame in one process ({} frames {}x{}): cpu {:.1} ms/frame, \
         gpu {:.1} ms/frame mean; ATE cpu {}, gpu {}",
        r.frames,
        r.width,
        r.height,
        r.cpu_frame_mean_s * 1e3,
        r.gpu_frame_mean_s * 1e3,
        run::ate_mm_text(r.cpu_accuracy.as_ref()),
        run::ate_mm_text(r.gpu_accuracy.as_ref()),
    );
    println!(
        "GPU/CPU interleaved: {:.2}x faster (ratio of means); per frame median {:.2}x, \
         10th-90th percentile {:.2}x..{:.2}x",
        r.ratio_of_means(),
        r.ratios.median,
        r.ratios.p10,
        r.ratios.p90
    );
}

/// Mean CPU frame time over mean GPU frame time ("x faster"), when both ran.
pub fn gpu_over_cpu(results: &[BenchResult]) -> Option<f64> {
    let c = results.iter().find(|r| r.backend == "cpu")?;
    let g = results.iter().find(|r| r.backend == "gpu")?;
    Some(c.frame_mean_s / g.frame_mean_s)
}

/// One line per backend for a whole-frame-only round, and the round's ratio.
pub fn print_round(round: usize, results: &[BenchResult]) {
    let order: Vec<&str> = results.iter().map(|r| r.backend.as_str()).collect();
    println!("round {round} ({}):", order.join(" then "));
    for r in results {
        println!(
            "{:>4}: {:.1} ms/frame median, {:.1} ms mean, ATE {}",
            r.backend,
            r.frame_median_s * 1e3,
            r.frame_mean_s * 1e3,
            run::ate_mm_text(r.accuracy.as_ref()),
        );
    }
    if let Some(x) = gpu_over_cpu(results) {
        println!("GPU/CPU: {x:.2}x faster per frame");
    }
}

/// The GPU/CPU ratio of every round and their median.
pub fn print_ratio_over_rounds(rounds: &[Vec<BenchResult>]) {
    let ratios: Vec<f64> = rounds.iter().filter_map(|r| gpu_over_cpu(r)).collect();
    if ratios.is_empty() {
        return;
    }
    let listed: Vec<String> = ratios.iter().map(|x| format!("{x:.2}x")).collect();
    let (lo, hi) = ratios
        .iter()
        .fold((f64::MAX, f64::MIN), |(lo, hi), &x| (lo.min(x), hi.max(x)));
    println!(
        "GPU/CPU over {} rounds: {} (median {:.2}x, range {lo:.2}x..{hi:.2}x)",
        ratios.len(),
        listed.join(", "),
        crate::stats::median(&ratios),
    );
}

/// Prints a table of the results and the GPU/CPU ratios.
pub fn print_table(results: &[BenchResult]) {
    for r in results {
        println!(
            "{:>4}: {} frames {}x{}: {:.1} ms/frame median, {:.1} ms mean, {:.2} fps, \
             peak {:.0} MiB, {} surfels, ATE {}",
            r.backend,
            r.frames,
            r.width,
            r.height,
            r.frame_median_s * 1e3,
            r.frame_mean_s * 1e3,
            r.fps,
            r.peak_memory_mib.unwrap_or(f64::NAN),
            r.map_points,
            run::ate_mm_text(r.accuracy.as_ref()),
        );
        for (stage, calls, ms) in &r.stages {
            println!("      {stage:<14} {calls:5.2} calls/frame  {ms:8.2} ms/call");
        }
        for (kernel, passes, ms) in &r.kernels {
            println!("      kernel {kernel:<16} {passes:5.2} passes/frame {ms:8.2} ms/pass");
        }
        println!(
            "      readback {:.0} bytes/frame, {:.1} submissions/frame; decoding the \
             images took {:.1} ms/frame (not timed in the frame)",
            r.readback_bytes_per_frame, r.submissions_per_frame, r.decode_ms_per_frame
        );
        if let Some(e) = &r.end_to_end {
            println!("      {}", e.text());
        }
        if let Some(t) = &r.round_trips {
            println!(
                "      {:.1} ICP iterations/frame; on {} frames without keyframe, \
                 relocalisation or loop check: submissions beyond one per ICP iteration \
                 {:.2} mean, {} most; waits beyond one per ICP iteration {:.2} mean, {} most; \
                 readback {:.0} bytes mean, {} most",
                t.icp_iterations_per_frame,
                t.plain_frames,
                t.plain_submissions_beyond_icp_mean,
                t.plain_submissions_beyond_icp_max,
                t.plain_waits_beyond_icp_mean,
                t.plain_waits_beyond_icp_max,
                t.plain_readback_bytes_mean,
                t.plain_readback_bytes_max
            );
        }
    }
    if let (Some(c), Some(g)) = (
        results.iter().find(|r| r.backend == "cpu"),
        results.iter().find(|r| r.backend == "gpu"),
    ) {
        println!(
            "GPU/CPU: {:.2}x faster per frame (mean {:.1} ms vs {:.1} ms)",
            c.frame_mean_s / g.frame_mean_s,
            g.frame_mean_s * 1e3,
            c.frame_mean_s * 1e3
        );
    }
}

/// Runs `wgslam bench-one <bench_one_args> --backends <backend>` in a child process (so
/// its peak memory is its own) and parses the result it prints as JSON. `bench_one_args`
/// name the dataset folder, the parameter file (`--params`) and the frames (the CLI's
/// `bench` writes them); `frames_only` asks for whole-frame times only, `kernels` for GPU
/// kernel times as well.
pub fn bench_in_child(
    bench_one_args: &[String],
    backend: &str,
    frames_only: bool,
    kernels: bool,
) -> Result<BenchResult> {
    let exe = std::env::current_exe().map_err(|e| crate::Error::io("current executable", e))?;
    let mut cmd = std::process::Command::new(&exe);
    cmd.arg("bench-one").args(bench_one_args);
    cmd.args(["--backends", backend]);
    if frames_only {
        cmd.arg("--frames-only");
    } else if kernels {
        cmd.arg("--kernels");
    }
    eprintln!("benchmarking the {backend} backend ...");
    let out = cmd
        .stderr(std::process::Stdio::inherit())
        .output()
        .map_err(|e| crate::Error::io(&exe, e))?;
    if !out.status.success() {
        return Err(crate::Error::format(
            &exe,
            format!(
                "bench-one for the {backend} backend exited with {} (its error is above)",
                out.status
            ),
        ));
    }
    serde_json::from_slice(&out.stdout)
        .map_err(|e| crate::Error::format(&exe, format!("bench-one output: {e}")))
}
