//! End-to-end dense SLAM on real ICL-NUIM frames, checked against the real ground truth.

mod common;

use wgslam::cpu_backend::CpuBackend;
use wgslam::dataset::{self, SequenceOptions};
use wgslam::pipeline::{PoseSource, SlamParams, TrackStatus};
use wgslam::run;

/// The bar for frames 1..200 at downsample 2: ATE RMSE after rigid alignment.
const ATE_ALIGNED_MAX_M: f64 = 1e-3;
/// Over the 23 bundled frames drift has little time to build up; a healthy tracker is at
/// ~0.2 mm here, so 0.5 mm still catches a tracker that is off by a pixel's worth.
const ATE_BUNDLED_MAX_M: f64 = 0.5e-3;

#[test]
fn bundled_frames_track_to_ground_truth() {
    let seq = dataset::open(&common::bundled_icl(), &SequenceOptions::default()).unwrap();
    let last = seq.len() - 1;
    let r = run::run(
        CpuBackend::new(),
        &seq,
        1,
        last,
        SlamParams::default(),
        |_| {},
    )
    .unwrap();
    let acc = r
        .metrics
        .accuracy
        .expect("the bundled frames have ground truth");
    eprintln!(
        "bundled 1..{last}: ATE aligned {:.3} mm, unaligned {:.3} mm, RPE {:.3} mm",
        acc.ate_rmse_aligned_m * 1e3,
        acc.ate_rmse_unaligned_m * 1e3,
        acc.rpe_trans_rmse_m * 1e3
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

#[test]
fn full_resolution_tracks_too() {
    let seq = dataset::open(&common::bundled_icl(), &SequenceOptions::default()).unwrap();
    let params = SlamParams {
        downsample: 1,
        ..SlamParams::default()
    };
    let r = run::run(CpuBackend::new(), &seq, 1, 8, params, |_| {}).unwrap();
    let acc = r.metrics.accuracy.unwrap();
    assert!(acc.ate_rmse_unaligned_m < ATE_BUNDLED_MAX_M, "{acc:?}");
    assert_eq!(r.metrics.width, 640);
}

#[test]
fn ground_truth_poses_fuse_without_tracking() {
    let seq = dataset::open(&common::bundled_icl(), &SequenceOptions::default()).unwrap();
    let params = SlamParams {
        poses: PoseSource::GroundTruth,
        ..SlamParams::default()
    };
    let r = run::run(CpuBackend::new(), &seq, 1, 10, params, |_| {}).unwrap();
    assert!(r
        .frames
        .iter()
        .all(|f| f.report.status == TrackStatus::Given));
    let acc = r.metrics.accuracy.unwrap();
    assert!(
        acc.ate_rmse_unaligned_m < 1e-9,
        "GT poses are returned unchanged"
    );
    // Later frames mostly merge into the map instead of duplicating it.
    let per_frame = r.map.len() as f64 / 10.0;
    assert!(per_frame < 0.5 * 76_800.0, "{per_frame} surfels per frame");
}

/// Frame 0 of ICL-NUIM has no ground truth: tracking without GT starts at identity, and
/// a ground-truth run refuses it with a clear error.
#[test]
fn frame_without_ground_truth() {
    let seq = dataset::open(&common::bundled_icl(), &SequenceOptions::default()).unwrap();
    let r = run::run(CpuBackend::new(), &seq, 0, 2, SlamParams::default(), |_| {}).unwrap();
    assert_eq!(r.frames[0].report.t_cam_to_world, glam::DMat4::IDENTITY);
    let params = SlamParams {
        poses: PoseSource::GroundTruth,
        ..SlamParams::default()
    };
    let err = run::run(CpuBackend::new(), &seq, 0, 2, params, |_| {}).unwrap_err();
    assert!(err.to_string().contains("ground truth"), "{err}");
}

/// The headline figure: frames 1..200 at downsample 2 within 1 mm ATE.
#[test]
fn shared_sequence_1_to_200_within_1mm() {
    let Some(root) = common::shared_icl() else {
        return;
    };
    let seq = dataset::open(&root, &SequenceOptions::default()).unwrap();
    let r = run::run(
        CpuBackend::new(),
        &seq,
        1,
        200,
        SlamParams::default(),
        |_| {},
    )
    .unwrap();
    let acc = r.metrics.accuracy.unwrap();
    eprintln!(
        "1..200: ATE aligned {:.3} mm, unaligned {:.3} mm; {} surfels",
        acc.ate_rmse_aligned_m * 1e3,
        acc.ate_rmse_unaligned_m * 1e3,
        r.map.len()
    );
    assert!(acc.ate_rmse_aligned_m < ATE_ALIGNED_MAX_M, "{acc:?}");
}

/// A frame whose depth is all invalid is reported and skipped; a frame with too little
/// valid depth to constrain ICP is reported as lost and not fused; tracking then resumes.
#[test]
fn empty_and_untrackable_frames_are_reported_not_fused() {
    use wgslam::pipeline::Slam;
    let seq = dataset::open(&common::bundled_icl(), &SequenceOptions::default()).unwrap();
    let mut slam = Slam::new(CpuBackend::new(), seq.intrinsics, SlamParams::default());
    let load = |i: usize| {
        let f = seq.load(i).unwrap();
        let c = run::packed_rgba(&f);
        (f.depth, c)
    };
    let (d1, c1) = load(1);
    let gt1 = seq.frames[1].gt_cam_to_world;
    slam.process(1, &d1, &c1, gt1.as_ref()).unwrap();
    let surfels = slam.backend.map().len();

    let empty = vec![0u16; d1.len()];
    let r = slam.process(2, &empty, &c1, None).unwrap();
    assert_eq!(r.status, TrackStatus::EmptyDepth);
    assert_eq!(r.surfels, surfels, "an empty frame adds nothing");

    // Keep 40 scattered valid pixels: fewer correspondences than solve::MIN_INLIERS.
    let mut sparse = vec![0u16; d1.len()];
    for k in 0..40 {
        let i = 1000 + k * 7001;
        sparse[i] = d1[i];
    }
    let r = slam.process(3, &sparse, &c1, None).unwrap();
    assert!(matches!(r.status, TrackStatus::Lost(_)), "{:?}", r.status);
    assert_eq!(r.surfels, surfels, "a lost frame is not fused");
    assert_eq!(r.t_cam_to_world, gt1.unwrap(), "the previous pose is kept");

    let (d4, c4) = load(4);
    let r = slam.process(4, &d4, &c4, None).unwrap();
    assert_eq!(r.status, TrackStatus::Converged);
    let err = (r.t_cam_to_world.w_axis - seq.frames[4].gt_cam_to_world.unwrap().w_axis)
        .truncate()
        .length();
    assert!(err < ATE_BUNDLED_MAX_M, "tracking resumes: {err} m off");
}
