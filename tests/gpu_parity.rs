//! Each WGSL kernel against its CPU twin on real ICL-NUIM frames from `assets/`, a whole
//! tracked run on both backends (and the GPU run against the real ground truth), and the
//! GPU map's growth and capacity error. Every trial shows as ignored without a GPU adapter
//! (tests/common/harness.rs).

mod common;

use std::process::ExitCode;

use common::frames::{gt_at, load_frame, load_gt};
use common::harness::{gpu, plain};
use glam::DMat4;
use wgslam::cpu;
use wgslam::geometry::camera::Intrinsics;
use wgslam::geometry::se3;
use wgslam::gpu::{GpuBackend, GpuContext};
use wgslam::layout::{
    CompactParams, FuseParams, MapChunk, ProjectParams, ASSOCIATION_BEST_CANDIDATE, BLOCK_SURFELS,
};
use wgslam::slam::backend::{Backend, FrameMaps, Inspect};
use wgslam::slam::cpu_backend::CpuBackend;
use wgslam::slam::map::SurfelMap;
use wgslam::slam::params::{BilateralSettings, PoseSource, Profile, SlamParams, UnstableRemoval};
use wgslam::slam::pipeline::{Slam, TrackStatus};
use wgslam::slam::solve::NormalEquations;
use wgslam::tools::compare::{system_rel_diffs, tolerance};
use wgslam::Error;

// ---------------------------------------------------------------------------------------
// Tolerances (each with its reason). Where `wgslam compare` has the same bound
// (`wgslam::tools::compare::tolerance`, documented there) it is used, converted to this file's units.

/// Vertices: the same f32 formula on both sides; lavapipe may contract a multiply-add into
/// an FMA or round a division differently, a few ULP of a value below 6 m (~1e-6 m).
const VERTEX_TOL_M: f32 = tolerance::VERTEX_MAX_ABS_M as f32;
/// Bilaterally filtered vertices: a weighted mean of 9 (default) to 49 depths whose weights come
/// from `exp`, which lavapipe evaluates with its own polynomial (WGSL allows 3 + 2|x| ULP)
/// and whose sums it may contract into FMAs. A relative weight error ε moves the mean by at
/// most ε times the spread of the window's depths, which the range weight keeps within a few
/// sigma_depth (0.1 m): ~1e-6 m for ε of a few ULP, within the vertex bound (measured on
/// lavapipe, frame 5: 1.2e-6 m with the default 3x3 window at 320x240 and 640x480, 1.7e-6 m
/// with the 7x7 one).
const FILTERED_VERTEX_TOL_M: f32 = VERTEX_TOL_M;
/// Normals, per component of a unit vector: a cross product of differences of nearby
/// vertices amplifies those ULPs by the inverse of the pixel spacing (~1/0.01 m). Derived
/// from `tolerance::NORMAL_MAX_DEG` (0.05 degrees): turning a unit vector by an angle θ moves
/// it by the chord 2 sin(θ/2) <= θ, so no component moves by more than θ in radians
/// (8.7e-4; was 1e-3 here; measured on lavapipe: 0 in preprocess).
const NORMAL_TOL: f32 = tolerance::NORMAL_MAX_DEG.to_radians() as f32;
/// Validity masks (normals, index map): a depth-jump comparison or a projection can land on
/// the other side of a boundary after one ULP of FMA difference. Allowed fraction of pixels.
const MASK_MISMATCH_FRACTION: f64 = tolerance::VALIDITY_MISMATCH_MAX_FRACTION;
/// The index map a best-candidate fusion builds for the next prediction against a fresh
/// projection of the fused map: a merge moves a surfel by a fraction of its radius, which
/// takes a few across a pixel border (measured: 51 of 72,604 covered pixels, 0.07%, on the
/// test's frame at 320x240). Allowed fraction of the covered pixels.
const FUSED_INDEX_MAP_MISMATCH_FRACTION: f64 = 0.01;
/// Index-map keys: the camera depth in the key may differ by a few ULP (FMA in the pose
/// transform on the GPU).
const KEY_DEPTH_ULP_TOL: u32 = 4;
/// fuse_select's off-ray distances, metres: the difference of the surfel's camera-frame
/// point and the pixel's, both a few ULP of ~3 m apart between the backends (FMA in the
/// pose transform, as for vertices), minus its component along the ray; the cancellation
/// leaves the vertices' absolute error, not a relative one.
const OFF_RAY_TOL_M: f32 = VERTEX_TOL_M;
/// Decoded 6x6 systems: f32 partial sums of ~50k rows per workgroup on the GPU versus f64
/// sums on the CPU; relative Frobenius difference of AᵀA and Aᵀb.
const SYSTEM_REL_TOL: f64 = tolerance::SYSTEM_REL_DIFF_MAX;
/// Solved increments (radians and metres mixed): 1e-6 is a micrometre / microradian, far
/// below the 1e-6 convergence threshold's effect on a pose and the data's 1 mm quantisation.
const INCREMENT_TOL: f64 = 1e-6;
/// Inlier counts: the distance and projection filters can flip for a few pixels (FMA), as
/// the validity masks can: the same allowed fraction.
const INLIER_FRACTION_TOL: f64 = tolerance::VALIDITY_MISMATCH_MAX_FRACTION;
/// Fused surfels: an average of a handful of observations of f32 values (metres / 0..255).
const SURFEL_POS_TOL_M: f32 = 1e-4;
const SURFEL_COLOR_TOL: f32 = 1e-2;
/// Surfel weights, relative: sums of `pixel_confidence`, an `exp` that lavapipe evaluates
/// with its own polynomial (WGSL allows 3 + 2|x| ULP), so a few ULP per term; counts
/// (the assignment's unit confidences) stay exact under it.
const SURFEL_WEIGHT_REL_TOL: f32 = 1e-5;
/// Surfel radii, metres: `surfel_radius` is a product and quotient of f32s of ~1e-2 m, a
/// few ULP apart (dot products may be contracted into FMAs).
const SURFEL_RADIUS_TOL_M: f32 = 1e-6;
/// Whole runs: per-frame pose difference between the backends (the solve differs only by
/// f32 vs f64 summation, and ICP converges to the same minimum).
const RUN_POSE_TOL_M: f64 = tolerance::POSE_MAX_MM / 1e3;
const RUN_POSE_TOL_DEG: f64 = tolerance::POSE_MAX_DEG;
/// Whole runs: surfel count difference between the backends (fusion filter decisions on a
/// boundary, amplified over frames).
const RUN_SURFEL_FRACTION_TOL: f64 = tolerance::SURFEL_COUNT_REL_DIFF_MAX;
/// The GPU run against ground truth over the bundled frames: translation RMSE (the bar
/// the CPU reference meets with ~0.2 mm to spare).
const GT_RMSE_MAX_M: f64 = 1e-3;

// ---------------------------------------------------------------------------------------
fn root() -> std::path::PathBuf {
    common::bundled_icl()
}

fn slam<B: Backend>(backend: B, params: SlamParams) -> Slam<B> {
    Slam::new(backend, Intrinsics::ICL_NUIM, params)
}

fn gpu_backend(ctx: GpuContext) -> GpuBackend {
    GpuBackend::new(ctx).expect("GPU backend")
}

/// Counts mask mismatches and panics (naming the first pixels) past the allowance.
fn check_mask(what: &str, cpu: &[bool], gpu: &[bool]) {
    assert_eq!(cpu.len(), gpu.len());
    let bad: Vec<usize> = (0..cpu.len()).filter(|&i| cpu[i] != gpu[i]).collect();
    let allowed = (cpu.len() as f64 * MASK_MISMATCH_FRACTION).ceil() as usize;
    eprintln!("{what}: {} of {} mask entries differ", bad.len(), cpu.len());
    assert!(
        bad.len() <= allowed,
        "{what}: {} mask mismatches (allowed {allowed}); first at pixels {:?} (cpu {:?}, gpu {:?})",
        bad.len(),
        &bad[..bad.len().min(5)],
        bad.iter().take(5).map(|&i| cpu[i]).collect::<Vec<_>>(),
        bad.iter().take(5).map(|&i| gpu[i]).collect::<Vec<_>>(),
    );
}

