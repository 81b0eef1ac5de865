//! End-to-end dense SLAM on the GPU backend through the same runner as the CPU tests
//! (`run::run`), checked against the real ICL-NUIM ground truth. Skips with a printed
//! reason without a GPU adapter unless `WGSLAM_REQUIRE_GPU=1`.

mod common;

use wgslam::dataset::{self, SequenceOptions};
use wgslam::gpu::test_support::gpu_or_skip;
use wgslam::gpu::GpuBackend;
use wgslam::pipeline::SlamParams;
use wgslam::run;

/// The bar for frames 1..200 at downsample 2: ATE RMSE after rigid alignment.
const ATE_ALIGNED_MAX_M: f64 = 1e-3;
/// Over the 23 bundled frames a healthy tracker is at ~0.2 mm (CPU and GPU alike), so
/// 0.5 mm still catches a tracker that is off by a pixel's worth.
const ATE_BUNDLED_MAX_M: f64 = 0.5e-3;

#[test]
fn gpu_bundled_frames_track_to_ground_truth() {
    let Some(ctx) = gpu_or_skip("gpu_bundled_frames_track_to_ground_truth") else {
        return;
    };
    let seq = dataset::open(&common::bundled_icl(), &SequenceOptions::default()).unwrap();
    let last = seq.len() - 1;
    let backend = GpuBackend::new(ctx).unwrap();
    let r = run::run(backend, &seq, 1, last, SlamParams::default(), |_| {}).unwrap();
    let acc = r
        .metrics
        .accuracy
        .expect("the bundled frames have ground truth");
    eprintln!(
        "GPU bundled 1..{last}: ATE aligned {:.3} mm, unaligned {:.3} mm, RPE {:.3} mm; \
         {} surfels; median {:.1} ms/frame",
        acc.ate_rmse_aligned_m * 1e3,
        acc.ate_rmse_unaligned_m * 1e3,
        acc.rpe_trans_rmse_m * 1e3,
        r.map.len(),
        r.metrics.time_per_frame_median_s * 1e3
    );
    assert_eq!(acc.pairs, last);
    assert!(acc.ate_rmse_unaligned_m < ATE_BUNDLED_MAX_M, "{acc:?}");
    assert!(acc.ate_rmse_aligned_m < ATE_BUNDLED_MAX_M, "{acc:?}");
    assert_eq!(r.metrics.tracking.lost, 0);
    assert!(
        r.map.len() > 70_000,
        "a 320x240 frame alone adds ~70k surfels"
    );
}

/// The headline figure on the GPU: frames 1..200 at downsample 2 within 1 mm ATE.
#[test]
fn gpu_shared_sequence_1_to_200_within_1mm() {
    let Some(root) = common::shared_icl() else {
        return;
    };
    let Some(ctx) = gpu_or_skip("gpu_shared_sequence_1_to_200_within_1mm") else {
        return;
    };
    let seq = dataset::open(&root, &SequenceOptions::default()).unwrap();
    let backend = GpuBackend::new(ctx).unwrap();
    let r = run::run(backend, &seq, 1, 200, SlamParams::default(), |_| {}).unwrap();
    let acc = r.metrics.accuracy.unwrap();
    eprintln!(
        "GPU 1..200: ATE aligned {:.3} mm, unaligned {:.3} mm; {} surfels; median {:.1} ms/frame",
        acc.ate_rmse_aligned_m * 1e3,
        acc.ate_rmse_unaligned_m * 1e3,
        r.map.len(),
        r.metrics.time_per_frame_median_s * 1e3
    );
    assert!(acc.ate_rmse_aligned_m < ATE_ALIGNED_MAX_M, "{acc:?}");
    assert_eq!(r.metrics.tracking.lost, 0);
}

/// The interleaved benchmark runs both backends over the same frames, each tracking to the
/// ground truth, and reports ordered per-frame ratios.
#[test]
fn interleaved_bench_tracks_both_backends() {
    let Some(ctx) = gpu_or_skip("interleaved_bench_tracks_both_backends") else {
        return;
    };
    let seq = dataset::open(&common::bundled_icl(), &SequenceOptions::default()).unwrap();
    let backend = GpuBackend::new(ctx).unwrap();
    let r = wgslam::bench::bench_interleaved(backend, &seq, 1, 6, &SlamParams::default()).unwrap();
    eprintln!("{r:?}");
    assert_eq!((r.frames, r.width, r.height), (6, 320, 240));
    for ate in [r.cpu_ate_rmse_aligned_m, r.gpu_ate_rmse_aligned_m] {
        assert!(ate.expect("ground truth") < ATE_BUNDLED_MAX_M, "{r:?}");
    }
    assert!(r.cpu_frame_mean_s > 0.0 && r.gpu_frame_mean_s > 0.0);
    assert!(0.0 < r.ratio_p10 && r.ratio_p10 <= r.ratio_median && r.ratio_median <= r.ratio_p90);
}
