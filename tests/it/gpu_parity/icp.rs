//! Tracking's normal equations: icp_reduce and icp_reduce_final against their twins, at
//! level 0 and on the coarser pyramid levels; photo_reduce's photometric system beside
//! icp_reduce's (`rgbd_system`); icp_candidates (the health test's
//! denominator) against its twin.

use super::{check_count, cpu_map_from_gt, preprocess_both, robust_pyramids_on_both, root};
use super::{increment_tol, INLIER_FRACTION_TOL, MASK_MISMATCH_FRACTION, SYSTEM_REL_TOL};
use crate::common::frames::{gt_at, load_frame};
use crate::common::harness::{gpu, gpu_backend_test, Test};
use crate::common::unfiltered_level_0;
use glam::DMat4;
use wgslam::cpu;
use wgslam::geometry::camera::Intrinsics;
use wgslam::geometry::se3;
use wgslam::gpu::{GpuBackend, GpuContext};
use wgslam::layout::ICP_SYSTEM_LEN;
use wgslam::slam::backend::{Backend, Inspect};
use wgslam::slam::cpu_backend::CpuBackend;
use wgslam::slam::params::{Profile, SlamParams, ValidParams};
use wgslam::slam::pipeline::Slam;
use wgslam::slam::solve::NormalEquations;
use wgslam::tools::compare::system_rel_diffs;
use wgslam::Error;

/// Both backends with a map fused from ground truth over frames 0..3, frame 4
/// preprocessed and the map predicted from frame 3's pose: the ICP of frame 4; with frame
/// 4's true world-to-camera pose.
fn frame_4_on_both(gpu: &mut GpuBackend, profile: Profile) -> (Slam<CpuBackend>, DMat4) {
    let params = SlamParams::profile(profile);
    let (mut s, gt) = cpu_map_from_gt(3, &params);
    gpu.upload_map(&s.backend.download_map().unwrap()).unwrap();
    let frame = load_frame(&root(), 4);
    let steps = unfiltered_level_0(&s);
    preprocess_both(&mut s.backend, gpu, &steps, &frame);
    let t_prev = se3::inverse_rigid(gt_at(&gt, 3).unwrap());
    let proj = s.project_params(&t_prev);
    s.backend.predict(&proj, &[]).unwrap();
    gpu.predict(&proj, &[]).unwrap();
    (s, se3::inverse_rigid(gt_at(&gt, 4).unwrap()))
}

/// A small pose error off frame 4's true pose to track from.
fn nudge() -> DMat4 {
    se3::exp(&[0.002, -0.001, 0.003, 0.004, 0.002, -0.003])
}

/// The CPU's and the GPU's 29-float systems of one case agree: inliers, the decoded AᵀA and
/// Aᵀb (the measure `wgslam compare` uses) and the solved increments.
fn check_systems(label: &str, sys_c: &[f64; ICP_SYSTEM_LEN], sys_g: &[f64; ICP_SYSTEM_LEN]) {
    check_systems_of(label, sys_c, sys_g, 10_000, 0);
}

/// [`check_systems`] with at least `min_inliers` on the CPU (a coarse level has fewer
/// pixels), at pyramid level `level` (its increment tolerance, [`increment_tol`]).
fn check_systems_of(
    label: &str,
    sys_c: &[f64; ICP_SYSTEM_LEN],
    sys_g: &[f64; ICP_SYSTEM_LEN],
    min_inliers: u64,
    level: usize,
) {
    let (c, g) = (
        NormalEquations::decode(sys_c),
        NormalEquations::decode(sys_g),
    );
    let (ata, atb) = system_rel_diffs(sys_c, sys_g);
    let inl = c.inliers.abs_diff(g.inliers) as f64 / c.inliers as f64;
    eprintln!(
        "{label}: inliers cpu {} gpu {}; rel diff AᵀA {ata:e} Aᵀb {atb:e}; \
         residual² cpu {:e} gpu {:e}",
        c.inliers, g.inliers, c.residual_sq_sum, g.residual_sq_sum
    );
    assert!(
        c.inliers > min_inliers,
        "{label}: too few inliers for a real test"
    );
    assert!(
        inl <= INLIER_FRACTION_TOL,
        "{label}: inliers {} vs {}",
        c.inliers,
        g.inliers
    );
    assert!(
        ata <= SYSTEM_REL_TOL,
        "{label}: AᵀA relative difference {ata:e}"
    );
    assert!(
        atb <= SYSTEM_REL_TOL,
        "{label}: Aᵀb relative difference {atb:e}"
    );
    let (xc, xg) = (c.solve().unwrap(), g.solve().unwrap());
    let dx: f64 = (0..6).map(|k| (xc[k] - xg[k]).powi(2)).sum::<f64>().sqrt();
    eprintln!("{label}: increment cpu {xc:?}\n      gpu {xg:?}; difference {dx:e}");
    assert!(
        dx <= increment_tol(level),
        "{label}: increments differ by {dx:e}"
    );
}