/// Compares two vec4 maps where both are valid; masks separately with [`check_mask`].
fn check_vec4_map(what: &str, cpu: &[[f32; 4]], gpu: &[[f32; 4]], tol: f32) {
    check_mask(
        what,
        &cpu.iter().map(|v| v[3] > 0.0).collect::<Vec<_>>(),
        &gpu.iter().map(|v| v[3] > 0.0).collect::<Vec<_>>(),
    );
    let mut worst = (0.0f32, 0usize);
    for (i, (c, g)) in cpu.iter().zip(gpu).enumerate() {
        if c[3] > 0.0 && g[3] > 0.0 {
            let d = (0..3).map(|k| (c[k] - g[k]).abs()).fold(0.0, f32::max);
            if d > worst.0 {
                worst = (d, i);
            }
        }
    }
    let i = worst.1;
    eprintln!("{what}: max difference {:e} at pixel {i}", worst.0);
    assert!(
        worst.0 <= tol,
        "{what}: pixel {i} differs by {:e} > {tol:e}: cpu {:?}, gpu {:?}",
        worst.0,
        cpu[i],
        gpu[i]
    );
}

/// A CPU map fused from bundled frames 1..=n at ground-truth poses.
fn cpu_map_from_gt(n: usize, params: &SlamParams) -> (Slam<CpuBackend>, Vec<Option<DMat4>>) {
    let gt = load_gt(&root());
    let mut s = slam(
        CpuBackend::new(),
        SlamParams {
            poses: PoseSource::GroundTruth,
            ..params.clone()
        },
    );
    for i in 1..=n {
        let f = load_frame(&root(), i);
        s.process(i as u32, &f.depth, &f.rgba, gt_at(&gt, i))
            .unwrap();
    }
    (s, gt)
}

// ---------------------------------------------------------------------------------------

/// depth_to_vertex and vertex_to_normal against their twins, at downsample 2 and 1.
fn preprocess_matches_twins(mut gpu: GpuBackend) {
    let frame = load_frame(&root(), 5);
    for downsample in [2, 1] {
        let mut params = SlamParams::profile(Profile::Assignment);
        params.input.downsample = downsample;
        let s = slam(CpuBackend::new(), params);
        let (pp, np) = (s.preprocess_params(), s.normal_params());
        let mut cpu_b = s.backend;
        cpu_b
            .preprocess(&pp, None, &np, &[], &frame.depth, &frame.rgba)
            .unwrap();
        gpu.preprocess(&pp, None, &np, &[], &frame.depth, &frame.rgba)
            .unwrap();
        let c = cpu_b.download_frame().unwrap();
        let g = gpu.download_frame().unwrap();
        let tag = format!("downsample {downsample}");
        check_vec4_map(&format!("{tag} vertex"), &c.vertex, &g.vertex, VERTEX_TOL_M);
        // Colour is integer-valued: exact.
        assert_eq!(c.color, g.color, "{tag}: colour maps differ");
        let (c_normal, g_normal) = (c.normal_map(), g.normal_map());
        check_vec4_map(&format!("{tag} normal"), &c_normal, &g_normal, NORMAL_TOL);
        let valid = c_normal.iter().filter(|n| n[3] > 0.0).count();
        assert!(
            valid > c_normal.len() / 2,
            "{tag}: only {valid} valid normals"
        );
    }
}

/// bilateral_filter against its twin, through `preprocess` with the filter on (so the GPU
/// pipeline's wiring is checked too): the unfiltered vertex map is kept, the filtered one
/// matches the twin, and the normals are made from it; at downsample 2 and 1, with the
/// default 3x3 window and depth-dependent sigma and with KinectFusion's 7x7 window and
/// constant 30 mm sigma.
fn bilateral_filter_matches_twin(mut gpu: GpuBackend) {
    let frame = load_frame(&root(), 5);
    let kinect_fusion = BilateralSettings {
        radius_px: 3,
        sigma_space_px: 2.25,
        sigma_depth_m: 0.03,
        sigma_depth_per_m2: 0.0,
    };
    for (downsample, settings) in [
        (2, BilateralSettings::default()),
        (1, BilateralSettings::default()),
        (2, kinect_fusion),
    ] {
        let mut params = SlamParams::profile(Profile::Assignment);
        params.input.downsample = downsample;
        params.bilateral = Some(settings);
        let s = slam(CpuBackend::new(), params);
        let (pp, bp, np) = (
            s.preprocess_params(),
            s.bilateral_params(),
            s.normal_params(),
        );
        assert!(bp.is_some());
        let mut cpu_b = s.backend;
        cpu_b
            .preprocess(&pp, bp.as_ref(), &np, &[], &frame.depth, &frame.rgba)
            .unwrap();
        gpu.preprocess(&pp, bp.as_ref(), &np, &[], &frame.depth, &frame.rgba)
            .unwrap();
        let c = cpu_b.download_frame().unwrap();
        let g = gpu.download_frame().unwrap();
        let tag = format!("bilateral {settings:?}, downsample {downsample}");
        check_vec4_map(&format!("{tag} vertex"), &c.vertex, &g.vertex, VERTEX_TOL_M);
        assert_eq!(c.filtered_vertex.len(), c.vertex.len());
        check_vec4_map(
            &format!("{tag} filtered vertex"),
            &c.filtered_vertex,
            &g.filtered_vertex,
            FILTERED_VERTEX_TOL_M,
        );
        // The filter keeps the validity mask exactly (invalid stays invalid, valid stays
        // valid) and moves depths: the twin's output is not the unfiltered map.
        let moved = (0..c.vertex.len())
            .filter(|&i| c.vertex[i][3] > 0.0 && c.vertex[i][2] != c.filtered_vertex[i][2])
            .count();
        assert!(
            c.vertex
                .iter()
                .zip(&c.filtered_vertex)
                .all(|(a, b)| (a[3] > 0.0) == (b[3] > 0.0)),
            "{tag}: the filter changed the validity mask"
        );
        assert!(
            moved > c.vertex.len() / 4,
            "{tag}: only {moved} depths moved"
        );
        let (c_normal, g_normal) = (c.normal_map(), g.normal_map());
        check_vec4_map(&format!("{tag} normal"), &c_normal, &g_normal, NORMAL_TOL);
        // normal_depth carries the filtered depth.
        let i = (0..c.vertex.len())
            .find(|&i| c.normal_depth[i][3] > 0.0)
            .expect("a valid normal");
        assert_eq!(
            c.normal_depth[i][3], c.filtered_vertex[i][2],
            "{tag}: pixel {i}"
        );
    }
    // Back to the filter off: the frame has no filtered map again.
    let s = slam(CpuBackend::new(), SlamParams::profile(Profile::Assignment));
    let (pp, np) = (s.preprocess_params(), s.normal_params());
    gpu.preprocess(&pp, None, &np, &[], &frame.depth, &frame.rgba)
        .unwrap();
    assert!(gpu.download_frame().unwrap().filtered_vertex.is_empty());
}

/// project_model and predict_model against their twins on a real fused map, viewed from a
/// later frame's ground-truth pose.
fn predict_matches_twins(mut gpu: GpuBackend) {
    let params = SlamParams::profile(Profile::Assignment);
    let (mut s, gt) = cpu_map_from_gt(3, &params);
    let map = s.backend.download_map().unwrap();
    gpu.upload_map(&map).unwrap();
    let frame = load_frame(&root(), 6);
    let (pp, np) = (s.preprocess_params(), s.normal_params());
    gpu.preprocess(&pp, None, &np, &[], &frame.depth, &frame.rgba)
        .unwrap();
    let t_world_to_cam = se3::inverse_rigid(gt_at(&gt, 6).unwrap());
    let proj = s.project_params(&t_world_to_cam);
    assert_eq!(proj.surfel_count as usize, map.len());

    let n = (proj.width * proj.height) as usize;
    let mut index_cpu = vec![0u64; n];
    let whole = MapChunk::whole(map.len());
    let bounds = cpu::block_bounds::whole_map_bounds(&map.position_weight);
    cpu::project_model::project_model(&proj, &whole, &bounds, &map.position_weight, &mut index_cpu);
    let (mut pv_cpu, mut pn_cpu) = (vec![[0.0; 4]; n], vec![[0.0; 4]; n]);
    cpu::predict_model::predict_model(
        &proj,
        &index_cpu,
        &whole,
        &map.position_weight,
        &map.normal_frame,
        &mut pv_cpu,
        &mut pn_cpu,
    );
    gpu.predict(&proj, &[]).unwrap();
    let index_gpu = gpu.download_index_map().unwrap();
    let (pv_gpu, pn_gpu) = gpu.download_prediction(0).unwrap();
    check_index_maps("index map", &index_cpu, &index_gpu);
    // The same surfel gives bit-identical copies of its position and normal.
    check_vec4_map("predicted vertex", &pv_cpu, &pv_gpu, 0.0);
    check_vec4_map("predicted normal", &pn_cpu, &pn_gpu, 0.0);
}

