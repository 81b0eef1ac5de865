//! End-to-end dense SLAM on real ICL-NUIM frames through the batch runner (`run::run`),
//! checked against the real ground truth. The bundled-frame and full-sequence bodies run
//! once per backend (CPU reference, GPU); the other checks are on the CPU reference, and
//! the interleaved benchmark runs both backends in one trial. GPU trials show as ignored
//! without an adapter, full-sequence trials without `../shared/data` (tests/it/common/harness.rs).

use crate::common;

use std::path::Path;

use common::harness::{gpu, gpu_backend, gpu_backend_test, gpu_shared, plain, shared};
use wgslam::dataset::{self, SequenceOptions};
use wgslam::gpu::{GpuBackend, GpuContext};
use wgslam::slam::backend::{Backend, Inspect};
use wgslam::slam::cpu_backend::CpuBackend;
use wgslam::slam::params::{
    BilateralSettings, PoseSource, Profile, SlamParams, UnstableRemoval, ValidParams,
};
use wgslam::slam::pipeline::TrackStatus;
use wgslam::slam::solve::LevelStop;
use wgslam::tools::run;

/// The issue's bar for frames 1..200 at downsample 2: ATE RMSE after rigid alignment.
const ATE_ALIGNED_MAX_M: f64 = 1e-3;
/// Over the 23 bundled frames drift has little time to build up; a healthy tracker is at
/// ~0.2 mm here (CPU and GPU alike), so 0.5 mm still catches a tracker that is off by a
/// pixel's worth.
const ATE_BUNDLED_MAX_M: f64 = 0.5e-3;
/// The robust profile on the 23 bundled noisy frames: measured 2.80 mm ATE aligned on both
/// backends (2.45 mm with the filtered points before 2026-11-26; the assignment's profile:
/// 11.6 mm); 5 mm is about twice the measurement and still fails a tracker that drifts like
/// the assignment's.
const ATE_BUNDLED_NOISY_MAX_M: f64 = 5e-3;
/// The issue's bar for noisy frames 1..200 at 320x240 (robust profile; measured 5.54 mm
/// CPU and 5.51 mm GPU with raw points, 6.50 mm with the filtered ones; the assignment's
/// profile 204 mm; Open3D's TSDF pipeline 38 mm).
const ATE_NOISY_320_MAX_M: f64 = 15e-3;
/// Issue 34's bar for noisy frames 1..200 at 640x480 with the default (geometric)
/// tracking: measured 6.10 mm with the robust profile's raw points, 7.60 mm with the
/// filtered points (`bilateral.filter_points`), which this bar fails.
const ATE_NOISY_640_MAX_M: f64 = 7.0e-3;
/// Map size on noisy frames 1..200 as a fraction of all pixels fused: measured 0.0076 on
/// the CPU with raw points (0.0064 with the filtered points, 0.0077 before pruning;
/// best-candidate fusion with the removal of unstable surfels; projective fusion 0.018,
/// the assignment's profile 0.41). The issue's target is 0.02; 0.012 is 1.6x the
/// measurement and fails projective fusion.
const NOISY_MAP_FRACTION_MAX: f64 = 0.012;