/// icp_reduce against its twin: the decoded 6x6 systems and the solved increments agree,
/// at a pose perturbed from the ground truth.
fn icp_system_matches_twin(mut gpu: GpuBackend) {
    let (mut s, t_true) = frame_4_on_both(&mut gpu, Profile::Assignment);
    // The robust profile's gates and weights too (angle gate, Huber, depth noise), with
    // the parameters its pipeline builds.
    let robust = Slam::new(
        CpuBackend::new(),
        Intrinsics::ICL_NUIM,
        ValidParams::profile(Profile::Robust),
    );
    let cases = [
        ("true pose", s.icp_params(0, &t_true)),
        ("perturbed pose", s.icp_params(0, &(nudge() * t_true))),
        (
            "robust, perturbed pose",
            robust.icp_params(0, &(nudge() * t_true)),
        ),
    ];
    assert!(cases[2].1.cos_normal_threshold > 0.0 && cases[2].1.noise_weighting == 1);
    for (label, ip) in cases {
        let (sys_c, sys_g) = (
            s.backend.icp_system(0, &ip).unwrap(),
            gpu.icp_system(0, &ip).unwrap(),
        );
        check_systems(label, &sys_c, &sys_g);
    }
}

/// photo_reduce (and predict_model's predicted intensity under it) against its twin,
/// through `rgbd_system`: both systems of one submission agree, the geometric one equal to
/// `icp_system`'s, at the true and a perturbed pose.
fn rgbd_systems_match_twin(mut gpu: GpuBackend) {
    let (mut s, t_true) = frame_4_on_both(&mut gpu, Profile::Assignment);
    for (label, t) in [("true pose", t_true), ("perturbed pose", nudge() * t_true)] {
        let ip = s.icp_params(0, &t);
        let [geo_c, photo_c] = s.backend.rgbd_system(0, &ip).unwrap();
        let [geo_g, photo_g] = gpu.rgbd_system(0, &ip).unwrap();
        assert_eq!(geo_c, s.backend.icp_system(0, &ip).unwrap(), "{label}");
        assert_eq!(geo_g, gpu.icp_system(0, &ip).unwrap(), "{label}");
        check_systems(&format!("{label}, geometric"), &geo_c, &geo_g);
        check_systems(&format!("{label}, photometric"), &photo_c, &photo_g);
    }
}

/// Intensity patches differ by at most this (intensity units, 0..1): the luma and the
/// binomial mean are a few multiply-adds of values below 1, so f32 rounding (and fused
/// multiply-add on a GPU) moves them by a few 1e-8; 1e-6 leaves a margin of 10.
const INTENSITY_TOL: f32 = 1e-6;