/// Index maps (project_model's keys): the same surfel at (almost) every pixel. The depth
/// half of the key may differ by a few ULP (the GPU may fuse the pose multiply-adds),
/// which is not a difference in the chosen surfel unless it changes the winner.
fn check_index_maps(what: &str, index_cpu: &[u64], index_gpu: &[u64]) {
    let n = index_cpu.len();
    assert_eq!(index_gpu.len(), n, "{what}: sizes");
    let surfel = |k: u64| (k != 0).then_some(k & 0xffff_ffff);
    let depth_bits = |k: u64| !((k >> 32) as u32);
    let differ: Vec<usize> = (0..n)
        .filter(|&i| surfel(index_cpu[i]) != surfel(index_gpu[i]))
        .collect();
    let allowed = (n as f64 * MASK_MISMATCH_FRACTION).ceil() as usize;
    let max_ulp = (0..n)
        .filter(|&i| index_cpu[i] != 0 && surfel(index_cpu[i]) == surfel(index_gpu[i]))
        .map(|i| depth_bits(index_cpu[i]).abs_diff(depth_bits(index_gpu[i])))
        .max()
        .unwrap_or(0);
    eprintln!(
        "{what}: {} of {n} pixels pick a different surfel; {} covered; depth keys within {max_ulp} ULP",
        differ.len(),
        index_cpu.iter().filter(|&&k| k != 0).count()
    );
    assert!(
        max_ulp <= KEY_DEPTH_ULP_TOL,
        "{what}: depth keys differ by {max_ulp} ULP"
    );
    if let Some(&i) = differ.first() {
        assert!(
            differ.len() <= allowed,
            "{what}: {} pixels differ (allowed {allowed}); first at pixel {i}: cpu {:#x} gpu {:#x}",
            differ.len(),
            index_cpu[i],
            index_gpu[i]
        );
    }
}

/// icp_reduce against its twin: the decoded 6x6 systems and the solved increments agree,
/// at a pose perturbed from the ground truth.
fn icp_system_matches_twin(mut gpu: GpuBackend) {
    let params = SlamParams::profile(Profile::Assignment);
    let (mut s, gt) = cpu_map_from_gt(3, &params);
    gpu.upload_map(&s.backend.download_map().unwrap()).unwrap();
    let frame = load_frame(&root(), 4);
    let (pp, np) = (s.preprocess_params(), s.normal_params());
    s.backend
        .preprocess(&pp, None, &np, &[], &frame.depth, &frame.rgba)
        .unwrap();
    gpu.preprocess(&pp, None, &np, &[], &frame.depth, &frame.rgba)
        .unwrap();
    // Predict from frame 3's pose, track frame 4 from a perturbed estimate.
    let t_prev = se3::inverse_rigid(gt_at(&gt, 3).unwrap());
    let proj = s.project_params(&t_prev);
    s.backend.predict(&proj, &[]).unwrap();
    gpu.predict(&proj, &[]).unwrap();
    let t_true = se3::inverse_rigid(gt_at(&gt, 4).unwrap());
    let nudge = se3::exp(&[0.002, -0.001, 0.003, 0.004, 0.002, -0.003]);
    // The robust profile's gates and weights too (angle gate, Huber, depth noise), with
    // the parameters its pipeline builds.
    let robust = Slam::new(
        CpuBackend::new(),
        Intrinsics::ICL_NUIM,
        SlamParams::profile(Profile::Robust),
    );
    let cases = [
        ("true pose", s.icp_params(0, &t_true)),
        ("perturbed pose", s.icp_params(0, &(nudge * t_true))),
        (
            "robust, perturbed pose",
            robust.icp_params(0, &(nudge * t_true)),
        ),
    ];
    assert!(cases[2].1.cos_normal_threshold > 0.0 && cases[2].1.noise_weighting == 1);
    for (label, ip) in cases {
        let (sys_c, sys_g) = (
            s.backend.icp_system(0, &ip).unwrap(),
            gpu.icp_system(0, &ip).unwrap(),
        );
        let (c, g) = (
            NormalEquations::decode(&sys_c),
            NormalEquations::decode(&sys_g),
        );
        // The measure `wgslam compare` uses (Aᵀb against its Cauchy-Schwarz bound).
        let (ata, atb) = system_rel_diffs(&sys_c, &sys_g);
        let inl = c.inliers.abs_diff(g.inliers) as f64 / c.inliers as f64;
        eprintln!(
            "{label}: inliers cpu {} gpu {}; rel diff AᵀA {ata:e} Aᵀb {atb:e}; \
             residual² cpu {:e} gpu {:e}",
            c.inliers, g.inliers, c.residual_sq_sum, g.residual_sq_sum
        );
        assert!(
            c.inliers > 10_000,
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
        assert!(dx <= INCREMENT_TOL, "{label}: increments differ by {dx:e}");
    }
}

/// pyramid_depth (with vertex_to_normal per level) against its twin, through `preprocess`
/// with the robust profile's three levels, with the bilateral filter on (level 1 made from
/// the filtered map) and off (from the unfiltered one), at downsample 2 and 1.
fn pyramid_depth_matches_twin(mut gpu: GpuBackend) {
    let frame = load_frame(&root(), 5);
    let robust = SlamParams::profile(Profile::Robust);
    assert_eq!(robust.icp.level_iters.len(), 3);
    for (downsample, bilateral) in [(2, robust.bilateral), (2, None), (1, robust.bilateral)] {
        let mut params = robust.clone();
        params.input.downsample = downsample;
        params.bilateral = bilateral;
        let s = slam(CpuBackend::new(), params);
        let (pp, bp, np, pyr) = (
            s.preprocess_params(),
            s.bilateral_params(),
            s.normal_params(),
            s.pyramid_levels(),
        );
        assert_eq!(pyr.len(), 2);
        let level_intrinsics: Vec<Intrinsics> = (1..3).map(|l| s.level_intrinsics(l)).collect();
        let mut cpu_b = s.backend;
        cpu_b
            .preprocess(&pp, bp.as_ref(), &np, &pyr, &frame.depth, &frame.rgba)
            .unwrap();
        gpu.preprocess(&pp, bp.as_ref(), &np, &pyr, &frame.depth, &frame.rgba)
            .unwrap();
        let (c, g) = (
            cpu_b.download_frame().unwrap(),
            gpu.download_frame().unwrap(),
        );
        assert_eq!((c.pyramid.len(), g.pyramid.len()), (2, 2));
        for (l, (cl, gl)) in c.pyramid.iter().zip(&g.pyramid).enumerate() {
            let k = level_intrinsics[l];
            let tag = format!(
                "downsample {downsample}, filter {}, level {} ({}x{})",
                bilateral.is_some(),
                l + 1,
                k.width,
                k.height
            );
            assert_eq!(cl.vertex.len(), k.pixels(), "{tag}");
            // A mean of up to 9 depths that differ by the filtered maps' tolerance.
            check_vec4_map(
                &format!("{tag} vertex"),
                &cl.vertex,
                &gl.vertex,
                FILTERED_VERTEX_TOL_M,
            );
            let (cn, gn) = (
                FrameMaps::normal_map_of(&cl.normal_depth),
                FrameMaps::normal_map_of(&gl.normal_depth),
            );
            check_vec4_map(&format!("{tag} normal"), &cn, &gn, NORMAL_TOL);
            let valid = cn.iter().filter(|n| n[3] > 0.0).count();
            assert!(valid > cn.len() / 2, "{tag}: only {valid} valid normals");
        }
    }
}

/// The robust profile on both backends from the same map (bundled frames 1..=3 fused at
/// ground truth): frame `frame` preprocessed into its pyramid, and the map predicted at
/// the ground-truth pose of frame `predict_at`. Returns the CPU tracker and the ground
/// truth.
fn robust_pyramids_on_both(
    gpu: &mut GpuBackend,
    frame: usize,
    predict_at: usize,
) -> (Slam<CpuBackend>, Vec<Option<DMat4>>) {
    let params = SlamParams::profile(Profile::Robust);
    let (mut s, gt) = cpu_map_from_gt(3, &params);
    gpu.upload_map(&s.backend.download_map().unwrap()).unwrap();
    let f = load_frame(&root(), frame);
    let (pp, bp, np, pyr) = (
        s.preprocess_params(),
        s.bilateral_params(),
        s.normal_params(),
        s.pyramid_levels(),
    );
    s.backend
        .preprocess(&pp, bp.as_ref(), &np, &pyr, &f.depth, &f.rgba)
        .unwrap();
    gpu.preprocess(&pp, bp.as_ref(), &np, &pyr, &f.depth, &f.rgba)
        .unwrap();
    let proj = s.project_params(&se3::inverse_rigid(gt_at(&gt, predict_at).unwrap()));
    s.backend.predict(&proj, &pyr).unwrap();
    gpu.predict(&proj, &pyr).unwrap();
    (s, gt)
}

/// pyramid_model against its twin, through `predict` with the robust profile's three
/// levels: each coarser level copies the finer level's pixel (2u, 2v), bit for bit, on
/// both backends.
fn pyramid_model_matches_twin(mut gpu: GpuBackend) {
    let (mut s, _) = robust_pyramids_on_both(&mut gpu, 6, 6);
    for level in 0..3 {
        let k = s.level_intrinsics(level);
        let (cv, cn) = s.backend.download_prediction(level).unwrap();
        let (gv, gn) = gpu.download_prediction(level).unwrap();
        assert_eq!(
            (cv.len(), gv.len()),
            (k.pixels(), k.pixels()),
            "level {level}"
        );
        check_vec4_map(&format!("level {level} predicted vertex"), &cv, &gv, 0.0);
        check_vec4_map(&format!("level {level} predicted normal"), &cn, &gn, 0.0);
        if level > 0 {
            // The twin's rule on its own finer level.
            let (fv, _) = s.backend.download_prediction(level - 1).unwrap();
            let fine_w = s.level_intrinsics(level - 1).width as usize;
            let (u, v) = (k.width as usize / 2, k.height as usize / 2);
            assert_eq!(cv[v * k.width as usize + u], fv[2 * v * fine_w + 2 * u]);
        }
    }
    assert!(gpu.download_prediction(3).unwrap().0.is_empty());
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
        assert_eq!(ip.width as usize * ip.height as usize, pixels);
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
        let allowed = (c.inliers as f64 * INLIER_FRACTION_TOL).ceil() as u64;
        assert!(
            c.inliers.abs_diff(g.inliers) <= allowed,
            "level {level}: inliers {} vs {}",
            c.inliers,
            g.inliers
        );
        assert!(
            ata <= SYSTEM_REL_TOL && atb <= SYSTEM_REL_TOL,
            "level {level}"
        );
        let (xc, xg) = (c.solve().unwrap(), g.solve().unwrap());
        let dx: f64 = (0..6).map(|k| (xc[k] - xg[k]).powi(2)).sum::<f64>().sqrt();
        assert!(
            dx <= INCREMENT_TOL,
            "level {level}: increments differ by {dx:e}"
        );
    }
    // A level the pyramid does not have is an argument error, not a panic.
    assert!(matches!(
        gpu.icp_system(3, &s.icp_params(2, &t)),
        Err(Error::Argument(_))
    ));
}

