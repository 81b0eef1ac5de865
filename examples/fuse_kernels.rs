//! Fusion on a fixed real map, CPU reference vs GPU, per stage and per kernel.
//!
//! Builds the map of ICL-NUIM kt2 frames 1..N (default 40, full resolution, ground-truth
//! poses) with the CPU reference, then fuses frame N+1 into copies of that map repeatedly
//! on both backends and prints the fastest repetition of each stage (CPU wall time) and
//! each GPU kernel (timestamp queries). The minimum over repetitions is what survives
//! other jobs sharing the machine; it is how the texture layout of the GPU map was chosen.
//!
//! `cargo run --release --example fuse_kernels [N]` (needs `../shared/data`).

use std::collections::BTreeMap;

use wgslam::cpu_backend::CpuBackend;
use wgslam::dataset::{self, Sequence, SequenceOptions};
use wgslam::gpu::{GpuBackend, GpuContext};
use wgslam::pipeline::{Backend, PoseSource, Slam, SlamParams};
use wgslam::timed::Timed;

const REPETITIONS: usize = 10;

/// Loads frame `i` and runs it through `slam` with its ground-truth pose.
fn process<B: Backend>(seq: &Sequence, slam: &mut Slam<B>, i: usize) -> wgslam::Result<()> {
    let f = seq.load(i)?;
    let rgba = wgslam::run::packed_rgba(&f);
    let gt = seq.frames[i].gt_cam_to_world;
    slam.process(i as u32, &f.depth, &rgba, gt.as_ref())?;
    Ok(())
}

fn main() -> wgslam::Result<()> {
    let root = std::path::Path::new("../shared/data/icl_living_room_kt2");
    if !root.exists() {
        eprintln!("skipped: {} is absent", root.display());
        return Ok(());
    }
    let n: usize = match std::env::args().nth(1) {
        Some(s) => s
            .parse()
            .map_err(|_| wgslam::Error::Argument(format!("N must be a number, got {s}")))?,
        None => 40,
    };
    let seq = dataset::open(root, &SequenceOptions::default())?;
    let mut params = SlamParams {
        poses: PoseSource::GroundTruth,
        downsample: 1,
        ..SlamParams::default()
    };
    params.depth_scale = seq.depth_scale;
    let mut cpu = Slam::new(CpuBackend::new(), seq.intrinsics, params.clone());
    for i in 1..=n {
        process(&seq, &mut cpu, i)?;
    }
    let map = cpu.backend.download_map()?;

    let mut cpu_best: BTreeMap<String, f64> = BTreeMap::new();
    let mut merged = 0;
    for _ in 0..REPETITIONS {
        let backend = Timed::new(CpuBackend::with_map(map.clone()));
        let mut slam = Slam::new(backend, seq.intrinsics, params.clone());
        process(&seq, &mut slam, n + 1)?;
        for (stage, (_, secs)) in &slam.backend.stages {
            let e = cpu_best.entry(stage.to_string()).or_insert(f64::MAX);
            *e = e.min(secs * 1e3);
        }
        let after = slam.backend.inner.download_map()?;
        merged = (0..map.len())
            .filter(|&i| after.weight(i) > map.weight(i))
            .count();
    }
    println!(
        "map of frames 1..{n}: {} surfels; fusing frame {} merges {merged} of them",
        map.len(),
        n + 1
    );

    let mut gpu = GpuBackend::new(GpuContext::new()?)?;
    gpu.enable_kernel_timing();
    let mut slam = Slam::new(Timed::new(gpu), seq.intrinsics, params);
    let mut gpu_best: BTreeMap<String, f64> = BTreeMap::new();
    let mut stage_best: BTreeMap<String, f64> = BTreeMap::new();
    let mut before = slam.backend.inner.kernel_times();
    // Two more repetitions: Mesa compiles each kernel on its first dispatch.
    for rep in 0..REPETITIONS + 2 {
        slam.backend.inner.upload_map(&map)?;
        slam.backend.stages.clear();
        process(&seq, &mut slam, n + 1)?;
        let now = slam.backend.inner.kernel_times();
        if rep >= 2 {
            for (stage, (_, secs)) in &slam.backend.stages {
                let e = stage_best.entry(stage.to_string()).or_insert(f64::MAX);
                *e = e.min(secs * 1e3);
            }
            for (kernel, (_, ms)) in &now {
                let spent = ms - before.get(kernel).map_or(0.0, |b| b.1);
                let e = gpu_best.entry(kernel.clone()).or_insert(f64::MAX);
                *e = e.min(spent);
            }
        }
        before = now;
    }
    println!("fastest of {REPETITIONS} repetitions, milliseconds:");
    for (stage, ms) in &cpu_best {
        println!("  cpu stage  {stage:<18} {ms:8.2}");
    }
    for (stage, ms) in &stage_best {
        println!("  gpu stage  {stage:<18} {ms:8.2}");
    }
    for (kernel, ms) in &gpu_best {
        println!("  gpu kernel {kernel:<18} {ms:8.2}");
    }
    let cpu_fuse = cpu_best.get("fuse").copied().unwrap_or(f64::NAN);
    let gpu_fuse = gpu_best.get("fuse_merge").copied().unwrap_or(f64::NAN)
        + gpu_best.get("fuse_add").copied().unwrap_or(f64::NAN);
    println!(
        "fuse: cpu {cpu_fuse:.1} ms, gpu fuse_merge + fuse_add {gpu_fuse:.1} ms, GPU/CPU {:.2}x faster",
        cpu_fuse / gpu_fuse
    );
    Ok(())
}
