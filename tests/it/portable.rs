//! The portable GPU path (no 64-bit integers, see `shaders::PORTABLE_KERNELS`): each key
//! twin run with the portable key writer (`cpu::key_writer::KeyPass`, two passes) against
//! the same twin on 64-bit keys, bit for bit, on a real map with and without ties;
//! the device options; and whole GPU runs on the portable kernels against the 64-bit
//! kernels (equal poses and maps) and the ground truth.
//!
//! The portable kernels against their twins run in `gpu_parity` (and every other GPU
//! module) with `WGSLAM_GPU_FEATURES=portable`, as `.ci/run` does: those tests compare the
//! GPU with the twins on 64-bit keys, which the first test here proves equal to the twins
//! on portable keys.

use crate::common;
use crate::common::level_0;

use common::frames::{gt_at, load_frame, load_gt};
use common::harness::{gpu, plain, skipped, Test};
use libtest_mimic::Completion;
use wgslam::cpu;
use wgslam::cpu::binding::Binding;
use wgslam::dataset::{self, SequenceOptions};
use wgslam::geometry::camera::Intrinsics;
use wgslam::geometry::se3;
use wgslam::gpu::context::{DeviceOptions, GpuFeatures, GpuLimits};
use wgslam::gpu::{GpuBackend, GpuContext};
use wgslam::layout::map::SurfelMap;
use wgslam::layout::{Camera, MapChunk, NormalParams, PreprocessParams, ProjectParams};
use wgslam::render::{self, MapCloud, RenderCamera, RenderSettings, View};
use wgslam::slam::backend::{Backend, Inspect, PreprocessSteps};
use wgslam::slam::cpu_backend::CpuBackend;
use wgslam::slam::params::{PoseSource, Profile, SlamParams, ValidParams};
use wgslam::slam::pipeline::Slam;
use wgslam::tools::run;

/// Over the bundled frames a healthy tracker is at ~0.2 mm (clean, assignment profile) and
/// ~2.5 mm (noisy, robust profile); the bars of `end_to_end`.
const ATE_BUNDLED_MAX_M: f64 = 0.5e-3;
const ATE_BUNDLED_NOISY_MAX_M: f64 = 5e-3;

pub fn tests() -> Vec<Test> {
    vec![
        plain(
            "portable_twins_equal_the_64_bit_twins",
            portable_twins_equal_the_64_bit_twins,
        ),
        plain(
            "device_options_read_the_environment_names",
            device_options_read_the_environment_names,
        ),
        gpu(
            "webgpu_limits_device_has_the_defaults_and_no_features",
            webgpu_limits_device_has_the_defaults_and_no_features,
        ),
        gpu("portable_clean_run_equals_the_64_bit_run", |ctx| {
            portable_run_equals_the_64_bit_run(ctx, false)
        }),
        gpu("portable_noisy_robust_run_equals_the_64_bit_run", |ctx| {
            portable_run_equals_the_64_bit_run(ctx, true)
        }),
    ]
}

/// `map` followed by a copy of itself: every surfel has a twin at the same depth with a
/// larger index, so every pixel's choice is a tie the index must break.
fn doubled(map: &SurfelMap) -> SurfelMap {
    let twice = |v: &Vec<[u32; 4]>| [v.clone(), v.clone()].concat();
    SurfelMap {
        position_weight: [map.position_weight.clone(), map.position_weight.clone()].concat(),
        normal_frame: twice(&map.normal_frame),
        color: [map.color.clone(), map.color.clone()].concat(),
    }
}

/// The `(low, high)` word pairs of a portable map as the 64-bit keys they stand for.
fn as_keys(words: &[u32]) -> Vec<u64> {
    words
        .chunks_exact(2)
        .map(|w| (w[1] as u64) << 32 | w[0] as u64)
        .collect()
}

/// Panics naming the first pixel where the portable keys differ from the 64-bit ones.
fn check_equal(what: &str, keys: &[u64], portable_words: &[u32]) {
    let portable = as_keys(portable_words);
    assert_eq!(keys.len(), portable.len(), "{what}: sizes");
    if let Some(p) = (0..keys.len()).find(|&p| keys[p] != portable[p]) {
        panic!(
            "{what}: pixel {p}: 64-bit keys {:#x}, portable keys {:#x}",
            keys[p], portable[p]
        );
    }
    let set = keys.iter().filter(|&&k| k != 0).count();
    eprintln!("{what}: {set} of {} keys set, all equal", keys.len());
    assert!(set > 1000, "{what}: too few keys for a real test");
}