/// Stride of [`interleaved`]: 64 surfels apart in the original order are neighbours in the
/// new one, so a map of 73,000 surfels puts each original 1024-surfel block across all
/// of them.
const INTERLEAVE_STRIDE: usize = 64;

/// `m` reordered: every `stride`-th surfel from 0, then every `stride`-th from 1, and so
/// on, so surfels made from neighbouring pixels (neighbours in append order) end up far
/// apart in the map.
fn interleaved(m: &SurfelMap, stride: usize) -> SurfelMap {
    let order: Vec<usize> = (0..stride)
        .flat_map(|r| (r..m.len()).step_by(stride))
        .collect();
    SurfelMap {
        position_weight: order.iter().map(|&i| m.position_weight[i]).collect(),
        normal_frame: order.iter().map(|&i| m.normal_frame[i]).collect(),
        color: order.iter().map(|&i| m.color[i]).collect(),
    }
}

/// Sort key for order-independent map comparison: position bits, then frame.
fn surfel_key(m: &SurfelMap, i: usize) -> ([u32; 3], u32) {
    let p = m.position(i);
    (
        [p[0].to_bits(), p[1].to_bits(), p[2].to_bits()],
        m.last_frame(i),
    )
}

/// Compares surfel `ic` of `c` with `ig` of `g`.
fn check_surfel(what: &str, c: &SurfelMap, ic: usize, g: &SurfelMap, ig: usize) {
    let dp = (0..3)
        .map(|k| (c.position(ic)[k] - g.position(ig)[k]).abs())
        .fold(0.0, f32::max);
    let dn = (0..3)
        .map(|k| (c.normal(ic)[k] - g.normal(ig)[k]).abs())
        .fold(0.0, f32::max);
    let dc = (0..3)
        .map(|k| (c.color(ic)[k] - g.color(ig)[k]).abs())
        .fold(0.0, f32::max);
    let dw = (c.weight(ic) - g.weight(ig)).abs();
    let dr = (c.radius(ic) - g.radius(ig)).abs();
    let same = dp <= SURFEL_POS_TOL_M
        && dn <= NORMAL_TOL
        && dc <= SURFEL_COLOR_TOL
        && dw <= SURFEL_WEIGHT_REL_TOL * c.weight(ic)
        && dr <= SURFEL_RADIUS_TOL_M
        && c.last_frame(ic) == g.last_frame(ig);
    assert!(
        same,
        "{what}: cpu surfel {ic} {:?} n {:?} c {:?} w {} r {} f {} vs gpu surfel {ig} {:?} n {:?} c {:?} w {} r {} f {}",
        c.position(ic), c.normal(ic), c.color(ic), c.weight(ic), c.radius(ic), c.last_frame(ic),
        g.position(ig), g.normal(ig), g.color(ig), g.weight(ig), g.radius(ig), g.last_frame(ig)
    );
}

