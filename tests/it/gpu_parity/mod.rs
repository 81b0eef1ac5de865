//! Each WGSL kernel against its CPU twin on real ICL-NUIM frames from `assets/`, a whole
//! tracked run on both backends (and the GPU run against the real ground truth), and the
//! GPU map's growth and capacity error. Every trial shows as ignored without a GPU adapter
//! (tests/it/common/harness.rs). One module per pipeline step; this one holds the
//! tolerances and the helpers they share.

mod compact;
mod fuse;
mod icp;
mod loops;
mod map;
mod predict;
mod preprocess;
mod run;

use crate::common;

use common::frames::{gt_at, load_frame, load_gt, Frame};
use common::harness::gpu_backend;
use glam::DMat4;
use wgslam::geometry::camera::Intrinsics;
use wgslam::geometry::se3;
use wgslam::gpu::{GpuBackend, GpuContext};
use wgslam::layout::map::SurfelMap;
use wgslam::layout::BLOCK_SURFELS;
use wgslam::slam::backend::{Backend, Inspect, PreprocessSteps};
use wgslam::slam::cpu_backend::CpuBackend;
use wgslam::slam::params::{PoseSource, Profile, SlamParams};
use wgslam::slam::pipeline::Slam;
use wgslam::tools::compare::tolerance;

pub fn tests() -> Vec<common::harness::Test> {
    [
        preprocess::tests(),
        predict::tests(),
        icp::tests(),
        loops::tests(),
        fuse::tests(),
        compact::tests(),
        map::tests(),
        run::tests(),
    ]
    .into_iter()
    .flatten()
    .collect()
}

// ---------------------------------------------------------------------------------------
// Tolerances (each with its reason). Where `wgslam compare` has the same bound
// (`wgslam::tools::compare::tolerance`, documented there) it is used, converted to these files' units.

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
/// Solved increments (radians and metres mixed) at level 0. Where both backends keep the
/// same rows they agree within 1e-7 (f32 against f64 sums); a row whose gate (distance,
/// angle) falls the other way on a knife edge, which [`INLIER_FRACTION_TOL`] allows, moves
/// more: on bundled frame 4 with the robust profile's raw-depth points 4 of 71,138 rows
/// moved Aᵀb by 5e-5 relative and the increment by 2.3e-6 (lavapipe). 5e-6 (5
/// micrometres / microradians) is 2x that and half the robust profile's convergence
/// threshold (`icp.min_increment`, 1e-5).
const INCREMENT_TOL: f64 = 5e-6;
/// Solved increments at a coarser pyramid level (1, 2): a level-l system sums 4^l times
/// fewer rows, so each row's own rounding (its residual carries a few ULP of the
/// positions, ~4e-6 m, independent from row to row) weighs 2^l more in Aᵀb, and where the
/// residuals are small (a pose near the truth) it dominates: at level 2 (2,920 rows, RMS
/// residual 0.4 mm) Aᵀb differs by 1.8e-4 relative, what that estimate gives, and the
/// increment by 5.9e-6 (measured on lavapipe, bundled frame 4, model fused from raw
/// depth). A coarse increment only starts the finer level, whose own check is
/// [`INCREMENT_TOL`]; 1e-5 (10 micrometres) is a 1,600th of a level-2 pixel at 1 m
/// (17 mm at ICL-NUIM's focal length).
const COARSE_INCREMENT_TOL: f64 = 1e-5;

/// The increment tolerance at pyramid level `level`.
fn increment_tol(level: usize) -> f64 {
    match level {
        0 => INCREMENT_TOL,
        _ => COARSE_INCREMENT_TOL,
    }
}
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
    Slam::new(backend, Intrinsics::ICL_NUIM, params.validate().unwrap())
}

/// `preprocess` of `frame` with `steps` on both backends.
fn preprocess_both(
    cpu: &mut impl Backend,
    gpu: &mut GpuBackend,
    steps: &PreprocessSteps,
    frame: &Frame,
) {
    cpu.preprocess(steps, &frame.depth, &frame.rgba).unwrap();
    gpu.preprocess(steps, &frame.depth, &frame.rgba).unwrap();
}

/// Counts mask mismatches and panics (naming the first pixels) past the allowance.
/// A count the backends may differ in by at most `fraction` of the CPU's (rounded up): the
/// tolerance constant passed says why they may differ at all.
fn check_count(what: &str, cpu: usize, gpu: usize, fraction: f64) {
    let allowed = (cpu as f64 * fraction).ceil() as usize;
    assert!(
        cpu.abs_diff(gpu) <= allowed,
        "{what}: cpu {cpu} vs gpu {gpu}, more than {allowed} apart"
    );
}

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
    let steps = s.preprocess_steps();
    preprocess_both(&mut s.backend, gpu, &steps, &f);
    let proj = s.project_params(&se3::inverse_rigid(gt_at(&gt, predict_at).unwrap()));
    s.backend.predict(&proj, &steps.pyramid).unwrap();
    gpu.predict(&proj, &steps.pyramid).unwrap();
    (s, gt)
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

/// Map chunks small enough that a few bundled frames fill many of them, so every map
/// kernel runs across chunk boundaries (8 culling blocks per chunk).
const SMALL_CHUNK_SURFELS: usize = 8 * BLOCK_SURFELS as usize;

/// A backend whose map is made of [`SMALL_CHUNK_SURFELS`]-surfel chunks.
fn small_chunk_backend(ctx: GpuContext) -> GpuBackend {
    GpuBackend::with_map_layout(ctx, SMALL_CHUNK_SURFELS, SMALL_CHUNK_SURFELS).unwrap()
}