/// Each key twin with the portable key writer, run as the portable kernel is (pass 0 over
/// the map, then pass 1), leaves the same 64-bit keys as with 64-bit keys: project_model,
/// fuse_select (both maps), fuse_add (the index map, and the same new surfels) and
/// render_splat, on a map fused from bundled frames and on that map doubled (ties at every
/// pixel, broken towards the larger index).
fn portable_twins_equal_the_64_bit_twins() {
    let root = common::bundled_icl();
    let gt = load_gt(&root);
    let params = SlamParams {
        poses: PoseSource::GroundTruth,
        ..SlamParams::profile(Profile::Robust)
    };
    let mut s = Slam::new(
        CpuBackend::new(),
        Intrinsics::ICL_NUIM,
        params.validate().unwrap(),
    );
    for i in 1..=3 {
        let f = load_frame(&root, i);
        s.process(i as u32, &f.depth, &f.rgba, gt_at(&gt, i))
            .unwrap();
    }
    let fused = s.backend.download_map().unwrap();
    let frame = load_frame(&root, 5);
    let steps = level_0(&s);
    s.backend
        .preprocess(&steps, &frame.depth, &frame.rgba)
        .unwrap();
    let maps = s.backend.download_frame().unwrap();
    let t_cam_to_world = *gt_at(&gt, 5).unwrap();
    let t_world_to_cam = se3::inverse_rigid(&t_cam_to_world);

    for (name, map) in [("map", fused.clone()), ("doubled map", doubled(&fused))] {
        let n_surfels = map.len();
        let whole = MapChunk::whole(n_surfels);
        let bounds = cpu::block_bounds::whole_map_bounds(&map.position_weight);

        // project_model.
        let proj = ProjectParams {
            surfel_count: n_surfels as u32,
            ..s.project_params(&t_world_to_cam)
        };
        let pixels = (proj.camera.width * proj.camera.height) as usize;
        let mut keys = vec![0u64; pixels];
        crate::common::project_map(&proj, &map, None, Binding::write(&mut keys));
        let mut words = vec![0u32; 2 * pixels];
        for key_pass in 0..2 {
            crate::common::project_map(&proj, &map, None, Binding::key_pass(&mut words, key_pass));
        }
        check_equal(&format!("{name}: project_model"), &keys, &words);
        if name == "doubled map" {
            let first_copy = keys
                .iter()
                .filter(|&&k| k != 0 && ((k as u32) as usize) < n_surfels / 2)
                .count();
            assert_eq!(first_copy, 0, "ties go to the larger index (the copy)");
        }

        // fuse_select: the association and the index map.
        let mut fp = s.fuse_params(&t_world_to_cam, 5);
        fp.surfel_count = n_surfels as u32;
        fp.capacity = (n_surfels + pixels) as u32;
        let (mut assoc, mut index_map) = (vec![0u64; pixels], vec![0u64; pixels]);
        // fuse_select with its two key maps bound as `assoc` and `index_map`.
        let select = |assoc: Binding, index_map: Binding| {
            cpu::fuse_select::fuse_select(&mut [
                Binding::of(&fp),
                Binding::read(&maps.normal_depth),
                Binding::of(&whole),
                Binding::read(&bounds),
                Binding::read(&map.position_weight),
                Binding::read(&map.normal_frame),
                Binding::read(&map.color),
                assoc,
                index_map,
            ])
        };
        select(Binding::write(&mut assoc), Binding::write(&mut index_map));
        let (mut assoc_w, mut index_w) = (vec![0u32; 2 * pixels], vec![0u32; 2 * pixels]);
        for key_pass in 0..2 {
            select(
                Binding::key_pass(&mut assoc_w, key_pass),
                Binding::key_pass(&mut index_w, key_pass),
            );
        }
        check_equal(&format!("{name}: fuse_select assoc"), &assoc, &assoc_w);
        check_equal(
            &format!("{name}: fuse_select index map"),
            &index_map,
            &index_w,
        );

        // fuse_add: every pixel flagged, in append order, onto fuse_select's index map.
        let appended = (0..proj.camera.height)
            .flat_map(|v| (0..proj.camera.width).map(move |u| cpu::append_index([u, v])))
            .max()
            .unwrap()
            + 1;
        let flags = vec![1u32; appended];
        let offsets: Vec<u32> = (0..appended as u32).collect();
        let slots = n_surfels + appended;
        let add_chunk = MapChunk::whole(slots);
        let mut grown = map.clone();
        grown.position_weight.resize(slots, [0.0; 4]);
        grown.normal_frame.resize(slots, [0; 4]);
        grown.color.resize(slots, [0.0; 4]);
        fp.capacity = slots as u32;
        // fuse_add into a copy of the grown map, with the key map bound as `key_map`.
        let add = |out: &mut SurfelMap, key_map: Binding| {
            cpu::fuse_add::fuse_add(&mut [
                Binding::of(&fp),
                Binding::read(&maps.normal_depth),
                Binding::read(&maps.color),
                Binding::read(&flags),
                Binding::read(&offsets),
                Binding::of(&add_chunk),
                Binding::write(&mut out.position_weight),
                Binding::write(&mut out.normal_frame),
                Binding::write(&mut out.color),
                key_map,
            ])
        };
        let mut added = grown.clone();
        add(&mut added, Binding::write(&mut index_map));
        let mut added_portable = grown.clone();
        for key_pass in 0..2 {
            add(
                &mut added_portable,
                Binding::key_pass(&mut index_w, key_pass),
            );
        }
        check_equal(&format!("{name}: fuse_add index map"), &index_map, &index_w);
        let new_keys = index_map
            .iter()
            .filter(|&&k| k != 0 && (k as u32) as usize >= n_surfels)
            .count();
        assert!(
            new_keys > 1000,
            "{name}: only {new_keys} pixels keep a new surfel"
        );
        assert!(
            added.position_weight == added_portable.position_weight
                && added.normal_frame == added_portable.normal_frame
                && added.color == added_portable.color,
            "{name}: fuse_add's new surfels differ"
        );

        // render_splat, from the frame's own pose.
        let map_cloud = MapCloud::new(&map);
        let cloud = map_cloud.cloud();
        let camera = RenderCamera {
            t_cam_to_world,
            intrinsics: Intrinsics::ICL_NUIM.downsampled(2),
        };
        let rp = render::render_params(&cloud, &camera, View::Color, &RenderSettings::default())
            .unwrap();
        let (splat_keys, _) = render::render_cpu_raw(&rp, &cloud);
        let mut splat_words = vec![0u32; 2 * splat_keys.len()];
        for key_pass in 0..2 {
            cpu::render_splat::render_splat(&mut [
                Binding::of(&rp),
                Binding::read(cloud.positions),
                Binding::read(cloud.normals.unwrap_or(&[])),
                Binding::key_pass(&mut splat_words, key_pass),
            ]);
        }
        check_equal(&format!("{name}: render_splat"), &splat_keys, &splat_words);
    }
}