/// fuse_select (robust profile), fuse_merge, fuse_flags, prefix_sum and fuse_add against
/// their twins, for each profile: the association keys pixel by pixel; merged surfels
/// keep their index and appended ones are in append order, so the maps are compared slot
/// by slot.
/// With `chunk_surfels` (the GPU map's chunk size), both backends start from the map in
/// [`interleaved`] order, so neighbouring surfels lie in different chunks, and the test
/// checks that surfels are retired across chunks.
fn fuse_matches_twins(mut gpu: GpuBackend, profile: Profile, chunk_surfels: Option<usize>) {
    let params = SlamParams::profile(profile);
    let (mut s, gt) = cpu_map_from_gt(2, &params);
    let mut before = s.backend.download_map().unwrap();
    if chunk_surfels.is_some() {
        before = interleaved(&before, INTERLEAVE_STRIDE);
        s.backend.upload_map(&before).unwrap();
    }
    gpu.upload_map(&before).unwrap();
    let frame = load_frame(&root(), 3);
    let (pp, bp, np) = (
        s.preprocess_params(),
        s.bilateral_params(),
        s.normal_params(),
    );
    s.backend
        .preprocess(&pp, bp.as_ref(), &np, &[], &frame.depth, &frame.rgba)
        .unwrap();
    gpu.preprocess(&pp, bp.as_ref(), &np, &[], &frame.depth, &frame.rgba)
        .unwrap();
    let t_world_to_cam = se3::inverse_rigid(gt_at(&gt, 3).unwrap());
    let mut fp = s.fuse_params(&t_world_to_cam, 3);
    // The pipeline prunes only on the frames the unstable-surfel removal runs after; the
    // kernels are checked with the profile's scale whatever the frame.
    let removal_frame = params.fusion.unstable_removal.map_or(1, |r| r.every_frames);
    assert_eq!(
        s.fuse_params(&t_world_to_cam, removal_frame)
            .prune_radius_scale,
        params.fusion.prune_scale
    );
    if params.fusion.unstable_removal.is_some() {
        assert_eq!(fp.prune_radius_scale, 0.0, "frame 3 is not a removal frame");
    }
    fp.prune_radius_scale = params.fusion.prune_scale;
    if fp.association == ASSOCIATION_BEST_CANDIDATE {
        check_fuse_select(&mut gpu, &before, &s.backend.download_frame().unwrap(), &fp);
    }
    let n_cpu = s.backend.fuse(&fp).unwrap();
    let n_gpu = gpu.fuse(&fp).unwrap();
    let c = s.backend.download_map().unwrap();
    let g = gpu.download_map().unwrap();
    assert_eq!((c.len(), g.len()), (n_cpu, n_gpu));
    let merged = (0..before.len()).filter(|&i| c.last_frame(i) == 3).count();
    eprintln!(
        "fuse: {} surfels before, {merged} merged; after cpu {n_cpu}, gpu {n_gpu}",
        before.len()
    );
    assert!(merged > 1000, "too few merges for a real test");
    // The GPU's association keys of this fuse step (fuse_select's choices).
    let keys = gpu.download_assoc().unwrap();
    if fp.association == ASSOCIATION_BEST_CANDIDATE {
        // fuse_flags: a valid pixel that chose nothing is added unless a neighbour's merged
        // surfel covers it; the test must see such pixels.
        let nd = s.backend.download_frame().unwrap().normal_depth;
        let unchosen = (0..keys.len())
            .filter(|&p| keys[p] == 0 && nd[p][3] > 0.0)
            .count();
        let covered = unchosen - (n_gpu - before.len());
        eprintln!("fuse_flags: {unchosen} valid pixels chose nothing, {covered} covered");
        assert!(
            covered > 100,
            "too few neighbour-covered pixels for a real test"
        );
        // The index map fuse_select and fuse_add built for the next prediction, on each
        // backend against a fresh projection of its own map, then against each other.
        let fused_cpu = s.backend.index_map().to_vec();
        let fused_gpu = gpu.download_index_map().unwrap();
        let proj = s.project_params(&t_world_to_cam);
        check_fused_index_map(&c, before.len(), &fused_cpu, &proj);
        check_fused_index_map(&g, before.len(), &fused_gpu, &proj);
        check_index_maps("fused index map", &fused_cpu, &fused_gpu);
    }
    // fuse_prune (robust profile) retires duplicates: weight 0 and last frame 0.
    let retired = |m: &SurfelMap| {
        (0..before.len())
            .filter(|&i| m.weight(i) == 0.0 && m.last_frame(i) == 0 && before.weight(i) > 0.0)
            .count()
    };
    let (retired_cpu, retired_gpu) = (retired(&c), retired(&g));
    eprintln!("fuse_prune: retired cpu {retired_cpu}, gpu {retired_gpu}");
    if fp.prune_radius_scale > 0.0 {
        assert!(retired_cpu > 100, "too few retired surfels for a real test");
        // The merged surfel a duplicate is compared with may be in another GPU chunk.
        let allowed = (retired_cpu as f64 * MASK_MISMATCH_FRACTION).ceil() as usize;
        assert!(
            retired_cpu.abs_diff(retired_gpu) <= allowed,
            "retired cpu {retired_cpu} vs gpu {retired_gpu}"
        );
        if let Some(chunk) = chunk_surfels {
            // Retired surfels whose pixel chose a surfel in another GPU chunk: the merged
            // surfel they were compared with came from that chunk, via `merged`.
            let cam = [fp.fx, fp.fy, fp.cx, fp.cy];
            let across = (0..before.len())
                .filter(|&i| g.weight(i) == 0.0 && g.last_frame(i) == 0 && before.weight(i) > 0.0)
                .filter(|&i| {
                    let p = cpu::transform_point(&fp.t_world_to_cam, g.position(i).into());
                    cpu::project_to_pixel(cam, fp.width, fp.height, p)
                        .is_some_and(|pix| (keys[pix] as u32) as usize / chunk != i / chunk)
                })
                .count();
            eprintln!("fuse_prune: {across} of {retired_gpu} retired across GPU chunks");
            assert!(
                across > 10,
                "too few retirements across chunks for a real test"
            );
        }
    } else {
        assert_eq!((retired_cpu, retired_gpu), (0, 0), "pruning is off");
    }
    // Merge decisions on a threshold can flip for a few surfels (FMA); then the appended
    // sets differ by the same few pixels.
    let allowed = (before.len() as f64 * MASK_MISMATCH_FRACTION).ceil() as usize;
    let flips: Vec<usize> = (0..before.len())
        .filter(|&i| (c.last_frame(i) == 3) != (g.last_frame(i) == 3))
        .collect();
    assert!(
        flips.len() <= allowed,
        "{} merge decisions differ; first surfel {:?}",
        flips.len(),
        flips.first()
    );
    for i in (0..before.len()).filter(|i| !flips.contains(i)) {
        check_surfel("merged/kept surfel", &c, i, &g, i);
    }
    assert!(
        n_cpu.abs_diff(n_gpu) <= allowed,
        "surfel counts cpu {n_cpu} gpu {n_gpu}"
    );
    // New surfels lie in append order on both backends (fuse_flags + prefix_sum), so the
    // maps match slot by slot: the GPU map's bytes do not depend on thread order.
    if flips.is_empty() && n_cpu == n_gpu {
        for i in before.len()..n_cpu {
            check_surfel("appended surfel", &c, i, &g, i);
        }
    }
}

/// The index map a best-candidate fusion built (`fused`, on the CPU) against
/// project_model's of the fused `map` at the same view (`proj`): a surfel merged this frame
/// keys the pixel its centre projected to before the merge moved it, so a few pixels pick
/// another surfel, and none may pick a surfel past the map's end. The surfels fuse_add
/// appended (from `first_new` on) lie on their pixels' rays, so both maps agree where one
/// of them is nearest.
fn check_fused_index_map(map: &SurfelMap, first_new: usize, fused: &[u64], proj: &ProjectParams) {
    let n = fused.len();
    let mut fresh = vec![0u64; n];
    let whole = MapChunk::whole(map.len());
    let bounds = cpu::block_bounds::whole_map_bounds(&map.position_weight);
    let proj = ProjectParams {
        surfel_count: map.len() as u32,
        ..*proj
    };
    cpu::project_model::project_model(&proj, &whole, &bounds, &map.position_weight, &mut fresh);
    let surfel = |k: u64| (k != 0).then_some(k & 0xffff_ffff);
    assert!(
        fused
            .iter()
            .all(|&k| surfel(k).is_none_or(|i| (i as usize) < map.len())),
        "the fused index map names a surfel past the map's end"
    );
    let covered = fresh.iter().filter(|&&k| k != 0).count();
    let differ = (0..n)
        .filter(|&p| surfel(fused[p]) != surfel(fresh[p]))
        .count();
    let is_new = |k: u64| surfel(k).is_some_and(|i| i as usize >= first_new);
    let new_keys = (0..n).filter(|&p| is_new(fresh[p])).count();
    let new_differ = (0..n)
        .filter(|&p| is_new(fresh[p]) && surfel(fused[p]) != surfel(fresh[p]))
        .count();
    eprintln!(
        "fused index map: {differ} of {covered} covered pixels pick another surfel than a \
         fresh projection; {new_differ} of the {new_keys} that pick a new surfel differ"
    );
    assert!(covered > 1000, "too few keys for a real test");
    assert!(new_keys > 10, "too few new surfels for a real test");
    // The new surfel's depth is its pixel's measurement both ways, give or take the few
    // ULP of the trip through the pose and back, which can flip a near tie: the mask
    // allowance.
    assert!(
        new_differ as f64 <= (MASK_MISMATCH_FRACTION * new_keys as f64).ceil(),
        "fused index map: {new_differ} of {new_keys} new surfels' pixels differ"
    );
    assert!(
        differ as f64 <= FUSED_INDEX_MAP_MISMATCH_FRACTION * covered as f64,
        "fused index map: {differ} of {covered} pixels differ from a fresh projection"
    );
}

/// fuse_select's twin on `map` against the GPU's keys of its whole fuse step from the
/// same map and frame (`params`: the fuse step's, with `surfel_count` filled in here).
fn check_fuse_select(
    gpu: &mut GpuBackend,
    map: &SurfelMap,
    frame: &FrameMaps,
    params: &FuseParams,
) {
    let params = FuseParams {
        surfel_count: map.len() as u32,
        ..*params
    };
    let n = frame.normal_depth.len();
    let mut keys = vec![0u64; n];
    let mut index_map = vec![0u64; n];
    let whole = MapChunk::whole(map.len());
    let bounds = cpu::block_bounds::whole_map_bounds(&map.position_weight);
    cpu::fuse_select::fuse_select(
        &params,
        &frame.normal_depth,
        &whole,
        &bounds,
        &map.position_weight,
        &map.normal_frame,
        &map.color,
        &mut keys,
        &mut index_map,
    );
    // The index map it builds on the way is project_model's at the same view, key for key
    // (the same transform and projection functions).
    let proj = ProjectParams {
        t_world_to_cam: params.t_world_to_cam,
        fx: params.fx,
        fy: params.fy,
        cx: params.cx,
        cy: params.cy,
        width: params.width,
        height: params.height,
        surfel_count: params.surfel_count,
        _pad: 0,
    };
    let mut projected = vec![0u64; n];
    cpu::project_model::project_model(&proj, &whole, &bounds, &map.position_weight, &mut projected);
    assert!(
        projected.iter().filter(|&&k| k != 0).count() > 1000,
        "too few keys"
    );
    if let Some(p) = (0..n).find(|&p| index_map[p] != projected[p]) {
        panic!(
            "fuse_select's index map differs from project_model's at pixel {p}: {:#x} vs {:#x}",
            index_map[p], projected[p]
        );
    }
    gpu.upload_map(map).unwrap();
    gpu.fuse(&params).unwrap();
    let g = gpu.download_assoc().unwrap();
    assert_eq!(g.len(), keys.len(), "assoc sizes");
    // A pixel's choice: the surfel (low word) must match; the off-ray distance (high word,
    // inverted bits) within OFF_RAY_TOL_M. A choice may flip where a gate or two distances
    // tie within that (FMA): the mask allowance.
    let off_ray_m = |k: u64| f32::from_bits(!((k >> 32) as u32));
    let chosen = keys.iter().filter(|&&k| k != 0).count();
    let differ: Vec<usize> = (0..keys.len())
        .filter(|&p| {
            let (c, g) = (keys[p], g[p]);
            (c as u32) != (g as u32)
                || (c == 0) != (g == 0)
                || (c != 0 && (off_ray_m(c) - off_ray_m(g)).abs() > OFF_RAY_TOL_M)
        })
        .collect();
    eprintln!(
        "fuse_select: {chosen} of {} pixels chose a surfel; {} differ",
        keys.len(),
        differ.len()
    );
    assert!(chosen > 1000, "too few choices for a real test");
    let allowed = (keys.len() as f64 * MASK_MISMATCH_FRACTION).ceil() as usize;
    assert!(
        differ.len() <= allowed,
        "{} pixels chose differently; first pixel {:?}: cpu {:x} gpu {:x}",
        differ.len(),
        differ.first(),
        differ.first().map_or(0, |&p| keys[p]),
        differ.first().map_or(0, |&p| g[p])
    );
    // Put the map back for the caller's own fuse step.
    gpu.upload_map(map).unwrap();
}

