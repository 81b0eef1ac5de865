//! The frame's preprocessing on both backends: depth_to_vertex and vertex_to_normal,
//! bilateral_filter and pyramid_depth against their twins, fern_encode (the relocalisation
//! code of the preprocessed frame), keypoint_detect and keypoint_describe (feature-based
//! relocalisation) against their twins, and a frame of the wrong size.

use super::{check_vec4_map, preprocess_both, root, slam};
use super::{FILTERED_VERTEX_TOL_M, NORMAL_TOL, VERTEX_TOL_M};
use crate::common::frames::{load_frame, Frame};
use crate::common::harness::{gpu_backend_test, Test};
use crate::common::{level_0, unfiltered_level_0};
use bytemuck::Zeroable;
use std::collections::BTreeSet;
use wgslam::cpu::binding::Binding;
use wgslam::cpu::fern_encode::fern_encode;
use wgslam::cpu::keypoint_describe::keypoint_describe;
use wgslam::cpu::keypoint_detect::keypoint_detect;
use wgslam::geometry::camera::Intrinsics;
use wgslam::gpu::GpuBackend;
use wgslam::layout::{Keypoint, KeypointParams, DESCRIPTOR_WORDS, FERN_NO_DEPTH};
use wgslam::slam::backend::{Backend, FrameMaps, Inspect, PreprocessSteps, ToDescribe};
use wgslam::slam::cpu_backend::CpuBackend;
use wgslam::slam::features;
use wgslam::slam::keyframes::KeyframeDatabase;
use wgslam::slam::params::{BilateralSettings, Profile, SlamParams};
use wgslam::slam::pipeline::Slam;
use wgslam::Error;

/// The frame's maps on the CPU and the GPU after `preprocess` with `params`, and the
/// steps `steps_of` made for the CPU pipeline (both backends run them).
fn maps_on_both(
    gpu: &mut GpuBackend,
    params: SlamParams,
    frame: &Frame,
    steps_of: fn(&Slam<CpuBackend>) -> PreprocessSteps,
) -> (FrameMaps, FrameMaps, PreprocessSteps) {
    let s = slam(CpuBackend::new(), params);
    let steps = steps_of(&s);
    let mut cpu_b = s.backend;
    preprocess_both(&mut cpu_b, gpu, &steps, frame);
    let c = cpu_b.download_frame().unwrap();
    (c, gpu.download_frame().unwrap(), steps)
}