pub fn tests() -> Vec<common::harness::Test> {
    vec![
        plain("bundled_frames_track_to_ground_truth", || {
            bundled_frames_track_to_ground_truth(
                CpuBackend::new(),
                SlamParams::profile(Profile::Assignment),
            )
        }),
        gpu("gpu_bundled_frames_track_to_ground_truth", |ctx| {
            bundled_frames_track_to_ground_truth(
                gpu_backend(ctx),
                SlamParams::profile(Profile::Assignment),
            )
        }),
        plain("bundled_frames_track_with_the_bilateral_filter", || {
            bundled_frames_track_to_ground_truth(CpuBackend::new(), with_bilateral())
        }),
        gpu(
            "gpu_bundled_frames_track_with_the_bilateral_filter",
            |ctx| bundled_frames_track_to_ground_truth(gpu_backend(ctx), with_bilateral()),
        ),
        plain("full_resolution_tracks_too", full_resolution_tracks_too),
        plain(
            "ground_truth_poses_fuse_without_tracking",
            ground_truth_poses_fuse_without_tracking,
        ),
        plain("frame_without_ground_truth", frame_without_ground_truth),
        shared("shared_sequence_1_to_200_within_1mm", |data| {
            shared_sequence_1_to_200_within_1mm(CpuBackend::new(), data)
        }),
        gpu_shared("gpu_shared_sequence_1_to_200_within_1mm", |ctx, data| {
            shared_sequence_1_to_200_within_1mm(gpu_backend(ctx), data)
        }),
        plain("robust_profile_tracks_bundled_noisy_frames", || {
            robust_profile_tracks_bundled_noisy_frames(CpuBackend::new())
        }),
        gpu_backend_test(
            "gpu_robust_profile_tracks_bundled_noisy_frames",
            robust_profile_tracks_bundled_noisy_frames,
        ),
        plain("robust_icp_runs_coarse_to_fine", || {
            robust_icp_runs_coarse_to_fine(CpuBackend::new())
        }),
        gpu_backend_test(
            "gpu_robust_icp_runs_coarse_to_fine",
            robust_icp_runs_coarse_to_fine,
        ),
        plain("removal_shrinks_the_bundled_noisy_map", || {
            removal_shrinks_the_bundled_noisy_map(CpuBackend::new(), CpuBackend::new())
        }),
        gpu("gpu_removal_shrinks_the_bundled_noisy_map", |ctx| {
            let off = GpuBackend::open().expect("a second GPU backend");
            removal_shrinks_the_bundled_noisy_map(gpu_backend(ctx), off)
        }),
        plain(
            "robust_profile_tracks_clean_frames_too",
            robust_profile_tracks_clean_frames_too,
        ),
        shared("shared_noisy_1_to_200_robust_within_15mm", |data| {
            shared_noisy_1_to_200_robust_within_15mm(CpuBackend::new(), data)
        }),
        shared(
            "shared_noisy_640_default_within_issue_bar",
            shared_noisy_640_default_within_issue_bar,
        ),
        gpu_shared(
            "gpu_shared_noisy_1_to_200_robust_within_15mm",
            |ctx, data| shared_noisy_1_to_200_robust_within_15mm(gpu_backend(ctx), data),
        ),
        plain(
            "empty_and_untrackable_frames_are_reported_not_fused",
            empty_and_untrackable_frames_are_reported_not_fused,
        ),
        gpu(
            "interleaved_bench_tracks_both_backends",
            interleaved_bench_tracks_both_backends,
        ),
    ]
}

/// The default parameters with the bilateral depth filter on, at its defaults.
fn with_bilateral() -> SlamParams {
    SlamParams {
        bilateral: Some(BilateralSettings::default()),
        ..SlamParams::profile(Profile::Assignment)
    }
}

