//! `wgslam bench --thread-scaling`: the CPU reference on one thread and on N, alternating
//! frame by frame in one process (issue 48 item 5's ratio "in one run"), so that other jobs
//! on the machine slow both alike; and whether both give the same bits, as the twins'
//! fixed-order reductions promise. Not a GPU benchmark.

use std::num::NonZeroUsize;

use serde::Serialize;

use crate::cpu::invocations::Threads;
use crate::dataset::Sequence;
use crate::slam::backend::Inspect;
use crate::slam::cpu_backend::CpuBackend;
use crate::slam::params::ValidParams;
use crate::slam::pipeline::Slam;
use crate::tools::bench::{interleave, mean_seconds, PerFrameRatios};
use crate::tools::run;
use crate::Result;

/// What [`bench_thread_scaling`] measured.
#[derive(Debug, Clone, Serialize)]
pub struct ThreadScaling {
    /// Threads of the second pipeline (the first has one).
    pub threads: usize,
    pub frames: usize,
    pub width: u32,
    pub height: u32,
    /// Pipeline time per frame (decode excluded), seconds: one thread, `threads` threads.
    pub one_thread_mean_s: f64,
    pub many_threads_mean_s: f64,
    /// One thread's time over `threads` threads' time of each frame.
    #[serde(flatten)]
    pub ratios: PerFrameRatios,
    /// Both pipelines gave the same poses (bits) and the same map.
    pub identical: bool,
}

impl ThreadScaling {
    /// Mean one-thread frame time over mean many-thread frame time.
    pub fn ratio_of_means(&self) -> f64 {
        self.one_thread_mean_s / self.many_threads_mean_s.max(f64::MIN_POSITIVE)
    }

    /// The lines `bench --thread-scaling` prints.
    pub fn text(&self) -> String {
        format!(
            "CPU reference, 1 and {} threads frame by frame in one process ({} frames \
             {}x{}): {:.1} and {:.1} ms/frame mean\n{} threads {:.2}x faster than 1 (ratio \
             of means); per frame median {:.2}x, 10th-90th percentile {:.2}x..{:.2}x; \
             outputs {}",
            self.threads,
            self.frames,
            self.width,
            self.height,
            self.one_thread_mean_s * 1e3,
            self.many_threads_mean_s * 1e3,
            self.threads,
            self.ratio_of_means(),
            self.ratios.median,
            self.ratios.p10,
            self.ratios.p90,
            match self.identical {
                true => "identical (poses bit for bit, map)",
                false => "DIFFER",
            }
        )
    }
}

/// Frames `first..=last` of `seq` on the CPU reference with one thread and on `many`,
/// interleaved frame by frame (`bench::interleave`).
pub fn bench_thread_scaling(
    many: Threads,
    seq: &Sequence,
    (first, last): (usize, usize),
    params: &ValidParams,
) -> Result<ThreadScaling> {
    let threads = many.count();
    let slam = |t| Slam::for_sequence(CpuBackend::with_threads(t), seq, params.clone());
    let one_thread = Threads::bounded(NonZeroUsize::MIN)?;
    let (mut one, mut many) = (slam(one_thread)?, slam(many)?);
    let (one_frames, many_frames) = interleave((&mut one, &mut many), seq, (first, last))?;
    let ratios = PerFrameRatios::of(&one_frames, &many_frames)?;
    let poses = |f: &[run::FrameOutcome]| -> Vec<[u64; 16]> {
        f.iter()
            .map(|o| o.report.t_cam_to_world.to_cols_array().map(f64::to_bits))
            .collect()
    };
    let camera = seq.intrinsics.downsampled(params.input.downsample);
    Ok(ThreadScaling {
        threads,
        frames: one_frames.len(),
        width: camera.width,
        height: camera.height,
        one_thread_mean_s: mean_seconds(&one_frames),
        many_threads_mean_s: mean_seconds(&many_frames),
        ratios,
        identical: poses(&one_frames) == poses(&many_frames)
            && one.backend.download_map()? == many.backend.download_map()?,
    })
}
