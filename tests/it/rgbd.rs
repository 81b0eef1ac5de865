//! RGB-D tracking (`icp.tracking = "rgbd"`, issue 34): the photometric term against the
//! real ground truth, on both backends. On the bundled noisy frames (clean colour,
//! Kinect-like depth noise) and on `../shared` noisy ICL-NUIM 1..200 at 640x480 the colour
//! holds the pose where the noisy depth lets it drift; every frame records its photometric
//! term. Measurements: `docs/rgbd-tracking.md`.

use crate::common;

use common::harness::{gpu, plain, shared, Test};
use common::{ate_m, bundled_icl_noisy, shared_icl_noisy};
use wgslam::dataset::{self, SequenceOptions};
use wgslam::gpu::GpuBackend;
use wgslam::slam::backend::{Backend, Inspect};
use wgslam::slam::cpu_backend::CpuBackend;
use wgslam::slam::params::{SlamParams, Tracking};
use wgslam::tools::run::{self, RunResult};

/// The bundled noisy frames 1..23, robust profile: measured (release and test builds, both
/// backends) 2.80 mm geometric and 2.25 mm with RGB-D tracking (the robust profile's raw
/// points; 2.45 and 2.12 mm with the filtered points before 2026-11-26); the bar is
/// halfway, so a photometric term that does not help fails.
const ATE_BUNDLED_NOISY_RGBD_MAX_M: f64 = 2.5e-3;
/// Noisy ICL-NUIM 1..200 at 640x480: measured 6.10 mm geometric and 1.66 mm with RGB-D
/// tracking (CPU, raw points; 7.60 and 3.45 mm with the filtered points); the issue asks
/// for 7.0 mm. 4 mm fails a term that gives back half the gain.
const ATE_NOISY_640_RGBD_MAX_M: f64 = 4.0e-3;

/// The robust profile with RGB-D tracking.
fn rgbd_params() -> SlamParams {
    let mut p = SlamParams::default();
    p.icp.tracking = Tracking::Rgbd;
    p
}

/// Every tracked frame's level-0 iterations carry the photometric term, with inliers.
fn every_frame_records_the_photometric_term(r: &RunResult) {
    for f in &r.frames[1..] {
        let level_0: Vec<_> = f
            .report
            .iterations
            .iter()
            .filter(|i| i.level == 0)
            .collect();
        assert!(
            !level_0.is_empty(),
            "frame {}: no level-0 iteration",
            f.index
        );
        for i in level_0 {
            let p = i.photometric.expect("a photometric term at level 0");
            assert!(
                p.inliers > 1000 && p.rms > 0.0,
                "frame {}: photometric {p:?}",
                f.index
            );
        }
    }
    let summary = r.metrics.tracking.photometric.as_ref().expect("summary");
    assert_eq!(summary.frames, r.frames.len() - 1);
}

/// RGB-D tracking on the bundled noisy frames beats the bar below geometric tracking's ATE.
fn bundled_noisy_frames_track_with_colour(backend: impl Backend + Inspect) {
    let seq = dataset::open(&bundled_icl_noisy(), &SequenceOptions::default()).unwrap();
    let r = run::run(
        backend,
        &seq,
        1,
        23,
        rgbd_params().validate().unwrap(),
        |_| {},
    )
    .unwrap();
    let ate = ate_m(&r);
    eprintln!(
        "bundled noisy frames, RGB-D tracking: ATE {:.3} mm",
        ate * 1e3
    );
    assert!(ate <= ATE_BUNDLED_NOISY_RGBD_MAX_M, "ATE {ate} m");
    assert_eq!(r.metrics.tracking.lost, 0);
    every_frame_records_the_photometric_term(&r);
}

/// Noisy ICL-NUIM 1..200 at 640x480 with RGB-D tracking: within the bar.
fn noisy_icl_640_tracks_with_colour(data: &std::path::Path) {
    let seq = dataset::open(&shared_icl_noisy(data), &SequenceOptions::default()).unwrap();
    let mut params = rgbd_params();
    params.input.downsample = 1;
    let r = common::run_cpu(&seq, 1, 200, params).unwrap();
    let ate = ate_m(&r);
    eprintln!(
        "noisy ICL-NUIM 1..200 at 640x480, RGB-D: ATE {:.3} mm",
        ate * 1e3
    );
    assert!(ate <= ATE_NOISY_640_RGBD_MAX_M, "ATE {ate} m");
    every_frame_records_the_photometric_term(&r);
}

pub fn tests() -> Vec<Test> {
    vec![
        plain("bundled_noisy_frames_track_with_colour_cpu", || {
            bundled_noisy_frames_track_with_colour(CpuBackend::new())
        }),
        gpu("bundled_noisy_frames_track_with_colour_gpu", |ctx| {
            bundled_noisy_frames_track_with_colour(GpuBackend::new(ctx).expect("GPU backend"))
        }),
        shared(
            "noisy_icl_640_tracks_with_colour_cpu",
            noisy_icl_640_tracks_with_colour,
        ),
    ]
}