/// The 23 bundled frames (1..=23) on `backend` with `params`: within [`ATE_BUNDLED_MAX_M`]
/// of the ground truth with and without alignment, no frame lost, a map of a plausible size.
/// With the bilateral filter on, the clean frames must track as well as without it.
fn bundled_frames_track_to_ground_truth<B: Backend + Inspect>(backend: B, params: SlamParams) {
    let name = format!(
        "{}{}",
        backend.name(),
        if params.bilateral.is_some() {
            " (bilateral)"
        } else {
            ""
        }
    );
    let seq = common::open_asset("icl_living_room_kt2");
    let last = seq.len() - 1;
    let r = run::run(backend, &seq, 1, last, params.validate().unwrap(), |_| {}).unwrap();
    let acc = r
        .metrics
        .accuracy
        .expect("the bundled frames have ground truth");
    eprintln!(
        "{name} bundled 1..{last}: ATE aligned {:.3} mm, unaligned {:.3} mm, RPE {:.3} mm; \
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

fn full_resolution_tracks_too() {
    let seq = common::open_asset("icl_living_room_kt2");
    let mut params = SlamParams::profile(Profile::Assignment);
    params.input.downsample = 1;
    let r = common::run_cpu(&seq, 1, 8, params).unwrap();
    let acc = r.metrics.accuracy.unwrap();
    assert!(acc.ate_rmse_unaligned_m < ATE_BUNDLED_MAX_M, "{acc:?}");
    assert_eq!(r.metrics.width, 640);
}

fn ground_truth_poses_fuse_without_tracking() {
    let seq = common::open_asset("icl_living_room_kt2");
    let params = SlamParams {
        poses: PoseSource::GroundTruth,
        ..SlamParams::profile(Profile::Assignment)
    };
    let r = common::run_cpu(&seq, 1, 10, params).unwrap();
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
fn frame_without_ground_truth() {
    let seq = common::open_asset("icl_living_room_kt2");
    let r = common::run_cpu(&seq, 0, 2, wgslam::SlamParams::profile(Profile::Assignment)).unwrap();
    assert_eq!(r.frames[0].report.t_cam_to_world, glam::DMat4::IDENTITY);
    let params = SlamParams {
        poses: PoseSource::GroundTruth,
        ..SlamParams::profile(Profile::Assignment)
    };
    let err = common::run_cpu(&seq, 0, 2, params).unwrap_err();
    assert!(err.to_string().contains("ground truth"), "{err}");
}

/// The issue's headline figure on `backend`: frames 1..200 of the full sequence in
/// `../shared/data` at downsample 2 within 1 mm ATE, no frame lost.
fn shared_sequence_1_to_200_within_1mm<B: Backend + Inspect>(backend: B, data: &Path) {
    let name = backend.name();
    let seq = dataset::open(&common::shared_icl(data), &SequenceOptions::default()).unwrap();
    let r = run::run(
        backend,
        &seq,
        1,
        200,
        ValidParams::profile(Profile::Assignment),
        |_| {},
    )
    .unwrap();
    let acc = r.metrics.accuracy.unwrap();
    eprintln!(
        "{name} 1..200: ATE aligned {:.3} mm, unaligned {:.3} mm; {} surfels; median {:.1} ms/frame",
        acc.ate_rmse_aligned_m * 1e3,
        acc.ate_rmse_unaligned_m * 1e3,
        r.map.len(),
        r.metrics.time_per_frame_median_s * 1e3
    );
    assert!(acc.ate_rmse_aligned_m < ATE_ALIGNED_MAX_M, "{acc:?}");
    assert_eq!(r.metrics.tracking.lost, 0);
}

/// A frame whose depth is all invalid is reported and skipped; a frame with too little
/// valid depth to constrain ICP is reported as lost and not fused; tracking then resumes.
fn empty_and_untrackable_frames_are_reported_not_fused() {
    use wgslam::slam::pipeline::Slam;
    let seq = common::open_asset("icl_living_room_kt2");
    let mut slam = Slam::new(
        CpuBackend::new(),
        seq.intrinsics,
        ValidParams::profile(Profile::Assignment),
    );
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
    assert_eq!(r.surfels_before, surfels, "the map frame 1 left");
    let after = slam.backend.surfel_count().unwrap();
    assert_eq!(after, surfels, "an empty frame adds nothing");

    // Keep 40 scattered valid pixels: fewer correspondences than solve::MIN_INLIERS.
    let mut sparse = vec![0u16; d1.len()];
    for k in 0..40 {
        let i = 1000 + k * 7001;
        sparse[i] = d1[i];
    }
    let r = slam.process(3, &sparse, &c1, None).unwrap();
    assert!(matches!(r.status, TrackStatus::Lost(_)), "{:?}", r.status);
    assert_eq!(r.surfels_before, surfels, "the map an empty frame left");
    let after = slam.backend.surfel_count().unwrap();
    assert_eq!(after, surfels, "a lost frame is not fused");
    assert_eq!(r.t_cam_to_world, gt1.unwrap(), "the previous pose is kept");

    let (d4, c4) = load(4);
    let r = slam.process(4, &d4, &c4, None).unwrap();
    assert_eq!(r.status, TrackStatus::Converged);
    let err = (r.t_cam_to_world.w_axis - seq.frames[4].gt_cam_to_world.unwrap().w_axis)
        .truncate()
        .length();
    assert!(err < ATE_BUNDLED_MAX_M, "tracking resumes: {err} m off");
}

/// The interleaved benchmark runs both backends over the same frames, each tracking to the
/// ground truth, and reports ordered per-frame ratios.
fn interleaved_bench_tracks_both_backends(ctx: GpuContext) {
    let seq = common::open_asset("icl_living_room_kt2");
    let r = wgslam::tools::bench::bench_interleaved(
        gpu_backend(ctx),
        &seq,
        1,
        6,
        &ValidParams::profile(Profile::Assignment),
    )
    .unwrap();
    eprintln!("{r:?}");
    assert_eq!((r.frames, r.width, r.height), (6, 320, 240));
    for ate in [r.cpu_ate_rmse_aligned_m, r.gpu_ate_rmse_aligned_m] {
        assert!(ate.expect("ground truth") < ATE_BUNDLED_MAX_M, "{r:?}");
    }
    assert!(r.cpu_frame_mean_s > 0.0 && r.gpu_frame_mean_s > 0.0);
    let q = &r.ratios;
    assert!(0.0 < q.p10 && q.p10 <= q.median && q.median <= q.p90);
}

/// Runs `backend` over frames `first..=last` of `dir` with `params`; returns the aligned
/// ATE (metres) and the map's size as a fraction of all pixels fused.
fn ate_and_map_fraction<B: Backend + Inspect>(
    backend: B,
    dir: &Path,
    first: usize,
    last: usize,
    params: SlamParams,
) -> (f64, f64) {
    let name = backend.name();
    let seq = dataset::open(dir, &SequenceOptions::default()).unwrap();
    let r = run::run(
        backend,
        &seq,
        first,
        last,
        params.validate().unwrap(),
        |_| {},
    )
    .unwrap();
    let acc = r.metrics.accuracy.expect("ground truth");
    eprintln!(
        "{name} {} {first}..{last} ({:?}): ATE aligned {:.3} mm, unaligned {:.3} mm; map {} \
         surfels ({:.4} of all pixels); lost {}",
        dir.display(),
        r.metrics.params.profile,
        acc.ate_rmse_aligned_m * 1e3,
        acc.ate_rmse_unaligned_m * 1e3,
        r.map.len(),
        r.metrics.compression_ratio,
        r.metrics.tracking.lost
    );
    assert_eq!(r.metrics.tracking.lost, 0, "{name}: no frame may be lost");
    (acc.ate_rmse_aligned_m, r.metrics.compression_ratio)
}

/// The robust profile holds on the bundled noisy frames, where the assignment's drifts.
fn robust_profile_tracks_bundled_noisy_frames<B: Backend + Inspect>(backend: B) {
    let dir = common::bundled_icl_noisy();
    let robust = SlamParams::profile(Profile::Robust);
    let (ate, _) = ate_and_map_fraction(backend, &dir, 1, 23, robust);
    assert_ate_within(ate, ATE_BUNDLED_NOISY_MAX_M, "robust ATE on noisy frames");
}

/// The robust profile tracks with its pyramid: every tracked frame's iterations run from
/// the coarsest level to level 0, never more at a level than its budget, and the status is
/// level 0's; a one-level schedule runs at level 0 only.
fn robust_icp_runs_coarse_to_fine<B: Backend + Inspect>(backend: B) {
    let seq = dataset::open(&common::bundled_icl_noisy(), &SequenceOptions::default()).unwrap();
    let robust = SlamParams::profile(Profile::Robust);
    let schedule = robust.icp.level_iters.clone();
    assert!(schedule.len() > 1, "the robust profile has a pyramid");
    let r = run::run(backend, &seq, 1, 6, robust.validate().unwrap(), |_| {}).unwrap();
    for f in &r.frames[1..] {
        let levels: Vec<usize> = f.report.iterations.iter().map(|it| it.level).collect();
        assert_eq!(
            levels.first(),
            Some(&(schedule.len() - 1)),
            "frame {}",
            f.index
        );
        assert_eq!(levels.last(), Some(&0), "frame {}", f.index);
        assert!(
            levels.windows(2).all(|w| w[0] >= w[1]),
            "frame {}: {levels:?}",
            f.index
        );
        for (i, &budget) in schedule.iter().enumerate() {
            let level = schedule.len() - 1 - i;
            let n = levels.iter().filter(|&&l| l == level).count();
            assert!((1..=budget).contains(&n), "frame {}: {levels:?}", f.index);
        }
        // Every level's last iteration, and only it, says why the level stopped.
        let its = &f.report.iterations;
        for (k, it) in its.iter().enumerate() {
            let last_of_level = its.get(k + 1).is_none_or(|next| next.level != it.level);
            assert_eq!(
                it.stop.is_some(),
                last_of_level,
                "frame {}: {its:?}",
                f.index
            );
        }
        let finest_stop = its.last().and_then(|it| it.stop);
        assert_eq!(
            finest_stop == Some(LevelStop::Budget),
            f.report.status == TrackStatus::MaxIterations,
            "frame {}: {finest_stop:?} {:?}",
            f.index,
            f.report.status
        );
        let at_0 = levels.iter().filter(|&&l| l == 0).count();
        match f.report.status {
            TrackStatus::Converged => {}
            TrackStatus::MaxIterations => assert_eq!(at_0, schedule[schedule.len() - 1]),
            ref other => panic!("frame {}: {other:?}", f.index),
        }
    }
    let acc = r.metrics.accuracy.expect("ground truth");
    assert!(acc.ate_rmse_aligned_m < ATE_BUNDLED_NOISY_MAX_M, "{acc:?}");
    assert_eq!(r.metrics.params.icp.level_iters, schedule);
}

/// The robust profile's removal of unstable surfels on the bundled noisy frames: the ATE
/// bound still holds, and the map is smaller than with the rule off (same backend). The
/// profile's 20-frame age limit and 10-frame cadence leave nothing old enough in 23
/// frames, so the rule runs here after every frame with a 5-frame age limit.
fn removal_shrinks_the_bundled_noisy_map<B: Backend + Inspect>(on: B, off: B) {
    let dir = common::bundled_icl_noisy();
    let profile = SlamParams::profile(Profile::Robust);
    assert!(
        profile.fusion.unstable_removal.is_some(),
        "the robust profile removes"
    );
    let mut robust = profile;
    robust.fusion.unstable_removal = Some(UnstableRemoval {
        max_age_frames: 5,
        every_frames: 1,
        ..UnstableRemoval::default()
    });
    let mut without = robust.clone();
    without.fusion.unstable_removal = None;
    let (ate, fraction_on) = ate_and_map_fraction(on, &dir, 1, 23, robust);
    let (_, fraction_off) = ate_and_map_fraction(off, &dir, 1, 23, without);
    assert_ate_within(
        ate,
        ATE_BUNDLED_NOISY_MAX_M,
        "robust ATE on noisy frames with removal",
    );
    assert!(
        fraction_on < fraction_off,
        "removal must shrink the map: {fraction_on:.4} with, {fraction_off:.4} without"
    );
}

/// The robust profile on clean frames: as good as the assignment's (which is exact there).
fn robust_profile_tracks_clean_frames_too() {
    let robust = SlamParams::profile(Profile::Robust);
    let (ate, _) = ate_and_map_fraction(CpuBackend::new(), &common::bundled_icl(), 1, 23, robust);
    assert_ate_within(ate, ATE_BUNDLED_MAX_M, "robust ATE on clean frames");
}

/// The issue's bar on the full noisy sequence at 320x240.
fn shared_noisy_1_to_200_robust_within_15mm<B: Backend + Inspect>(backend: B, data: &Path) {
    let dir = common::shared_icl_noisy(data);
    let robust = SlamParams::profile(Profile::Robust);
    let (ate, map_fraction) = ate_and_map_fraction(backend, &dir, 1, 200, robust);
    assert_ate_within(ate, ATE_NOISY_320_MAX_M, "robust ATE on noisy 1..200");
    assert!(
        map_fraction < NOISY_MAP_FRACTION_MAX,
        "robust map {map_fraction:.4} of all pixels on noisy 1..200"
    );
}

/// The default (robust profile, geometric tracking) on noisy frames 1..200 at 640x480
/// meets issue 34's bar (CPU; the GPU's pose agrees within 0.03 mm at 320x240).
fn shared_noisy_640_default_within_issue_bar(data: &Path) {
    let dir = common::shared_icl_noisy(data);
    let mut robust = SlamParams::profile(Profile::Robust);
    robust.input.downsample = 1;
    let (ate, _) = ate_and_map_fraction(CpuBackend::new(), &dir, 1, 200, robust);
    assert_ate_within(
        ate,
        ATE_NOISY_640_MAX_M,
        "default ATE on noisy 1..200 at 640x480",
    );
}

/// `ate_m` (metres) is within the bar `max_m`; `what` says which run (printed with the ATE
/// in millimetres when it is not).
fn assert_ate_within(ate_m: f64, max_m: f64, what: &str) {
    assert!(
        ate_m <= max_m,
        "{what}: {:.3} mm over {:.1} mm",
        ate_m * 1e3,
        max_m * 1e3
    );
}