/// depth_to_vertex and vertex_to_normal against their twins, at downsample 2 and 1.
fn preprocess_matches_twins(mut gpu: GpuBackend) {
    let frame = load_frame(&root(), 5);
    for downsample in [2, 1] {
        let mut params = SlamParams::profile(Profile::Assignment);
        params.input.downsample = downsample;
        let (c, g, _) = maps_on_both(&mut gpu, params, &frame, unfiltered_level_0);
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
/// matches the twin, and the normals are made from it; `normal_depth` carries the raw
/// depth (the default) or with `filter_points` the filtered one, on both backends; at
/// downsample 2 and 1, with the default 3x3 window and depth-dependent sigma and with
/// KinectFusion's 7x7 window and constant 30 mm sigma.
fn bilateral_filter_matches_twin(mut gpu: GpuBackend) {
    let frame = load_frame(&root(), 5);
    let kinect_fusion = BilateralSettings {
        radius_px: 3,
        sigma_space_px: 2.25,
        sigma_depth_m: 0.03,
        sigma_depth_per_m2: 0.0,
        filter_points: true,
    };
    let filtered_points = BilateralSettings {
        filter_points: true,
        ..BilateralSettings::default()
    };
    for (downsample, settings) in [
        (2, BilateralSettings::default()),
        (1, BilateralSettings::default()),
        (2, filtered_points),
        (2, kinect_fusion),
    ] {
        let mut params = SlamParams::profile(Profile::Assignment);
        params.input.downsample = downsample;
        params.bilateral = Some(settings);
        let (c, g, steps) = maps_on_both(&mut gpu, params, &frame, level_0);
        assert!(steps.bilateral.is_some());
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
        // normal_depth carries the points' depth: the filtered map's with `filter_points`,
        // else the unfiltered one's; the GPU's within the filtered vertices' bound.
        let points = match settings.filter_points {
            true => &c.filtered_vertex,
            false => &c.vertex,
        };
        for (i, (nd, g_nd)) in c.normal_depth.iter().zip(&g.normal_depth).enumerate() {
            if nd[3] > 0.0 {
                assert_eq!(nd[3], points[i][2], "{tag}: pixel {i}");
            }
            if nd[3] > 0.0 && g_nd[3] > 0.0 {
                let diff = (nd[3] - g_nd[3]).abs();
                assert!(
                    diff <= FILTERED_VERTEX_TOL_M,
                    "{tag}: pixel {i} depth {diff}"
                );
            }
        }
    }
    // Back to the filter off: the frame has no filtered map again.
    let s = slam(CpuBackend::new(), SlamParams::profile(Profile::Assignment));
    let steps = unfiltered_level_0(&s);
    gpu.preprocess(&steps, &frame.depth, &frame.rgba).unwrap();
    assert!(gpu.download_frame().unwrap().filtered_vertex.is_empty());
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
        let steps = s.preprocess_steps();
        assert_eq!(steps.pyramid.len(), 2);
        let level_intrinsics: Vec<Intrinsics> = (1..3).map(|l| s.level_intrinsics(l)).collect();
        let mut cpu_b = s.backend;
        preprocess_both(&mut cpu_b, &mut gpu, &steps, &frame);
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

/// fern_encode against its twin on the GPU's own level-0 maps of a real frame, at
/// downsample 2 and 1: every code equal (the twin compares sums of the same values in the
/// same order, so there is nothing to round differently), and the codes are not trivial
/// (several distinct codes, few cells without depth).
fn fern_encode_matches_twin(mut gpu: GpuBackend) {
    let frame = load_frame(&root(), 5);
    for downsample in [2, 1] {
        let mut params = SlamParams::profile(Profile::Robust);
        params.input.downsample = downsample;
        let s = slam(CpuBackend::new(), params.clone());
        let steps = unfiltered_level_0(&s);
        gpu.preprocess(&steps, &frame.depth, &frame.rgba).unwrap();
        let db = KeyframeDatabase::new(params.relocalisation.as_ref().unwrap());
        let fp = db.params(steps.params.camera.width, steps.params.camera.height);
        let g = gpu.encode_ferns(&fp, db.ferns()).unwrap();
        let maps = gpu.download_frame().unwrap();
        let mut c = vec![0; db.ferns().len()];
        fern_encode(&mut [
            Binding::of(&fp),
            Binding::read(db.ferns()),
            Binding::read(&maps.normal_depth),
            Binding::read(&maps.color),
            Binding::write(&mut c),
        ]);
        assert_eq!(c, g, "downsample {downsample}: fern codes differ");
        let distinct: std::collections::BTreeSet<u32> = c.iter().copied().collect();
        let no_depth = c.iter().filter(|&&x| x == FERN_NO_DEPTH).count();
        eprintln!(
            "downsample {downsample}: {} distinct codes, {no_depth} of {} ferns without depth",
            distinct.len(),
            c.len()
        );
        assert!(distinct.len() >= 8 && no_depth < c.len() / 10);
    }
}

/// Corners the two sides may find differently: a corner whose Harris response ties a
/// neighbour's within the f32 rounding that lavapipe's fused multiply-adds change (see
/// `cpu::keypoint_detect`). Allowed fraction of the corners; measured 0 on the test's frame.
const KEYPOINT_MISMATCH_FRACTION: f64 = 0.01;

/// keypoint_detect and keypoint_describe against their twins on the GPU's own level-0
/// maps of a real frame: the same corners (as sets: the GPU appends in no particular
/// order), and for the same keypoints the same descriptor bits and vertices exactly (box
/// sums of whole numbers; the vertex is a copy).
fn keypoint_kernels_match_twins(mut gpu: GpuBackend) {
    let frame = load_frame(&root(), 5);
    let params = SlamParams::profile(Profile::Robust);
    let s = slam(CpuBackend::new(), params);
    let steps = unfiltered_level_0(&s);
    gpu.preprocess(&steps, &frame.depth, &frame.rgba).unwrap();
    let maps = gpu.download_frame().unwrap();
    let pattern = features::pattern();
    let mut kp = KeypointParams {
        width: steps.params.camera.width,
        height: steps.params.camera.height,
        threshold: features::HARRIS_THRESHOLD,
        capacity: features::KEYPOINT_CAPACITY,
        count: 0,
        tests: pattern.len() as u32,
        _pad0: 0,
        _pad1: 0,
    };
    let (g, g_found) = gpu.detect_keypoints(&kp).unwrap();
    let mut c = vec![Keypoint::zeroed(); kp.capacity as usize];
    let mut counter = [0u32];
    keypoint_detect(&mut [
        Binding::of(&kp),
        Binding::read(&maps.color),
        Binding::read(&maps.normal_depth),
        Binding::write(&mut c),
        Binding::write(&mut counter),
    ]);
    c.truncate(counter[0] as usize);
    let key = |k: &Keypoint| (k.v, k.u);
    let gs: BTreeSet<_> = g.iter().map(key).collect();
    let cs: BTreeSet<_> = c.iter().map(key).collect();
    let differ = gs.symmetric_difference(&cs).count();
    eprintln!(
        "corners: gpu {g_found}, cpu {}, {differ} found by one side only",
        counter[0]
    );
    assert!(
        counter[0] > 50 && counter[0] < kp.capacity,
        "{}",
        counter[0]
    );
    assert!(differ as f64 <= KEYPOINT_MISMATCH_FRACTION * cs.len() as f64);
    // The same keypoints described on both sides.
    c.truncate(features::MAX_FEATURES);
    kp.count = c.len() as u32;
    let what = ToDescribe {
        params: &kp,
        keypoints: &c,
        pattern: &pattern,
    };
    let (gd, gp) = gpu.describe_keypoints(what).unwrap();
    let n = c.len();
    let mut cd = vec![0u32; n * DESCRIPTOR_WORDS];
    let mut cp = vec![[0.0f32; 4]; n];
    keypoint_describe(&mut [
        Binding::of(&kp),
        Binding::read(&maps.color),
        Binding::read(&maps.vertex),
        Binding::read(&c),
        Binding::read(&pattern),
        Binding::write(&mut cd),
        Binding::write(&mut cp),
    ]);
    assert_eq!(gd.concat(), cd, "descriptors differ");
    assert_eq!(gp, cp, "keypoint vertices differ");
    let distinct: BTreeSet<_> = gd.iter().collect();
    assert!(
        distinct.len() > n * 9 / 10,
        "descriptors are not distinctive"
    );
}

/// A frame whose buffers do not match its stated size is a user error, not a panic or a
/// GPU fault; downloads before the first frame are empty, as on the CPU.
fn bad_frame_size_is_an_argument_error(mut gpu: GpuBackend) {
    assert_eq!(gpu.download_frame().unwrap(), Default::default());
    assert!(gpu.download_prediction(0).unwrap().0.is_empty());
    let s = slam(CpuBackend::new(), SlamParams::profile(Profile::Assignment));
    let steps = unfiltered_level_0(&s);
    let short = vec![0u16; 100];
    match gpu.preprocess(&steps, &short, &vec![0u32; 100]) {
        Err(Error::Argument(msg)) => assert!(msg.contains("640x480"), "{msg}"),
        other => panic!("expected Error::Argument, got {other:?}"),
    }
    // The backend still works afterwards.
    let f = load_frame(&root(), 1);
    gpu.preprocess(&steps, &f.depth, &f.rgba).unwrap();
    assert_eq!(gpu.download_frame().unwrap().vertex.len(), 320 * 240);
}

pub(super) fn tests() -> Vec<Test> {
    vec![
        gpu_backend_test("preprocess_matches_twins", preprocess_matches_twins),
        gpu_backend_test(
            "bilateral_filter_matches_twin",
            bilateral_filter_matches_twin,
        ),
        gpu_backend_test("pyramid_depth_matches_twin", pyramid_depth_matches_twin),
        gpu_backend_test("fern_encode_matches_twin", fern_encode_matches_twin),
        gpu_backend_test("keypoint_kernels_match_twins", keypoint_kernels_match_twins),
        gpu_backend_test(
            "bad_frame_size_is_an_argument_error",
            bad_frame_size_is_an_argument_error,
        ),
    ]
}