/// Runs the `compact` step on both backends from the same `map` with `params`; checks
/// each kernel's output against its twin exactly (integer flags, offsets and count; the
/// scatter is a copy, so the compacted maps are bit-identical: same surfels, same order).
/// Returns the surfels kept.
fn check_compaction(gpu: &mut GpuBackend, map: &SurfelMap, params: &CompactParams) -> usize {
    let n = map.len();
    let params = CompactParams {
        surfel_count: n as u32,
        ..*params
    };
    // The twins, kernel by kernel.
    let mut flags = vec![0u32; n];
    cpu::compact_flags::compact_flags(
        &params,
        &MapChunk::whole(n),
        &map.position_weight,
        &map.normal_frame,
        &mut flags,
    );
    let mut offsets = vec![0u32; n];
    let mut kept = 0u32;
    cpu::prefix_sum::prefix_sum(&params, &flags, &mut offsets, &mut kept);
    // The plain running sum, so a bug shared by the twin and the shader shows too.
    let mut running = 0u32;
    for i in 0..n {
        assert_eq!(offsets[i], running, "twin prefix_sum at surfel {i}");
        running += flags[i];
    }
    assert_eq!(kept, running, "twin prefix_sum total");
    // The step on both backends.
    let mut c = CpuBackend::with_map(map.clone());
    let n_cpu = c.compact(&params).unwrap();
    gpu.upload_map(map).unwrap();
    let n_gpu = gpu.compact(&params).unwrap();
    let (g_flags, g_offsets) = gpu.download_compaction(n).unwrap();
    let first_diff = |a: &[u32], b: &[u32]| (0..n).find(|&i| a[i] != b[i]);
    if let Some(i) = first_diff(&flags, &g_flags) {
        panic!(
            "compact_flags: surfel {i} cpu {} gpu {}",
            flags[i], g_flags[i]
        );
    }
    if let Some(i) = first_diff(&offsets, &g_offsets) {
        panic!(
            "prefix_sum: surfel {i} cpu {} gpu {}",
            offsets[i], g_offsets[i]
        );
    }
    assert_eq!(
        (n_cpu, n_gpu),
        (kept as usize, kept as usize),
        "surfels kept (cpu step, gpu step) vs twin"
    );
    let (cm, gm) = (c.download_map().unwrap(), gpu.download_map().unwrap());
    assert_eq!(cm.len(), n_cpu);
    for i in 0..n_cpu {
        let same = cm.position_weight[i].map(f32::to_bits)
            == gm.position_weight[i].map(f32::to_bits)
            && cm.normal_frame[i] == gm.normal_frame[i]
            && cm.color[i].map(f32::to_bits) == gm.color[i].map(f32::to_bits);
        assert!(
            same,
            "compact_scatter: slot {i} cpu {:?} {:?} {:?} gpu {:?} {:?} {:?}",
            cm.position_weight[i],
            cm.normal_frame[i],
            cm.color[i],
            gm.position_weight[i],
            gm.normal_frame[i],
            gm.color[i]
        );
    }
    // The survivors are the flagged surfels in their order.
    let expected: Vec<usize> = (0..n).filter(|&i| flags[i] != 0).collect();
    for (slot, &i) in expected.iter().enumerate() {
        assert_eq!(
            cm.normal_frame[slot], map.normal_frame[i],
            "slot {slot} is surfel {i}"
        );
    }
    n_cpu
}

/// compact_flags, prefix_sum and compact_scatter against their twins on a real map: the
/// robust profile's fusion of bundled frames 1..=8 at ground truth without removal, then
/// removal after frame 8 with a short age limit (so part of the map goes), and with rules
/// that keep everything and remove every unstable surfel.
fn compaction_matches_twins(mut gpu: GpuBackend) {
    let mut params = SlamParams::profile(Profile::Robust);
    params.fusion.unstable_removal = None;
    let (mut s, _) = cpu_map_from_gt(8, &params);
    let map = s.backend.download_map().unwrap();
    let n = map.len();
    assert!(n > 2 * 4096, "a map over several texture rows ({n})");
    let rule = |stable_weight, max_age_frames| CompactParams {
        surfel_count: 0,
        frame_id: 8,
        stable_weight,
        max_age_frames,
    };
    let kept = check_compaction(&mut gpu, &map, &rule(3.0, 2));
    eprintln!("compaction: {n} surfels, {kept} kept (weight >= 3 or seen in frames 6..8)");
    assert!(
        kept < n && kept > n / 10,
        "a real test removes some: {kept} of {n}"
    );
    assert_eq!(check_compaction(&mut gpu, &map, &rule(0.0, 0)), n);
    let stable = (0..n)
        .filter(|&i| map.weight(i) >= 2.0 || map.last_frame(i) == 8)
        .count();
    assert_eq!(check_compaction(&mut gpu, &map, &rule(2.0, 0)), stable);
}

/// prefix_sum's chunking at sizes around its 256 threads (fewer surfels than threads, not a
/// multiple, one chunk each) on hand-made maps with a fixed pattern of stable surfels.
fn compaction_sizes_match_twins(mut gpu: GpuBackend) {
    for n in [1usize, 7, 255, 256, 257, 1000, 4097, 70_001] {
        let mut map = SurfelMap::default();
        for i in 0..n {
            // Every third surfel stable, every fifth recent: a pattern that is not periodic
            // in the chunk size.
            let weight = if i % 3 == 0 { 5.0 } else { 1.0 };
            let frame = if i % 5 == 0 { 100 } else { 1 };
            let x = i as f32 * 1e-3;
            map.push(
                [x, 0.5, 2.0],
                [0.0, 0.0, -1.0],
                [i as f32 % 255.0, 1.0, 2.0],
                weight,
                frame,
            );
        }
        let params = CompactParams {
            surfel_count: 0,
            frame_id: 100,
            stable_weight: 3.0,
            max_age_frames: 10,
        };
        let kept = check_compaction(&mut gpu, &map, &params);
        let expected = (0..n).filter(|i| i % 3 == 0 || i % 5 == 0).count();
        assert_eq!(kept, expected, "n = {n}");
    }
}

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
        let ds = rc.surfels.abs_diff(rg.surfels) as f64 / rc.surfels as f64;
        assert!(
            dm <= RUN_POSE_TOL_M && ddeg <= RUN_POSE_TOL_DEG,
            "frame {i}: poses differ by {:.4} mm / {ddeg:.5} deg",
            dm * 1e3
        );
        assert!(
            ds <= RUN_SURFEL_FRACTION_TOL,
            "frame {i}: surfels cpu {} gpu {}",
            rc.surfels,
            rg.surfels
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
        g.backend.surfel_count(),
        counters.readback_bytes,
        counters.submissions
    );
    assert!(rmse < GT_RMSE_MAX_M, "GPU RMSE {:.3} mm", rmse * 1e3);
}

