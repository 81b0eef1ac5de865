//! Process memory (RSS) over many calls of one GPU step with new parameters each call: the
//! measurement behind binding every kernel's params struct as a read-only storage buffer
//! rather than a uniform buffer (`gpu::kernel::BindingKind::Params`).
//!
//! With `var<uniform> params`, lavapipe (Mesa 22.3) compiled a new variant of `icp_reduce`
//! after every write of its params and kept it: RSS grew by 0.75 MB per ICP iteration (500
//! iterations: 121 MB -> 496 MB), even with the same values written each time and with
//! the write in a submission of its own; writing another kernel's uniform, or not writing
//! at all, did not grow it. With `var<storage, read> params`: 132 MB -> 132 MB.
//!
//! Runs the robust profile on two bundled frames, then calls `icp_system` (and then
//! `predict`) N times at slightly different poses and prints RSS before and after.
//!
//! `cargo run --release --example params_memory [N]`

use wgslam::dataset::{self, SequenceOptions};
use wgslam::geometry::se3;
use wgslam::gpu::GpuBackend;
use wgslam::slam::backend::Backend;
use wgslam::slam::params::{Profile, ValidParams};
use wgslam::slam::pipeline::Slam;
use wgslam::tools::run::packed_rgba;

/// Resident set size of this process, MiB (Linux: /proc/self/statm).
fn rss_mib() -> f64 {
    let statm = std::fs::read_to_string("/proc/self/statm").unwrap_or_default();
    let pages: f64 = statm
        .split_whitespace()
        .nth(1)
        .and_then(|p| p.parse().ok())
        .unwrap_or(0.0);
    pages * 4096.0 / (1024.0 * 1024.0)
}

fn main() -> wgslam::Result<()> {
    let n: usize = std::env::args()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(500);
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/icl_living_room_kt2");
    let seq = dataset::open(&root, &SequenceOptions::default())?;
    let mut s = Slam::for_sequence(
        GpuBackend::open()?,
        &seq,
        ValidParams::profile(Profile::Robust),
    )?;
    for i in 1..=3 {
        let f = seq.load(i)?;
        s.process(
            i as u32,
            &f.depth,
            &packed_rgba(&f),
            seq.frames[i].gt_cam_to_world.as_ref(),
        )?;
    }
    let gt = se3::inverse_rigid(&seq.frames[3].gt_cam_to_world.expect("ground truth"));
    let pyramid = s.pyramid_levels();
    // A pose a few micrometres off for call k, so every call writes new values.
    let pose = |k: usize| se3::exp(&[0.0, 0.0, 0.0, 1e-6 * k as f64, 0.0, 0.0]) * gt;
    let before = rss_mib();
    for k in 0..n {
        s.backend.icp_system(0, &s.icp_params(0, &pose(k)))?;
    }
    let after_icp = rss_mib();
    for k in 0..n {
        s.backend.predict(&s.project_params(&pose(k)), &pyramid)?;
    }
    let after_predict = rss_mib();
    println!(
        "RSS: {before:.1} MiB; after {n} icp_system calls {after_icp:.1} MiB \
         ({:+.3} MiB per call); after {n} predict calls {after_predict:.1} MiB ({:+.3} MiB per call)",
        (after_icp - before) / n as f64,
        (after_predict - after_icp) / n as f64
    );
    Ok(())
}
