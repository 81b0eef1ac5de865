//! Per-frame profile of a whole GPU run: wall time of every stage (waiting after each) next
//! to the GPU timestamp time of every kernel, frame by frame, with the map size.
//!
//! Shows where a frame's time goes as the map grows, and whether any wall time is spent
//! outside the kernels (growth copies, uploads, waits). One line per `STEP` frames.
//!
//! `cargo run --release --example frame_profile [LAST] [DOWNSAMPLE] [STEP]` (needs
//! `../shared/data`; defaults 1..200, full resolution, every 10th frame).

use std::collections::BTreeMap;

use wgslam::dataset::{self, SequenceOptions};
use wgslam::gpu::{GpuBackend, GpuContext};
use wgslam::instrumented::Instrumented;
use wgslam::pipeline::{Backend, Slam, SlamParams};

fn arg(i: usize, default: usize) -> wgslam::Result<usize> {
    match std::env::args().nth(i) {
        Some(s) => s
            .parse()
            .map_err(|_| wgslam::Error::Argument(format!("argument {i} must be a number"))),
        None => Ok(default),
    }
}

fn main() -> wgslam::Result<()> {
    let root = std::path::Path::new("../shared/data/icl_living_room_kt2");
    if !root.exists() {
        eprintln!("skipped: {} is absent", root.display());
        return Ok(());
    }
    let (last, downsample, step) = (arg(1, 200)?, arg(2, 1)?, arg(3, 10)?.max(1));
    let seq = dataset::open(root, &SequenceOptions::default())?;
    let params = SlamParams {
        downsample: downsample as u32,
        ..SlamParams::default()
    };
    let mut gpu = GpuBackend::new(GpuContext::new()?)?;
    gpu.enable_kernel_timing();
    let mut slam = Slam::for_sequence(Instrumented::timed(gpu), &seq, params);
    let mut stages_before: BTreeMap<&str, (u64, f64)> = BTreeMap::new();
    let mut kernels_before = slam.backend.inner.kernel_times();
    let mut acc_stage: BTreeMap<String, f64> = BTreeMap::new();
    let mut acc_kernel: BTreeMap<String, f64> = BTreeMap::new();
    let mut acc_frame = 0.0;
    let mut total_ms = 0.0;
    let mut frames = 0;
    for i in 1..=last.min(seq.frames.len() - 1) {
        let f = seq.load(i)?;
        let rgba = wgslam::run::packed_rgba(&f);
        let gt = seq.frames[i].gt_cam_to_world;
        let t0 = std::time::Instant::now();
        slam.process(i as u32, &f.depth, &rgba, gt.as_ref())?;
        let ms = t0.elapsed().as_secs_f64() * 1e3;
        acc_frame += ms;
        total_ms += ms;
        frames += 1;
        for (k, (_, s)) in &slam.backend.stages {
            let b = stages_before.get(k).map_or(0.0, |x| x.1);
            *acc_stage.entry(k.to_string()).or_default() += (s - b) * 1e3;
        }
        stages_before = slam.backend.stages.clone();
        let now = slam.backend.inner.kernel_times();
        for (k, (_, ms)) in &now {
            let b = kernels_before.get(k).map_or(0.0, |x| x.1);
            *acc_kernel.entry(k.clone()).or_default() += ms - b;
        }
        kernels_before = now;
        if i % step == 0 {
            let n = step as f64;
            let stages: Vec<String> = acc_stage
                .iter()
                .map(|(k, v)| format!("{k} {:.1}", v / n))
                .collect();
            let kernels: Vec<String> = acc_kernel
                .iter()
                .map(|(k, v)| format!("{k} {:.1}", v / n))
                .collect();
            println!(
                "frames ..{i}: {} surfels (capacity {}), frame {:.1} ms | {} | {}",
                slam.backend.surfel_count(),
                slam.backend.inner.capacity(),
                acc_frame / n,
                stages.join(", "),
                kernels.join(", ")
            );
            acc_stage.clear();
            acc_kernel.clear();
            acc_frame = 0.0;
        }
    }
    println!(
        "{frames} frames: {:.1} ms per frame (stages timed one by one)",
        total_ms / frames.max(1) as f64
    );
    Ok(())
}