/// The environment variables take the command line's names, case-insensitively, and
/// refuse anything else naming the variable.
fn device_options_read_the_environment_names() {
    use clap::ValueEnum;
    assert_eq!(
        GpuFeatures::from_str("portable", true),
        Ok(GpuFeatures::Portable)
    );
    assert_eq!(GpuLimits::from_str("WebGPU", true), Ok(GpuLimits::Webgpu));
    let all = wgpu::Features::all();
    let portable = DeviceOptions {
        features: GpuFeatures::Portable,
        limits: GpuLimits::Adapter,
        ..DeviceOptions::default()
    };
    let f = portable.features_from(all);
    assert!(!f.contains(wgpu::Features::SHADER_INT64));
    assert!(!f.contains(wgpu::Features::SHADER_INT64_ATOMIC_MIN_MAX));
    assert!(f.contains(wgpu::Features::TIMESTAMP_QUERY));
    let webgpu = DeviceOptions {
        features: GpuFeatures::Auto,
        limits: GpuLimits::Webgpu,
        ..DeviceOptions::default()
    };
    assert_eq!(webgpu.features_from(all), wgpu::Features::empty());
    assert_eq!(
        webgpu.limits_from(wgpu::Limits::downlevel_defaults()),
        wgpu::Limits::default()
    );
    assert_eq!(
        DeviceOptions::default().features_from(all),
        wgslam::gpu::context::WANTED_FEATURES
    );
}