/// intensity_pyramid against its twin on every level of a real frame (robust profile, three
/// levels), then photo_reduce at every level through `rgbd_system`: the photometric and
/// geometric systems agree as icp_reduce's do at level 0.
fn intensity_pyramid_and_coarse_rgbd_match_twin(mut gpu: GpuBackend) {
    let (mut s, gt) = robust_pyramids_on_both(&mut gpu, 4, 3);
    let nudge = se3::exp(&[0.002, -0.001, 0.003, 0.004, 0.002, -0.003]);
    let t = nudge * se3::inverse_rigid(gt_at(&gt, 4).unwrap());
    for level in (0..3).rev() {
        let ip = s.icp_params(level, &t);
        let [geo_c, photo_c] = s.backend.rgbd_system(level, &ip).unwrap();
        let [geo_g, photo_g] = gpu.rgbd_system(level, &ip).unwrap();
        assert_eq!(geo_c, s.backend.icp_system(level, &ip).unwrap(), "{level}");
        // A real test at every level: a tenth of the level's pixels.
        let min = s.level_intrinsics(level).pixels() as u64 / 10;
        check_systems_of(
            &format!("level {level}, geometric"),
            &geo_c,
            &geo_g,
            min,
            level,
        );
        // The photometric system alone is ill-conditioned at the coarse levels (a few
        // thousand rows of image gradient): its entries must agree, and the increment of
        // the system the tracker solves, the two combined.
        let (ata, atb) = system_rel_diffs(&photo_c, &photo_g);
        let (pc, pg) = (
            NormalEquations::decode(&photo_c),
            NormalEquations::decode(&photo_g),
        );
        eprintln!(
            "level {level}, photometric: inliers cpu {} gpu {}; rel diff AᵀA {ata:e} Aᵀb {atb:e}",
            pc.inliers, pg.inliers
        );
        assert!(pc.inliers > min, "level {level}: too few photometric rows");
        check_level_system(
            level,
            "photometric rows",
            (pc.inliers, pg.inliers),
            ata,
            atb,
        );
        let w = s.params.icp.photometric_weight;
        let combined = |geo: &[f64; ICP_SYSTEM_LEN], photo: &NormalEquations| {
            let x = NormalEquations::decode(geo)
                .with_photometric(photo, w)
                .solve();
            x.expect("a well-posed combined system")
        };
        let (xc, xg) = (combined(&geo_c, &pc), combined(&geo_g, &pg));
        let dx: f64 = (0..6).map(|k| (xc[k] - xg[k]).powi(2)).sum::<f64>().sqrt();
        assert!(
            dx <= increment_tol(level),
            "level {level}: combined increments differ by {dx:e}"
        );
    }
    let cpu_patches = s.backend.intensity_patches().to_vec();
    let gpu_patches = gpu.download_intensity_patches().unwrap();
    assert_eq!(cpu_patches.len(), 3);
    assert_eq!(gpu_patches.len(), 3);
    for (level, (c, g)) in cpu_patches.iter().zip(&gpu_patches).enumerate() {
        assert_eq!(c.len(), s.level_intrinsics(level).pixels(), "level {level}");
        assert_eq!(c.len(), g.len(), "level {level}");
        let mut textured = 0;
        for (i, (pc, pg)) in c.iter().zip(g).enumerate() {
            for k in 0..4 {
                assert!(
                    (pc[k] - pg[k]).abs() <= INTENSITY_TOL,
                    "level {level} pixel {i} corner {k}: cpu {pc:?} gpu {pg:?}"
                );
            }
            textured += (pc[1] != pc[0]) as usize;
        }
        assert!(
            textured > c.len() / 2,
            "level {level}: a flat image tests little"
        );
    }
}

/// icp_reduce on the coarser pyramid levels against its twin: the kernel is level 0's, with
/// the level's textures, size and intrinsics bound; the decoded systems and increments
/// agree as at level 0 (robust profile, a perturbed pose).
fn coarse_icp_systems_match_twin(mut gpu: GpuBackend) {
    let (mut s, gt) = robust_pyramids_on_both(&mut gpu, 4, 3);
    let nudge = se3::exp(&[0.002, -0.001, 0.003, 0.004, 0.002, -0.003]);
    let t = nudge * se3::inverse_rigid(gt_at(&gt, 4).unwrap());
    for level in 1..3 {
        let ip = s.icp_params(level, &t);
        let pixels = s.level_intrinsics(level).pixels();
        assert_eq!(ip.camera.width as usize * ip.camera.height as usize, pixels);
        let (sys_c, sys_g) = (
            s.backend.icp_system(level, &ip).unwrap(),
            gpu.icp_system(level, &ip).unwrap(),
        );
        let (c, g) = (
            NormalEquations::decode(&sys_c),
            NormalEquations::decode(&sys_g),
        );
        let (ata, atb) = system_rel_diffs(&sys_c, &sys_g);
        eprintln!(
            "level {level}: inliers cpu {} gpu {} of {pixels} pixels; rel diff AᵀA {ata:e} \
             Aᵀb {atb:e}",
            c.inliers, g.inliers
        );
        assert!(
            c.inliers as usize > pixels / 4,
            "level {level}: too few inliers for a real test"
        );
        check_level_system(level, "inliers", (c.inliers, g.inliers), ata, atb);
        let (xc, xg) = (c.solve().unwrap(), g.solve().unwrap());
        let dx: f64 = (0..6).map(|k| (xc[k] - xg[k]).powi(2)).sum::<f64>().sqrt();
        assert!(
            dx <= increment_tol(level),
            "level {level}: increments differ by {dx:e}"
        );
    }
    // A level the pyramid does not have is an argument error, not a panic.
    assert!(matches!(
        gpu.icp_system(3, &s.icp_params(2, &t)),
        Err(Error::Argument(_))
    ));
}