/// A tiny initial capacity forces the map buffers to grow during fusion; the result is
/// the same map as the CPU's.
/// The compact step across map growth: from a tiny capacity, the robust profile with an
/// aggressive removal rule over bundled frames 1..=8 at ground truth (the map grows, the
/// compaction buffers follow, the two map sets swap every frame); the GPU's surfel counts
/// stay within the run tolerance of the CPU's and its map downloads at its count.
fn compaction_follows_map_growth(ctx: GpuContext) {
    let gpu = GpuBackend::with_initial_capacity(ctx, 1000).unwrap();
    let gt = load_gt(&root());
    let mut params = SlamParams {
        poses: PoseSource::GroundTruth,
        ..SlamParams::profile(Profile::Robust)
    };
    params.fusion.unstable_removal = Some(UnstableRemoval {
        stable_weight: 3.0,
        max_age_frames: 1,
        every_frames: 1,
    });
    let mut c = slam(CpuBackend::new(), params.clone());
    let mut g = slam(gpu, params);
    let mut obeyed = 0;
    for i in 1..=8 {
        let f = load_frame(&root(), i);
        let rc = c
            .process(i as u32, &f.depth, &f.rgba, gt_at(&gt, i))
            .unwrap();
        let rg = g
            .process(i as u32, &f.depth, &f.rgba, gt_at(&gt, i))
            .unwrap();
        let allowed = (rc.surfels as f64 * RUN_SURFEL_FRACTION_TOL).ceil() as usize;
        assert!(
            rc.surfels.abs_diff(rg.surfels) <= allowed,
            "frame {i}: surfels cpu {} gpu {}",
            rc.surfels,
            rg.surfels
        );
        let map = c.backend.map();
        obeyed += (0..map.len()).all(|k| map.last_frame(k) + 1 >= i as u32 || map.weight(k) >= 3.0)
            as usize;
    }
    assert_eq!(obeyed, 8, "every CPU map obeys the rule after each frame");
    assert!(g.backend.capacity() > 1000, "the map grew");
    assert_eq!(
        g.backend.download_map().unwrap().len(),
        g.backend.surfel_count()
    );
}

/// Map chunks small enough that a few bundled frames fill many of them, so every map
/// kernel runs across chunk boundaries (8 culling blocks per chunk).
const SMALL_CHUNK_SURFELS: usize = 8 * BLOCK_SURFELS as usize;

/// A backend whose map is made of [`SMALL_CHUNK_SURFELS`]-surfel chunks.
fn small_chunk_backend(ctx: GpuContext) -> GpuBackend {
    GpuBackend::with_map_layout(ctx, SMALL_CHUNK_SURFELS, SMALL_CHUNK_SURFELS).unwrap()
}

fn map_grows_from_a_tiny_capacity(ctx: GpuContext) {
    let gpu = GpuBackend::with_map_layout(ctx, 1000, SMALL_CHUNK_SURFELS).unwrap();
    // Slots come in whole culling blocks.
    assert_eq!(gpu.capacity(), BLOCK_SURFELS as usize);
    let gt = load_gt(&root());
    let params = SlamParams {
        poses: PoseSource::GroundTruth,
        ..SlamParams::profile(Profile::Assignment)
    };
    let mut c = slam(CpuBackend::new(), params.clone());
    let mut g = slam(gpu, params);
    for i in 1..=3 {
        let f = load_frame(&root(), i);
        c.process(i as u32, &f.depth, &f.rgba, gt_at(&gt, i))
            .unwrap();
        g.process(i as u32, &f.depth, &f.rgba, gt_at(&gt, i))
            .unwrap();
    }
    let cap = g.backend.capacity();
    eprintln!(
        "capacity grew 1024 -> {cap} in {} chunks; surfels cpu {} gpu {}",
        g.backend.map_chunks(),
        c.backend.surfel_count(),
        g.backend.surfel_count()
    );
    assert!(g.backend.map_chunks() > 1, "the map grew past one chunk");
    assert!(cap >= g.backend.surfel_count() + 76_800);
    let allowed = (c.backend.surfel_count() as f64 * RUN_SURFEL_FRACTION_TOL).ceil() as usize;
    assert!(c.backend.surfel_count().abs_diff(g.backend.surfel_count()) <= allowed);
    // The first frame's surfels survived every grow-by-copy: compare them sorted.
    let (cm, gm) = (
        c.backend.download_map().unwrap(),
        g.backend.download_map().unwrap(),
    );
    let first = |m: &SurfelMap| {
        let mut v: Vec<usize> = (0..m.len())
            .filter(|&i| m.weight(i) == 1.0 && m.last_frame(i) == 1)
            .collect();
        v.sort_by_key(|&i| surfel_key(m, i));
        v
    };
    let (fc, fg) = (first(&cm), first(&gm));
    assert!(fc.len() > 1000);
    assert!(
        fc.len().abs_diff(fg.len()) <= allowed,
        "{} vs {}",
        fc.len(),
        fg.len()
    );
    if fc.len() == fg.len() {
        for (&a, &b) in fc.iter().zip(&fg) {
            check_surfel("frame-1 surfel after growth", &cm, a, &gm, b);
        }
    }
}

/// A map capped below what the second frame may need fails with Error::Capacity naming
/// the surfels, bytes and limit, instead of writing out of bounds or dropping the frame.
fn map_capacity_error(ctx: GpuContext) {
    let gpu = GpuBackend::with_initial_capacity(ctx, 1000)
        .unwrap()
        .with_max_surfels(100_000);
    let gt = load_gt(&root());
    let params = SlamParams {
        poses: PoseSource::GroundTruth,
        ..SlamParams::profile(Profile::Assignment)
    };
    let mut g = slam(gpu, params);
    let f = load_frame(&root(), 1);
    // Frame 1: 0 + 76,800 pixels fit in 100,000.
    g.process(1, &f.depth, &f.rgba, gt_at(&gt, 1)).unwrap();
    let f = load_frame(&root(), 2);
    match g.process(2, &f.depth, &f.rgba, gt_at(&gt, 2)) {
        Err(Error::Capacity(msg)) => {
            eprintln!("{msg}");
            assert!(msg.contains("100000 surfels"), "{msg}");
        }
        other => panic!("expected Error::Capacity, got {other:?}"),
    }
}

/// A frame whose buffers do not match its stated size is a user error, not a panic or a
/// GPU fault; downloads before the first frame are empty, as on the CPU.
fn bad_frame_size_is_an_argument_error(mut gpu: GpuBackend) {
    assert_eq!(gpu.download_frame().unwrap(), Default::default());
    assert!(gpu.download_prediction(0).unwrap().0.is_empty());
    let s = slam(CpuBackend::new(), SlamParams::profile(Profile::Assignment));
    let (pp, np) = (s.preprocess_params(), s.normal_params());
    let short = vec![0u16; 100];
    match gpu.preprocess(&pp, None, &np, &[], &short, &vec![0u32; 100]) {
        Err(Error::Argument(msg)) => assert!(msg.contains("640x480"), "{msg}"),
        other => panic!("expected Error::Argument, got {other:?}"),
    }
    // The backend still works afterwards.
    let f = load_frame(&root(), 1);
    gpu.preprocess(&pp, None, &np, &[], &f.depth, &f.rgba)
        .unwrap();
    assert_eq!(gpu.download_frame().unwrap().vertex.len(), 320 * 240);
}