/// `--gpu-limits webgpu`: exactly WebGPU's default limits, no optional feature, so the
/// portable kernels; and a backend and the renderer build on it.
fn webgpu_limits_device_has_the_defaults_and_no_features(ctx: GpuContext) {
    drop(ctx);
    let ctx = GpuContext::with_options(DeviceOptions {
        features: GpuFeatures::Auto,
        limits: GpuLimits::Webgpu,
        ..DeviceOptions::default()
    })
    .expect("a device with WebGPU's default limits");
    assert_eq!(ctx.limits(), &wgpu::Limits::default());
    assert_eq!(ctx.features(), wgpu::Features::empty());
    assert!(!ctx.has_int64_atomics());
    wgslam::render::gpu::GpuRenderer::new(&ctx).expect("the renderer builds");
    GpuBackend::new(ctx).expect("the backend builds");
    // A long, thin image (10000 x 2) pads fusion's tiled per-pixel arrays past WebGPU's
    // 128 MiB storage buffers: the error names the image and what to do, not the array.
    let ctx = GpuContext::with_options(DeviceOptions {
        features: GpuFeatures::Auto,
        limits: GpuLimits::Webgpu,
        ..DeviceOptions::default()
    })
    .expect("a device with WebGPU's default limits");
    let mut gpu = GpuBackend::new(ctx).expect("the backend builds");
    let (w, h) = (10_000, 2);
    let params = PreprocessParams {
        camera: Camera::new(&Intrinsics {
            width: w,
            height: h,
            fx: 500.0,
            fy: 500.0,
            cx: 5000.0,
            cy: 1.0,
        }),
        raw_width: w,
        raw_height: h,
        stride: 1,
        depth_scale: 5000.0,
        min_depth_m: 0.1,
        max_depth_m: 10.0,
        _pad0: 0,
        _pad1: 0,
    };
    let steps = PreprocessSteps {
        params,
        bilateral: None,
        normal: NormalParams {
            width: w,
            height: h,
            max_depth_jump_m: 0.1,
            _pad: 0,
        },
        pyramid: vec![],
    };
    let n = (w * h) as usize;
    let err = gpu
        .preprocess(&steps, &vec![0; n], &vec![0; n])
        .expect_err("the frame buffers cannot fit");
    let msg = err.to_string();
    assert!(
        msg.contains("10000x2") && msg.contains("--downsample") && msg.contains("--backend cpu"),
        "{msg}"
    );
}

/// One GPU run over the bundled frames with `options`: per-frame poses, the map size and
/// ATE (aligned) against the ground truth.
fn gpu_run(options: DeviceOptions, noisy: bool) -> (Vec<glam::DMat4>, usize, f64) {
    let ctx = GpuContext::with_options(options).expect("GPU device");
    let backend = GpuBackend::new(ctx).expect("GPU backend");
    let (root, profile) = if noisy {
        (common::bundled_icl_noisy(), Profile::Robust)
    } else {
        (common::bundled_icl(), Profile::Assignment)
    };
    let seq = dataset::open(&root, &SequenceOptions::default()).unwrap();
    let last = seq.len() - 1;
    let r = run::run(
        backend,
        &seq,
        1,
        last,
        ValidParams::profile(profile),
        |_| {},
    )
    .unwrap();
    let poses = r.frames.iter().map(|f| f.report.t_cam_to_world).collect();
    let ate = r.metrics.accuracy.expect("ground truth").ate_rmse_aligned_m;
    (poses, r.map.len(), ate)
}

/// The portable kernels decide every key as the 64-bit ones do, so a whole run on them
/// gives the same poses, bit for bit, and the same map size; both track to the ground truth.
/// Clean frames with the assignment profile (project_model, fuse_merge), noisy frames with
/// the robust one (fuse_select, fuse_add). Skipped where the adapter has no 64-bit atomics
/// (nothing to compare with).
fn portable_run_equals_the_64_bit_run(ctx: GpuContext, noisy: bool) -> Completion {
    let int64 = {
        let full = GpuContext::with_options(DeviceOptions::default());
        full.map(|c| c.has_int64_atomics()).unwrap_or(false)
    };
    drop(ctx);
    if !int64 {
        return skipped("the adapter has no 64-bit atomics: no 64-bit run to compare with");
    }
    let (bar, what) = if noisy {
        (ATE_BUNDLED_NOISY_MAX_M, "noisy, robust")
    } else {
        (ATE_BUNDLED_MAX_M, "clean, assignment")
    };
    let (poses_64, surfels_64, ate_64) = gpu_run(DeviceOptions::default(), noisy);
    let portable = DeviceOptions {
        features: GpuFeatures::Portable,
        limits: GpuLimits::Adapter,
        ..DeviceOptions::default()
    };
    let (poses_32, surfels_32, ate_32) = gpu_run(portable, noisy);
    eprintln!(
        "bundled {what}: 64-bit ATE {:.4} mm, {surfels_64} surfels; portable ATE {:.4} mm, \
         {surfels_32} surfels",
        ate_64 * 1e3,
        ate_32 * 1e3
    );
    assert_eq!(poses_64.len(), poses_32.len());
    for (i, (a, b)) in poses_64.iter().zip(&poses_32).enumerate() {
        assert!(
            a.to_cols_array() == b.to_cols_array(),
            "frame {i}: poses differ: 64-bit {a:?}, portable {b:?}"
        );
    }
    assert_eq!(surfels_64, surfels_32, "map sizes");
    assert!(ate_32 < bar, "portable ATE {ate_32} m");
    Completion::Completed
}
