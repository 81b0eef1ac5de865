//! `wgslam bench --streams N`: one sequence tracked by N GPU streams at once in this
//! process, each on its own context sharing one device and queue (as `batch --concurrent
//! N` runs its jobs), after the same sequence as one stream alone: host waits and
//! submissions per stream-frame (those each stream asked for, and the `queue.submit` calls
//! the device got, fewer where streams combine them), ICP iterations per frame, wall time
//! against N runs one at a time, and whether every stream's result equals the lone
//! stream's. Not a CPU benchmark: the CPU backend has no waits to share.

use serde::Serialize;

use crate::dataset::Sequence;
use crate::gpu::backend::GpuBackend;
use crate::gpu::GpuContext;
use crate::slam::params::ValidParams;
use crate::tools::bench::{self, BenchResult};
use crate::tools::run;
use crate::{Error, Result};

/// Per stream-frame figures of one run of `streams` streams, means over every stream's
/// every frame.
#[derive(Debug, Clone, Serialize)]
pub struct StreamsPass {
    pub streams: usize,
    /// Wall time of the whole pass (every stream started, run and finished), seconds.
    pub wall_s: f64,
    /// ICP iterations per frame (each one submit and one read-back).
    pub icp_iterations_per_frame: f64,
    /// Device waits a stream made itself, per stream-frame.
    pub waits_per_stream_frame: f64,
    /// Waits served by another stream's device wait, per stream-frame.
    pub shared_waits_per_stream_frame: f64,
    /// Submissions per stream-frame (each stream's own, as it asked for them).
    pub submissions_per_stream_frame: f64,
    /// `queue.submit` calls the device got per stream-frame: every stream's together over
    /// every stream's frames. Fewer than the submissions where streams combine theirs.
    pub device_submissions_per_stream_frame: f64,
    /// Each stream's own result (its `round_trips` hold its per-frame counts).
    #[serde(skip)]
    pub each: Vec<BenchResult>,
}

/// One stream alone, then `streams` at once, on the same frames.
#[derive(Debug, Clone, Serialize)]
pub struct StreamsResult {
    pub frames_per_stream: usize,
    pub one: StreamsPass,
    pub many: StreamsPass,
    /// The many streams' wall time over `streams` times the lone stream's: below 1 when
    /// running them at once beats running them one at a time.
    pub wall_ratio_to_one_at_a_time: f64,
    /// Every stream's map size and accuracy (ATE, RPE, unaligned and aligned) equal the
    /// lone stream's, bit for bit.
    pub identical_to_one: bool,
}

/// Runs `frames` of `seq` as one stream on a context shared from `ctx`, then as `streams`
/// streams at once, each on its own shared context (see the module docs).
pub fn bench_streams(
    ctx: &GpuContext,
    seq: &Sequence,
    frames: (usize, usize),
    params: &ValidParams,
    streams: usize,
) -> Result<StreamsResult> {
    if streams == 0 {
        return Err(Error::Argument("--streams: want at least 1".into()));
    }
    // Builds the kernels (cached per device) before any pass is timed, so the lone
    // stream's wall time does not carry the pipelines' start-up that the others reuse.
    drop(GpuBackend::new(ctx.share())?);
    let run = Frames { frames, params };
    let one = pass(ctx, seq, run, 1)?;
    let many = pass(ctx, seq, run, streams)?;
    let same = |r: &BenchResult| {
        let lone = &one.each[0];
        r.map_points == lone.map_points
            && serde_json::to_string(&r.accuracy).ok() == serde_json::to_string(&lone.accuracy).ok()
    };
    let identical_to_one = many.each.iter().all(same);
    Ok(StreamsResult {
        frames_per_stream: one.each[0].frames,
        wall_ratio_to_one_at_a_time: many.wall_s
            / (streams as f64 * one.wall_s).max(f64::MIN_POSITIVE),
        identical_to_one,
        one,
        many,
    })
}

/// What every stream runs: frames `frames.0..=frames.1` with `params`.
#[derive(Clone, Copy)]
struct Frames<'a> {
    frames: (usize, usize),
    params: &'a ValidParams,
}

/// `streams` streams at once over `frames` of `seq`, each in a thread of its own on a
/// context shared from `ctx`.
fn pass(ctx: &GpuContext, seq: &Sequence, run: Frames<'_>, streams: usize) -> Result<StreamsPass> {
    let Frames { frames, params } = run;
    let start = web_time::Instant::now();
    let each: Vec<Result<BenchResult>> = std::thread::scope(|scope| {
        let handles: Vec<_> = (0..streams)
            .map(|_| {
                let stream_ctx = ctx.share();
                scope.spawn(move || {
                    let mut stream_ctx = Some(stream_ctx);
                    let make = || {
                        let c = stream_ctx.take().expect("bench_frames opens one backend");
                        GpuBackend::new(c)
                    };
                    bench::bench_frames(make, seq, frames, params, run::Decode::BeforeEachFrame)
                })
            })
            .collect();
        handles
            .into_iter()
            .map(|h| {
                h.join()
                    .unwrap_or_else(|_| Err(Error::Gpu("a stream's thread panicked".into())))
            })
            .collect()
    });
    let wall_s = start.elapsed().as_secs_f64();
    let each: Vec<BenchResult> = each.into_iter().collect::<Result<_>>()?;
    let mean = |f: &dyn Fn(&crate::tools::round_trips::RoundTrips) -> f64| {
        let sum: f64 = each
            .iter()
            .filter_map(|r| r.round_trips.as_ref())
            .map(f)
            .sum();
        sum / each.len().max(1) as f64
    };
    Ok(StreamsPass {
        streams,
        wall_s,
        icp_iterations_per_frame: mean(&|t| t.icp_iterations_per_frame),
        waits_per_stream_frame: mean(&|t| t.waits_per_frame),
        shared_waits_per_stream_frame: mean(&|t| t.shared_waits_per_frame),
        device_submissions_per_stream_frame: mean(&|t| t.device_submissions_per_frame),
        submissions_per_stream_frame: each.iter().map(|r| r.submissions_per_frame).sum::<f64>()
            / each.len().max(1) as f64,
        each,
    })
}

impl StreamsPass {
    /// The pass's figures in a line (without every stream's whole result).
    pub fn line(&self) -> String {
        format!(
            "{} stream(s): ICP {:.2}, waits {:.2}, shared {:.2}, submissions {:.2}, device \
             submissions {:.2} per stream-frame, {:.2} s",
            self.streams,
            self.icp_iterations_per_frame,
            self.waits_per_stream_frame,
            self.shared_waits_per_stream_frame,
            self.submissions_per_stream_frame,
            self.device_submissions_per_stream_frame,
            self.wall_s
        )
    }
}

/// Prints the two passes, one line each, and how they compare.
pub fn print_streams(r: &StreamsResult) {
    for p in [&r.one, &r.many] {
        println!("{}", p.line());
    }
    println!(
        "{} frames per stream; wall time of {} at once / {} one at a time: {:.2}; results {}",
        r.frames_per_stream,
        r.many.streams,
        r.many.streams,
        r.wall_ratio_to_one_at_a_time,
        if r.identical_to_one {
            "identical to one stream's"
        } else {
            "DIFFER from one stream's"
        }
    );
}
