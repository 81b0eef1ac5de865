//! A whole tracked run over the bundled frames on both backends, and the GPU's against the
//! ground truth.

use super::{root, slam};
use super::{GT_RMSE_MAX_M, RUN_POSE_TOL_DEG, RUN_POSE_TOL_M, RUN_SURFEL_FRACTION_TOL};
use crate::common::frames::{gt_at, load_frame, load_gt};
use crate::common::harness::{gpu_backend_test, Test};
use wgslam::geometry::se3;
use wgslam::gpu::GpuBackend;
use wgslam::slam::backend::{Backend, Inspect};
use wgslam::slam::cpu_backend::CpuBackend;
use wgslam::slam::params::{Profile, SlamParams};
use wgslam::slam::pipeline::TrackStatus;

/// Tracks the bundled frames 1..=N on both backends: same statuses, poses within
/// RUN_POSE_TOL, surfel counts within RUN_SURFEL_FRACTION_TOL, and the GPU poses within
/// GT_RMSE_MAX_M of the ground truth.
fn tracked_run_matches_cpu_and_ground_truth(gpu: GpuBackend) {
    let gt = load_gt(&root());
    let last = gt.len() - 1;
    assert!(
        last >= 20,
        "at least 20 frames with ground truth are bundled"
    );
    let mut c = slam(CpuBackend::new(), SlamParams::profile(Profile::Assignment));
    let mut g = slam(gpu, SlamParams::profile(Profile::Assignment));
    let (mut sq_err, mut worst_m, mut worst_deg) = (0.0, 0.0f64, 0.0f64);
    let t0 = std::time::Instant::now();
    let (mut t_cpu, mut t_gpu) = (0.0, 0.0);
    for i in 1..=last {
        let f = load_frame(&root(), i);
        let t = std::time::Instant::now();
        let rc = c
            .process(i as u32, &f.depth, &f.rgba, gt_at(&gt, i))
            .unwrap();
        t_cpu += t.elapsed().as_secs_f64();
        let t = std::time::Instant::now();
        let rg = g
            .process(i as u32, &f.depth, &f.rgba, gt_at(&gt, i))
            .unwrap();
        t_gpu += t.elapsed().as_secs_f64();
        assert!(
            !matches!(rg.status, TrackStatus::Lost(_) | TrackStatus::EmptyDepth),
            "frame {i}: GPU {:?}",
            rg.status
        );
        let d = se3::inverse_rigid(&rc.t_cam_to_world) * rg.t_cam_to_world;
        let (dm, ddeg) = (
            se3::translation_norm(&d),
            se3::rotation_angle(&d).to_degrees(),
        );
        worst_m = worst_m.max(dm);
        worst_deg = worst_deg.max(ddeg);
        let e = se3::inverse_rigid(gt_at(&gt, i).unwrap()) * rg.t_cam_to_world;
        sq_err += se3::translation_norm(&e).powi(2);
        // The maps each frame was tracked against (0 at the first).
        let (sc, sg) = (rc.surfels_before, rg.surfels_before);
        let ds = sc.abs_diff(sg) as f64 / sc.max(1) as f64;
        assert!(
            dm <= RUN_POSE_TOL_M && ddeg <= RUN_POSE_TOL_DEG,
            "frame {i}: poses differ by {:.4} mm / {ddeg:.5} deg",
            dm * 1e3
        );
        assert!(
            ds <= RUN_SURFEL_FRACTION_TOL,
            "frame {i}: surfels cpu {sc} gpu {sg}"
        );
    }
    let rmse = (sq_err / last as f64).sqrt();
    let counters = g.backend.counters();
    eprintln!(
        "{last} frames in {:.1} s (cpu {t_cpu:.2} s, gpu {t_gpu:.2} s): backends differ by at \
         most {:.4} mm / {worst_deg:.5} deg; GPU translation RMSE vs ground truth {:.3} mm; \
         {} surfels; GPU read back {} bytes in {} submissions",
        t0.elapsed().as_secs_f64(),
        worst_m * 1e3,
        rmse * 1e3,
        g.backend.surfel_count().unwrap(),
        counters.readback_bytes,
        counters.submissions
    );
    assert!(rmse < GT_RMSE_MAX_M, "GPU RMSE {:.3} mm", rmse * 1e3);
}

pub(super) fn tests() -> Vec<Test> {
    vec![gpu_backend_test(
        "tracked_run_matches_cpu_and_ground_truth",
        tracked_run_matches_cpu_and_ground_truth,
    )]
}