/// icp_reduce_final against its twin, bit for bit, over partials shaped as on lavapipe (16
/// workgroups) and on a GPU (1024): entries of mixed sign and magnitude (as AᵀA, Aᵀb,
/// counts and residuals are), so the order of the f32 adds shows in the result.
fn icp_reduce_final_matches_twin(ctx: GpuContext) {
    use wgslam::gpu::backend::bindings::ICP_REDUCE_FINAL;
    use wgslam::gpu::{GpuArray, Kernel, Readback};
    use wgslam::layout::ICP_SYSTEM_LEN;
    let kernel = Kernel::new(&ctx, "icp_reduce_final", &ICP_REDUCE_FINAL).unwrap();
    for groups in [1usize, 16, 1024] {
        let n = groups * ICP_SYSTEM_LEN;
        let partials: Vec<f32> = (0..n)
            .map(|i| {
                let x = ((i as u64 * 2_654_435_761) % 1_000_003) as f32 / 1_000_003.0 - 0.3;
                x * 10f32.powi((i % 7) as i32 - 3)
            })
            .collect();
        let twin = cpu::icp_reduce_final::icp_reduce_final(&partials);
        let input = GpuArray::from_slice(&ctx, "partials", &partials).unwrap();
        let mut system = GpuArray::<f32>::new(&ctx, "system", ICP_SYSTEM_LEN).unwrap();
        system.set_len(ICP_SYSTEM_LEN);
        let mut readback = Readback::new(&ctx, "system read-back", ICP_SYSTEM_LEN);
        let bg = kernel.bind_group(&ctx, &[input.binding(), system.binding()]);
        let mut enc = ctx.encoder("icp_reduce_final");
        {
            let mut pass = enc.begin_compute_pass(&Default::default());
            kernel.dispatch(&ctx, &mut pass, &bg, 1).unwrap();
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

// ---------------------------------------------------------------------------------------
// Culling by block boxes.

/// True when every surfel lies inside its block's box (`bounds` as the backends keep it).
fn surfels_in_their_boxes(map: &SurfelMap, bounds: &[[u32; 4]]) -> Result<(), String> {
    for i in 0..map.len() {
        let b = i / BLOCK_SURFELS as usize;
        let (lo, hi) = (
            cpu::decode_corner(bounds[2 * b]),
            cpu::decode_corner(bounds[2 * b + 1]),
        );
        let p = glam::Vec3::from(map.position(i));
        if p.cmplt(lo).any() || p.cmpgt(hi).any() {
            return Err(format!(
                "surfel {i} at {p} outside block {b}'s box {lo}..{hi}"
            ));
        }
    }
    Ok(())
}

/// Culling never drops a surfel that would land in the image: project_model's twin with
/// the real boxes gives the same index map as with boxes that hold the whole world, from
/// a pose that sees the map and from that pose tilted about its horizontal axis (a block
/// is a few image rows of one frame, so tilting moves some out of view while others stay)
/// and turned about its vertical axis until it faces away (where every block is culled):
/// the equality is tested where culling does something.
fn culling_is_conservative() {
    let params = SlamParams::profile(Profile::Robust);
    let (s, gt) = cpu_map_from_gt(4, &params);
    let map = s.backend.map();
    let whole = MapChunk::whole(map.len());
    let bounds = cpu::block_bounds::whole_map_bounds(&map.position_weight);
    surfels_in_their_boxes(map, &bounds).unwrap();
    // One box per block holding the whole world (1000 km either way).
    let corner = |x: f32| {
        let e = wgslam::layout::ordered_from_f32(x);
        [e, e, e, 0]
    };
    let world: Vec<[u32; 4]> = (0..bounds.len())
        .map(|e| corner(if e % 2 == 0 { -1.0e6 } else { 1.0e6 }))
        .collect();
    let t_seen = se3::inverse_rigid(gt_at(&gt, 6).unwrap());
    let blocks = bounds.len() / 2;
    let mut partial = 0;
    let tilt = |d: f64| {
        (
            format!("tilted {d} deg"),
            glam::DMat4::from_rotation_x(d.to_radians()),
        )
    };
    let turn = |d: f64| {
        (
            format!("turned {d} deg"),
            glam::DMat4::from_rotation_y(d.to_radians()),
        )
    };
    let poses = [
        turn(0.0),
        tilt(10.0),
        tilt(20.0),
        tilt(-20.0),
        turn(45.0),
        turn(180.0),
    ];
    for (i, (label, turn)) in poses.iter().enumerate() {
        let proj = wgslam::layout::ProjectParams {
            surfel_count: map.len() as u32,
            ..s.project_params(&(*turn * t_seen))
        };
        let n = (proj.width * proj.height) as usize;
        let splat = |b: &[[u32; 4]]| {
            let mut index = vec![0u64; n];
            cpu::project_model::project_model(&proj, &whole, b, &map.position_weight, &mut index);
            index
        };
        let (culled_index, full_index) = (splat(&bounds), splat(&world));
        let cam = [proj.fx, proj.fy, proj.cx, proj.cy];
        let culled = (0..blocks)
            .filter(|&b| {
                let (lo, hi) = (
                    cpu::decode_corner(bounds[2 * b]),
                    cpu::decode_corner(bounds[2 * b + 1]),
                );
                !cpu::block_visible(&proj.t_world_to_cam, cam, proj.width, proj.height, lo, hi)
            })
            .count();
        let covered = full_index.iter().filter(|&&k| k != 0).count();
        eprintln!("{label}: {culled} of {blocks} blocks culled; {covered} pixels covered");
        assert_eq!(
            culled_index, full_index,
            "{label}: culling changed the index map"
        );
        if i == 0 {
            assert!(covered > 1000, "the map is in view");
        }
        if i == poses.len() - 1 {
            assert_eq!(covered, 0, "facing away, nothing is in view");
            assert_eq!(culled, blocks, "facing away, every block is culled");
        }
        if culled > 0 && covered > 0 {
            partial += 1;
        }
    }
    assert!(
        partial > 0,
        "no pose culled some blocks with surfels in view"
    );
}

/// After a robust run (merges moving surfels, compaction, appends) every surfel lies in
/// its block's box on both backends, the GPU's map in small chunks.
fn block_boxes_hold_their_surfels(ctx: GpuContext) {
    let gt = load_gt(&root());
    let params = SlamParams::profile(Profile::Robust);
    let mut c = slam(CpuBackend::new(), params.clone());
    let mut g = slam(small_chunk_backend(ctx), params);
    let last = 12;
    for i in 1..=last {
        let f = load_frame(&root(), i);
        c.process(i as u32, &f.depth, &f.rgba, gt_at(&gt, i))
            .unwrap();
        g.process(i as u32, &f.depth, &f.rgba, gt_at(&gt, i))
            .unwrap();
    }
    // A predict refreshes the boxes of the blocks the last fusion appended to.
    let proj = c.project_params(&se3::inverse_rigid(gt_at(&gt, last).unwrap()));
    let pyramid = c.pyramid_levels();
    c.backend.predict(&proj, &pyramid).unwrap();
    g.backend.predict(&proj, &pyramid).unwrap();
    let cm = c.backend.download_map().unwrap();
    surfels_in_their_boxes(&cm, c.backend.block_bounds()).unwrap();
    let gm = g.backend.download_map().unwrap();
    let gb = g.backend.download_block_bounds().unwrap();
    surfels_in_their_boxes(&gm, &gb).unwrap();
    eprintln!(
        "{} / {} surfels in {} / {} blocks inside their boxes ({} GPU chunks)",
        cm.len(),
        gm.len(),
        cm.len().div_ceil(BLOCK_SURFELS as usize),
        gb.len() / 2,
        g.backend.map_chunks()
    );
}

fn main() -> ExitCode {
    common::harness::run(vec![
        gpu("preprocess_matches_twins", |ctx| {
            preprocess_matches_twins(gpu_backend(ctx))
        }),
        gpu("bilateral_filter_matches_twin", |ctx| {
            bilateral_filter_matches_twin(gpu_backend(ctx))
        }),
        gpu("predict_matches_twins", |ctx| {
            predict_matches_twins(gpu_backend(ctx))
        }),
        gpu("icp_system_matches_twin", |ctx| {
            icp_system_matches_twin(gpu_backend(ctx))
        }),
        gpu(
            "icp_reduce_final_matches_twin",
            icp_reduce_final_matches_twin,
        ),
        gpu("pyramid_depth_matches_twin", |ctx| {
            pyramid_depth_matches_twin(gpu_backend(ctx))
        }),
        gpu("pyramid_model_matches_twin", |ctx| {
            pyramid_model_matches_twin(gpu_backend(ctx))
        }),
        gpu("coarse_icp_systems_match_twin", |ctx| {
            coarse_icp_systems_match_twin(gpu_backend(ctx))
        }),
        gpu("fuse_matches_twins", |ctx| {
            fuse_matches_twins(gpu_backend(ctx), Profile::Assignment, None)
        }),
        gpu("robust_fuse_matches_twins", |ctx| {
            fuse_matches_twins(gpu_backend(ctx), Profile::Robust, None)
        }),
        gpu("compaction_matches_twins", |ctx| {
            compaction_matches_twins(gpu_backend(ctx))
        }),
        gpu("compaction_sizes_match_twins", |ctx| {
            compaction_sizes_match_twins(gpu_backend(ctx))
        }),
        plain("culling_is_conservative", culling_is_conservative),
        gpu(
            "block_boxes_hold_their_surfels",
            block_boxes_hold_their_surfels,
        ),
        gpu("predict_matches_twins_in_small_chunks", |ctx| {
            predict_matches_twins(small_chunk_backend(ctx))
        }),
        gpu("robust_fuse_matches_twins_in_small_chunks", |ctx| {
            fuse_matches_twins(
                small_chunk_backend(ctx),
                Profile::Robust,
                Some(SMALL_CHUNK_SURFELS),
            )
        }),
        gpu("compaction_matches_twins_in_small_chunks", |ctx| {
            compaction_matches_twins(small_chunk_backend(ctx))
        }),
        gpu("tracked_run_matches_cpu_and_ground_truth", |ctx| {
            tracked_run_matches_cpu_and_ground_truth(gpu_backend(ctx))
        }),
        gpu(
            "map_grows_from_a_tiny_capacity",
            map_grows_from_a_tiny_capacity,
        ),
        gpu("map_capacity_error", map_capacity_error),
        gpu(
            "compaction_follows_map_growth",
            compaction_follows_map_growth,
        ),
        gpu("bad_frame_size_is_an_argument_error", |ctx| {
            bad_frame_size_is_an_argument_error(gpu_backend(ctx))
        }),
    ])
}