/// icp_reduce_final against its twin, bit for bit, over partials shaped as on lavapipe (16
/// workgroups), on a GPU (1024) and around the tree's 64 threads: entries of mixed sign and magnitude (as AᵀA, Aᵀb,
/// counts and residuals are), so the order of the f32 adds shows in the result.
fn icp_reduce_final_matches_twin(ctx: GpuContext) {
    use wgslam::gpu::{GpuArray, Kernel, Readback};
    use wgslam::layout::ICP_SYSTEM_LEN;
    let kernel = Kernel::new(&ctx, "icp_reduce_final").unwrap();
    for groups in [1usize, 16, 63, 64, 65, 1024, 4099] {
        let n = groups * ICP_SYSTEM_LEN;
        let partials: Vec<f32> = (0..n)
            .map(|i| {
                let x = ((i as u64 * 2_654_435_761) % 1_000_003) as f32 / 1_000_003.0 - 0.3;
                x * 10f32.powi((i % 7) as i32 - 3)
            })
            .collect();
        // The twin's tree over the shader's f32 (the CPU backend runs it over f64).
        let mut twin = [0.0f32; ICP_SYSTEM_LEN];
        cpu::icp_reduce_final::sum_tree(&partials, &mut twin);
        let input = GpuArray::from_slice(&ctx, "partials", &partials).unwrap();
        let mut system = GpuArray::<f32>::new(&ctx, "system", ICP_SYSTEM_LEN).unwrap();
        system.set_len(ICP_SYSTEM_LEN);
        let mut readback = Readback::new(&ctx, "system read-back", ICP_SYSTEM_LEN);
        let bg = kernel.bind_group(
            &ctx,
            &[("partials", input.binding()), ("system", system.binding())],
        );
        let mut enc = ctx.encoder("icp_reduce_final");
        {
            let mut pass = enc.begin_compute_pass(&Default::default());
            // One workgroup per entry of the system.
            kernel
                .dispatch_grid(&ctx, &mut pass, &bg, [ICP_SYSTEM_LEN as u32, 1])
                .unwrap();
        }
        readback.copy_from(&mut enc, &system, ICP_SYSTEM_LEN);
        ctx.submit(enc);
        let gpu = readback.read(&ctx).unwrap();
        for k in 0..ICP_SYSTEM_LEN {
            assert_eq!(
                gpu[k].to_bits(),
                twin[k].to_bits(),
                "{groups} workgroups, entry {k}: gpu {} twin {}",
                gpu[k],
                twin[k]
            );
        }
    }
}

/// icp_candidates against its twin on the same maps (the CPU map uploaded to the GPU, the
/// same frame, predicted at frame 3's pose), at the true and a perturbed pose: the counts
/// agree within the validity-mask allowance (a projection can land on the other side of a
/// texel border after an FMA), and they are real counts (most of the image).
fn icp_candidates_matches_twin(mut gpu: GpuBackend) {
    let (mut s, t_true) = frame_4_on_both(&mut gpu, Profile::Robust);
    let nudge = se3::exp(&[0.01, -0.02, 0.01, 0.05, 0.02, -0.03]);
    for (label, t) in [("true pose", t_true), ("perturbed pose", nudge * t_true)] {
        let ip = s.icp_params(0, &t);
        let (c, g) = (
            s.backend.count_candidates(&ip).unwrap(),
            gpu.count_candidates(&ip).unwrap(),
        );
        eprintln!("{label}: candidates cpu {c} gpu {g}");
        let pixels = (ip.camera.width * ip.camera.height) as u64;
        assert!(c > pixels / 2, "{label}: only {c} candidates");
        assert!(
            c.abs_diff(g) as f64 <= MASK_MISMATCH_FRACTION * pixels as f64,
            "{label}: {c} vs {g}"
        );
    }
}

pub(super) fn tests() -> Vec<Test> {
    vec![
        gpu_backend_test("icp_candidates_matches_twin", icp_candidates_matches_twin),
        gpu_backend_test("icp_system_matches_twin", icp_system_matches_twin),
        gpu_backend_test("rgbd_systems_match_twin", rgbd_systems_match_twin),
        gpu(
            "icp_reduce_final_matches_twin",
            icp_reduce_final_matches_twin,
        ),
        gpu_backend_test(
            "coarse_icp_systems_match_twin",
            coarse_icp_systems_match_twin,
        ),
        gpu_backend_test(
            "intensity_pyramid_and_coarse_rgbd_match_twin",
            intensity_pyramid_and_coarse_rgbd_match_twin,
        ),
    ]
}

/// A level's system from both backends: the rows counted (`what`, CPU then GPU) within
/// [`INLIER_FRACTION_TOL`], and the relative differences of AᵀA and Aᵀb within
/// [`SYSTEM_REL_TOL`].
fn check_level_system(level: usize, what: &str, rows: (u64, u64), ata: f64, atb: f64) {
    let what = format!("level {level}: {what}");
    check_count(&what, rows.0 as usize, rows.1 as usize, INLIER_FRACTION_TOL);
    assert!(
        ata <= SYSTEM_REL_TOL && atb <= SYSTEM_REL_TOL,
        "{what}: AᵀA {ata:e} Aᵀb {atb:e}"
    );
}
