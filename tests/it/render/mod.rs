//! Renderer tests: ground truth against the bundled real frames, determinism, the depth
//! test's key order, overlays, trajectory plots, bad input, and (with a GPU) GPU-vs-CPU
//! parity. Set `WGSLAM_RENDER_OUT=DIR` to keep the pictures for a look.

use crate::common;

use std::path::{Path, PathBuf};

use common::frames::{load_frame, load_gt, Frame};
use common::harness::{gpu, plain, skipped};
use common::wgsl::{self, rust_layout};
use glam::{DMat4, DVec3};
use libtest_mimic::Completion;
use wgslam::cpu::depth_to_vertex::depth_to_vertex;
use wgslam::cpu::vertex_to_normal::vertex_to_normal;
use wgslam::geometry::camera::Intrinsics;
use wgslam::gpu::GpuContext;
use wgslam::layout::{pack_rgba8, NormalParams, PreprocessParams};
use wgslam::render::{self, Cloud, MapCloud, RenderCamera, RenderSettings, View};
use wgslam::slam::map::SurfelMap;

/// Ground-truth poses (`t_cam_to_world`) of the bundled frames that have one, in frame
/// order (frame 0 has none, so `[0]` is frame 1).
fn gt_poses(root: &Path) -> Vec<(usize, DMat4)> {
    load_gt(root)
        .into_iter()
        .enumerate()
        .filter_map(|(i, t)| Some((i, t?)))
        .collect()
}

/// Intrinsics, then camera-frame vertex, normal and colour maps (row-major `[f32; 4]`).
type Maps = (Intrinsics, Vec<[f32; 4]>, Vec<[f32; 4]>, Vec<[f32; 4]>);

/// Camera-frame vertex, normal and colour maps of frame `i`, downsampled by `stride`.
fn frame_maps(root: &Path, i: usize, stride: u32) -> Maps {
    let k = Intrinsics::ICL_NUIM.downsampled(stride);
    let Frame { depth, rgba } = load_frame(root, i);
    let pp = PreprocessParams {
        fx: k.fx,
        fy: k.fy,
        cx: k.cx,
        cy: k.cy,
        width: k.width,
        height: k.height,
        raw_width: 640,
        raw_height: 480,
        stride,
        depth_scale: 5000.0,
        min_depth_m: 0.1,
        max_depth_m: 10.0,
    };
    let n = k.pixels();
    let (mut vmap, mut cmap, mut nmap) = (vec![[0.0; 4]; n], vec![[0.0; 4]; n], vec![[0.0; 4]; n]);
    depth_to_vertex(&pp, &depth, &rgba, &mut vmap, &mut cmap);
    let np = NormalParams {
        width: k.width,
        height: k.height,
        max_depth_jump_m: 0.1,
        _pad: 0,
    };
    vertex_to_normal(&np, &vmap, &mut nmap);
    (k, vmap, nmap, cmap)
}

/// A surfel map from the bundled frames `frames` at their ground-truth poses (no fusion:
/// every pixel with a normal becomes a surfel; weight = position in `frames` + 1).
fn bundled_map(frames: &[usize], stride: u32) -> SurfelMap {
    let root = common::bundled_icl();
    let gt = gt_poses(&root);
    let mut map = SurfelMap::default();
    for (fi, &i) in frames.iter().enumerate() {
        let t = gt.iter().find(|(j, _)| *j == i).expect("gt pose").1;
        let (_, vmap, nmap, cmap) = frame_maps(&root, i, stride);
        for pix in 0..vmap.len() {
            if vmap[pix][3] > 0.0 && nmap[pix][3] > 0.0 {
                let p = t.transform_point3(DVec3::new(
                    vmap[pix][0] as f64,
                    vmap[pix][1] as f64,
                    vmap[pix][2] as f64,
                ));
                let n = t.transform_vector3(DVec3::new(
                    nmap[pix][0] as f64,
                    nmap[pix][1] as f64,
                    nmap[pix][2] as f64,
                ));
                map.push(
                    p.as_vec3().to_array(),
                    n.as_vec3().to_array(),
                    [cmap[pix][0], cmap[pix][1], cmap[pix][2]],
                    (fi + 1) as f32,
                    i as u32,
                );
            }
        }
    }
    map
}

/// Where to keep pictures, when asked.
fn out_dir() -> Option<PathBuf> {
    std::env::var_os("WGSLAM_RENDER_OUT").map(PathBuf::from)
}

fn keep(name: &str, img: &image::RgbImage) {
    if let Some(d) = out_dir() {
        std::fs::create_dir_all(&d).unwrap();
        render::write_png(&d.join(name), img).unwrap();
    }
}

/// Fraction of pixels that differ from `bg`.
fn coverage(img: &image::RgbImage, bg: [u8; 3]) -> f64 {
    img.pixels().filter(|p| p.0 != bg).count() as f64 / (img.width() * img.height()) as f64
}

fn render_from_the_frames_own_pose_matches_its_photo() {
    // Ground truth: the map of frame 1 seen from frame 1's pose with the dataset intrinsics
    // is (nearly) frame 1's own colour image.
    let root = common::bundled_icl();
    let map = bundled_map(&[1], 1);
    let t = gt_poses(&root)[0].1;
    let camera = RenderCamera {
        t_cam_to_world: t,
        intrinsics: Intrinsics::ICL_NUIM,
    };
    let settings = RenderSettings::default();
    let img = render::render_cpu(
        &MapCloud::new(&map).cloud(),
        &camera,
        View::Color,
        &settings,
    )
    .unwrap();
    keep("own_pose_color.png", &img);
    let photo = image::open(root.join("rgb/1.png")).unwrap().into_rgb8();
    // Pixels of the photo with no normal (image border, depth jumps) stay background.
    let mut diffs: Vec<f64> = Vec::new();
    let mut background = 0usize;
    for (a, b) in img.pixels().zip(photo.pixels()) {
        if a.0 == settings.background {
            background += 1;
            continue;
        }
        let d: i32 = (0..3).map(|c| (a.0[c] as i32 - b.0[c] as i32).abs()).sum();
        diffs.push(d as f64 / 3.0);
    }
    diffs.sort_by(f64::total_cmp);
    let median = diffs[diffs.len() / 2];
    let frac_bg = background as f64 / img.pixels().len() as f64;
    // Splats of neighbouring pixels overlap (radius >= 0.75 px), so a pixel may show its
    // neighbour's colour: a median colour error of a few levels is expected, not 0.
    const MAX_MEDIAN_LEVELS: f64 = 4.0;
    // Border pixels and occlusion edges have no normal and so no surfel.
    const MAX_BACKGROUND: f64 = 0.05;
    assert!(
        median <= MAX_MEDIAN_LEVELS,
        "median colour error {median} levels"
    );
    assert!(
        frac_bg <= MAX_BACKGROUND,
        "{frac_bg} of the pixels are background"
    );
}

fn renders_are_deterministic_and_views_differ() {
    let map = bundled_map(&[1, 10, 20], 4);
    let map_cloud = MapCloud::new(&map);
    let cloud = map_cloud.cloud();
    let up_fwd =
        render::trajectory_view_hint(&[gt_poses(&common::bundled_icl())[0].1], -480.0).unwrap();
    let camera =
        render::default_camera(&map.position_weight, 320, 240, up_fwd.0, up_fwd.1, true).unwrap();
    let settings = RenderSettings::default();
    let mut seen = Vec::new();
    for view in [View::Color, View::Normals, View::Weight, View::Depth] {
        let a = render::render_cpu(&cloud, &camera, view, &settings).unwrap();
        let b = render::render_cpu(&cloud, &camera, view, &settings).unwrap();
        assert!(
            a == b,
            "{} view differs between two identical renders",
            view.name()
        );
        keep(&format!("default_{}.png", view.name()), &a);
        // The default view frames the map: a good part of the picture, not a dot.
        let cov = coverage(&a, settings.background);
        const MIN_COVERAGE: f64 = 0.10;
        assert!(cov > MIN_COVERAGE, "{} view covers only {cov}", view.name());
        seen.push(a);
    }
    for i in 0..seen.len() {
        for j in i + 1..seen.len() {
            assert!(seen[i] != seen[j], "views {i} and {j} are the same picture");
        }
    }
}

fn nearest_surfel_wins_and_ties_go_to_the_larger_index() {
    // Three surfels on the optical axis: 0 at 2 m, 1 at 1 m, 2 at 1 m (tie with 1).
    let positions = [
        [0.0, 0.0, 2.0, 1.0],
        [0.0, 0.0, 1.0, 1.0],
        [0.0, 0.0, 1.0, 1.0],
    ];
    let colors = [
        [255.0, 0.0, 0.0, 255.0],
        [0.0, 255.0, 0.0, 255.0],
        [0.0, 0.0, 255.0, 255.0],
    ];
    let cloud = Cloud {
        positions: &positions,
        normals: None,
        colors: Some(&colors),
        weights: None,
    };
    let camera = RenderCamera {
        t_cam_to_world: DMat4::IDENTITY,
        intrinsics: render::framing_intrinsics(9, 9, false),
    };
    let params =
        render::render_params(&cloud, &camera, View::Color, &RenderSettings::default()).unwrap();
    let (index_map, rgba) = render::render_cpu_raw(&params, &cloud);
    let centre = 4 * 9 + 4;
    assert_eq!(
        index_map[centre] & 0xffff_ffff,
        2,
        "tie must go to the larger index"
    );
    assert_eq!(f32::from_bits(!((index_map[centre] >> 32) as u32)), 1.0);
    assert_eq!(rgba[centre], pack_rgba8([0, 0, 255]));
    assert_eq!(rgba[0], pack_rgba8([255, 255, 255]), "corner is background");
}

fn overlay_shows_both_clouds_and_alignment_changes_it() {
    // Two real frames' point clouds (camera frames); the ground-truth relative pose aligns
    // frame 20 (source) onto frame 1 (target).
    let root = common::bundled_icl();
    let gt = gt_poses(&root);
    let pose = |i: usize| gt.iter().find(|(j, _)| *j == i).unwrap().1;
    let pts = |i| {
        let (_, v, _, _) = frame_maps(&root, i, 4);
        v.into_iter().filter(|p| p[3] > 0.0).collect::<Vec<_>>()
    };
    let (src, tgt) = (pts(20), pts(1));
    let t_true = pose(1).inverse() * pose(20);
    let camera = render::overlay_camera(
        &src,
        &tgt,
        &DMat4::IDENTITY,
        (320, 240),
        DVec3::Z,
        DVec3::Y,
        true,
    )
    .unwrap();
    let settings = RenderSettings::default();
    let before = render::render_overlay(&src, &tgt, &DMat4::IDENTITY, &camera, &settings).unwrap();
    let after = render::render_overlay(&src, &tgt, &t_true, &camera, &settings).unwrap();
    keep("overlay_before.png", &before);
    keep("overlay_after.png", &after);
    for (name, img) in [("before", &before), ("after", &after)] {
        let count = |c: [u8; 3]| img.pixels().filter(|p| p.0 == c).count();
        // Each cloud must be clearly visible: a few percent of the picture at least.
        const MIN_SHARE: f64 = 0.02;
        let n = (img.width() * img.height()) as f64;
        assert!(
            count(render::SOURCE_RGB) as f64 / n > MIN_SHARE,
            "{name}: source hardly visible"
        );
        assert!(
            count(render::TARGET_RGB) as f64 / n > MIN_SHARE,
            "{name}: target hardly visible"
        );
    }
    assert!(before != after, "the alignment did not change the overlay");
}

fn missing_attributes_fall_back_to_depth_and_say_so() {
    let positions = [[0.0, 0.0, 1.0, 1.0]];
    let cloud = Cloud {
        positions: &positions,
        normals: None,
        colors: None,
        weights: None,
    };
    for view in [View::Color, View::Normals, View::Weight] {
        let (used, why) = cloud.usable_view(view);
        assert_eq!(used, View::Depth);
        assert!(why.unwrap().contains("no "), "{view:?}");
    }
    assert_eq!(cloud.usable_view(View::Depth), (View::Depth, None));
    let camera = RenderCamera {
        t_cam_to_world: DMat4::IDENTITY,
        intrinsics: render::framing_intrinsics(16, 16, false),
    };
    let img =
        render::render_cpu(&cloud, &camera, View::Normals, &RenderSettings::default()).unwrap();
    assert!(coverage(&img, [255, 255, 255]) > 0.0, "the point is drawn");
}

fn bad_sizes_and_clouds_are_refused() {
    for s in [
        "0x10",
        "10x0",
        "20000x10",
        "10",
        "axb",
        "16384x16384",
        "-5x5",
    ] {
        assert!(render::parse_size(s).is_err(), "{s} accepted");
    }
    assert_eq!(render::parse_size("960x720").unwrap(), (960, 720));
    assert!(render::framing_camera(&[], 64, 64, DVec3::Z, DVec3::Y, false).is_err());
    let nan = [[f32::NAN, 0.0, 1.0, 1.0]];
    assert!(render::framing_camera(&nan, 64, 64, DVec3::Z, DVec3::Y, false).is_err());
    assert!(render::framing_camera(&[[0.0; 4]], 64, 64, DVec3::Z, DVec3::Z, false).is_err());
    // Mismatched attribute lengths are an error, not a panic.
    let positions = [[0.0, 0.0, 1.0, 1.0], [0.0, 0.0, 2.0, 1.0]];
    let colors = [[0.0; 4]];
    let cloud = Cloud {
        positions: &positions,
        normals: None,
        colors: Some(&colors),
        weights: None,
    };
    let camera = RenderCamera {
        t_cam_to_world: DMat4::IDENTITY,
        intrinsics: render::framing_intrinsics(16, 16, false),
    };
    assert!(render::render_cpu(&cloud, &camera, View::Color, &RenderSettings::default()).is_err());
    // NaN and far-off points are skipped, not drawn across the picture.
    let wild = [
        [f32::NAN, 0.0, 1.0, 1.0],
        [1.0e9, 0.0, 1.0, 1.0],
        [f32::INFINITY; 4],
    ];
    let cloud = Cloud {
        positions: &wild,
        normals: None,
        colors: None,
        weights: None,
    };
    let settings = RenderSettings {
        far_m: Some(10.0),
        ..RenderSettings::default()
    };
    let img = render::render_cpu(&cloud, &camera, View::Depth, &settings).unwrap();
    assert_eq!(coverage(&img, [255, 255, 255]), 0.0);
}

fn trajectory_plot_picks_the_horizontal_axes_and_is_deterministic() {
    let root = common::bundled_icl();
    let gt: Vec<(f64, DMat4)> = gt_poses(&root)
        .into_iter()
        .map(|(i, t)| (i as f64, t))
        .collect();
    // A made-up estimate: the ground truth with a growing offset.
    let est: Vec<(f64, DMat4)> = gt
        .iter()
        .enumerate()
        .map(|(k, (s, t))| {
            (
                *s,
                DMat4::from_translation(DVec3::new(0.002 * k as f64, 0.0, 0.0)) * *t,
            )
        })
        .collect();
    let pts: Vec<DVec3> = gt.iter().map(|(_, t)| t.w_axis.truncate()).collect();
    let pairs = wgslam::render::plot::associate(&est, &gt);
    assert_eq!(pairs.len(), est.len());
    let last = pairs.last().unwrap();
    assert!(((last.1 - last.2).length() - 0.002 * (est.len() - 1) as f64).abs() < 1e-9);
    let axes = wgslam::render::plot::horizontal_axes(&pts);
    // ICL-NUIM's first frames move mostly in x and z, y is vertical.
    assert_eq!(axes, (0, 2), "axes chosen: {axes:?}");
    let a = wgslam::render::plot::trajectory_plot(&est, &gt, (900, 400)).unwrap();
    let b = wgslam::render::plot::trajectory_plot(&est, &gt, (900, 400)).unwrap();
    assert!(a == b, "two plots of the same input differ");
    keep("trajectory.png", &a);
    // Both series are drawn in their colours, and text (dark pixels) is present.
    let has = |c: [u8; 3]| a.pixels().any(|p| p.0 == c);
    assert!(has([220, 60, 30]) && has([30, 90, 200]));
    let dark = a.pixels().filter(|p| p.0.iter().all(|&v| v < 60)).count();
    const MIN_TEXT_PIXELS: usize = 2000;
    assert!(
        dark > MIN_TEXT_PIXELS,
        "only {dark} dark pixels: labels missing?"
    );
    // Without ground truth it still draws, and refuses an empty estimate.
    wgslam::render::plot::trajectory_plot(&est, &[], (900, 400)).unwrap();
    assert!(wgslam::render::plot::trajectory_plot(&[], &gt, (900, 400)).is_err());
    assert!(wgslam::render::plot::trajectory_plot(&est, &gt, (0, 400)).is_err());
}

fn render_args(map: &Path, out: &Path) -> wgslam::cli::render::RenderArgs {
    wgslam::cli::render::RenderArgs {
        map: map.to_path_buf(),
        pose: None,
        view: "color".into(),
        size: "320x240".into(),
        camera: "icl".into(),
        up: "y".into(),
        splat_radius: 0.01,
        no_cull: false,
        backend: wgslam::slam::any_backend::BackendChoice::Cpu,
        out: out.to_path_buf(),
    }
}

fn render_command_writes_pngs_and_refuses_bad_input() {
    use wgslam::cli::render::run_render;
    let dir = common::temp_dir("render-cli");
    let map = bundled_map(&[1, 20], 4);
    let ply = dir.join("map.ply");
    wgslam::io::ply::write_surfel_map(&ply, &map).unwrap();

    let out = dir.join("out.png");
    for view in ["color", "normals", "weight", "depth"] {
        let mut args = render_args(&ply, &out);
        args.view = view.into();
        let report = run_render(&args).unwrap();
        assert_eq!(report.view.name(), view);
        assert!(report.warnings.is_empty(), "{:?}", report.warnings);
        let img = image::open(&out).unwrap().into_rgb8();
        assert_eq!(img.dimensions(), (320, 240));
        assert!(
            coverage(&img, [255, 255, 255]) > 0.1,
            "{view} view nearly empty"
        );
    }
    // Auto: the GPU when there is one, else the CPU with a warning; same size either way.
    let mut args = render_args(&ply, &out);
    args.backend = wgslam::slam::any_backend::BackendChoice::Auto;
    let report = run_render(&args).unwrap();
    eprintln!(
        "auto backend drew on {}: {:?}",
        report.backend, report.warnings
    );
    assert_eq!(
        image::open(&out).unwrap().into_rgb8().dimensions(),
        (320, 240)
    );
    // From a TUM line and from a TUM file: frame 1's pose.
    let mut args = render_args(&ply, &out);
    args.pose = Some("1 0 0 -2.25 0 0 0 1".into());
    run_render(&args).unwrap();
    let gt_file = common::bundled_icl().join("livingRoom2.gt.freiburg");
    args.pose = Some(gt_file.to_string_lossy().into_owned());
    run_render(&args).unwrap();

    // Bad input: each is an error, none panics, and the output is not touched.
    std::fs::remove_file(&out).unwrap();
    let bad_pose = |p: &str| {
        let mut a = render_args(&ply, &out);
        a.pose = Some(p.into());
        a
    };
    let not_ply = dir.join("not.ply");
    std::fs::write(&not_ply, "hello\n").unwrap();
    let empty_ply = dir.join("empty.ply");
    std::fs::write(
        &empty_ply,
        "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\nproperty float z\nend_header\n",
    )
    .unwrap();
    let cases: Vec<(&str, wgslam::cli::render::RenderArgs)> = vec![
        ("missing file", render_args(&dir.join("nope.ply"), &out)),
        ("not a PLY", render_args(&not_ply, &out)),
        ("no vertex", render_args(&empty_ply, &out)),
        ("pose with 3 fields", bad_pose("1 2 3")),
        ("pose not numbers", bad_pose("a b c d e f g h")),
        ("pose with zero quaternion", bad_pose("1 0 0 0 0 0 0 0")),
        ("zero size", {
            let mut a = render_args(&ply, &out);
            a.size = "0x100".into();
            a
        }),
        ("enormous size", {
            let mut a = render_args(&ply, &out);
            a.size = "100000x100".into();
            a
        }),
        ("unknown view", {
            let mut a = render_args(&ply, &out);
            a.view = "fancy".into();
            a
        }),
        ("bad up axis", {
            let mut a = render_args(&ply, &out);
            a.up = "w".into();
            a
        }),
        (
            "output dir missing",
            render_args(&ply, &dir.join("no/such/dir/out.png")),
        ),
    ];
    for (what, args) in cases {
        match run_render(&args) {
            Ok(_) => panic!("{what}: accepted"),
            Err(e) => eprintln!("{what}: {e}"),
        }
        assert!(!out.exists(), "{what}: output written");
    }
}

fn render_command_draws_a_bare_point_cloud_and_says_what_is_missing() {
    use wgslam::cli::render::run_render;
    let dir = common::temp_dir("render-bare");
    let map = bundled_map(&[1], 4);
    let mut text = format!(
        "ply\nformat ascii 1.0\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\nend_header\n",
        map.len()
    );
    for p in &map.position_weight {
        text.push_str(&format!("{} {} {}\n", p[0], p[1], p[2]));
    }
    let ply = dir.join("bare.ply");
    std::fs::write(&ply, text).unwrap();
    let out = dir.join("bare.png");
    let mut args = render_args(&ply, &out);
    args.view = "normals".into();
    let report = run_render(&args).unwrap();
    assert_eq!(report.view, View::Depth);
    let all = report.warnings.join(" | ");
    for what in ["normals", "colours", "weights"] {
        assert!(all.contains(what), "warnings do not mention {what}: {all}");
    }
    let img = image::open(&out).unwrap().into_rgb8();
    keep("bare_depth.png", &img);
    assert!(coverage(&img, [255, 255, 255]) > 0.1);
}

fn run_and_icp_outputs_are_written() {
    use wgslam::render::outputs::{write_icp_overlays, write_map_renders, OverlayViewpoint};
    let dir = common::temp_dir("render-outputs");
    let root = common::bundled_icl();
    let gt: Vec<(f64, DMat4)> = gt_poses(&root)
        .into_iter()
        .filter(|(i, _)| *i <= 20)
        .map(|(i, t)| (i as f64, t))
        .collect();
    let map = bundled_map(&[1, 10, 20], 4);
    let k = Intrinsics::ICL_NUIM.downsampled(2);
    let written =
        write_map_renders(&render::RenderBackend::Cpu, &dir, &map, &gt, &k, (320, 240)).unwrap();
    assert_eq!(written.len(), 4);
    for p in &written {
        let img = image::open(p).unwrap().into_rgb8();
        assert!(
            coverage(&img, [255, 255, 255]) > 0.1,
            "{} nearly empty",
            p.display()
        );
        keep(&p.file_name().unwrap().to_string_lossy(), &img);
    }
    let pts = |i| {
        let (_, v, _, _) = frame_maps(&root, i, 4);
        v
    };
    let t_true = gt[0].1.inverse() * gt.last().unwrap().1;
    let [before, after] = write_icp_overlays(
        &dir,
        &pts(20),
        &pts(1),
        &DMat4::IDENTITY,
        &t_true,
        OverlayViewpoint::Camera { fy_negative: true },
    )
    .unwrap();
    assert!(before.is_file() && after.is_file());
    // An empty map is refused.
    assert!(write_map_renders(
        &render::RenderBackend::Cpu,
        &dir,
        &SurfelMap::default(),
        &gt,
        &k,
        (320, 240)
    )
    .is_err());
}

/// `RenderParams` is declared in both render kernels (not in common.wgsl): both match Rust.
fn render_params_layout_matches_both_shaders() {
    use wgslam::gpu::shaders;
    use wgslam::render::layout::RenderParams;
    let rust = rust_layout!(RenderParams {
        t_world_to_cam,
        fx,
        fy,
        cx,
        cy,
        width,
        height,
        surfel_count,
        view,
        splat_radius_m,
        min_radius_px,
        max_radius_px,
        cull_backfaces,
        near_m,
        far_m,
        weight_max,
        background,
    });
    let mut failures = Vec::new();
    for kernel in ["render_splat", "render_resolve"] {
        let module = wgsl::parse(kernel, &shaders::source(kernel));
        failures.extend(wgsl::layout_mismatches(kernel, &module, &rust));
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// Pixels whose winning surfel may differ between GPU and CPU: a pixel centre exactly on a
/// splat's rim can fall in or out depending on fused multiply-add in `du*du + dv*dv` and in
/// the projection (lavapipe fuses, Rust does not). Measured on lavapipe: 0 of 76,800
/// pixels in each of the 8 renders below.
const MAX_INDEX_MISMATCH_FRACTION: f64 = 0.002;
/// Depth in the keys: the transform's multiply-adds may be fused on the GPU.
const MAX_DEPTH_ULPS: i64 = 4;
/// Colour channels may differ by one level where `(n + 1) * 127.5 + 0.5` or a ramp lands
/// within an ulp of a rounding boundary and the GPU fuses the multiply-add.
const MAX_CHANNEL_DIFF: i32 = 1;
/// ... and only on a tiny fraction of the pixels (measured on lavapipe: at most 1 pixel
/// of 76,800 per render, in the depth view).
const MAX_COLOUR_DIFF_FRACTION: f64 = 0.001;

fn gpu_matches_cpu_on_a_small_map(ctx: GpuContext) -> Completion {
    use wgslam::render::gpu::GpuRenderer;
    let renderer = match GpuRenderer::new(&ctx) {
        Ok(r) => r,
        Err(e) if !wgslam::gpu::test_support::gpu_required() => {
            return skipped(format!("the adapter cannot run the renderer: {e}"));
        }
        Err(e) => panic!("{e}"),
    };
    let root = common::bundled_icl();
    let map = bundled_map(&[1, 10, 20], 2);
    let map_cloud = MapCloud::new(&map);
    let cloud = map_cloud.cloud();
    let (up, heading) = render::trajectory_view_hint(&[gt_poses(&root)[0].1], -480.0).unwrap();
    let cameras = [
        (
            "default",
            render::default_camera(&map.position_weight, 320, 240, up, heading, true).unwrap(),
        ),
        (
            "own pose",
            RenderCamera {
                t_cam_to_world: gt_poses(&root)[0].1,
                intrinsics: Intrinsics::ICL_NUIM.downsampled(2),
            },
        ),
    ];
    for (name, camera) in &cameras {
        for view in [View::Color, View::Normals, View::Weight, View::Depth] {
            let params =
                render::render_params(&cloud, camera, view, &RenderSettings::default()).unwrap();
            let (cpu_idx, cpu_rgba) = render::render_cpu_raw(&params, &cloud);
            let (gpu_idx, gpu_rgba) = renderer.render_raw(&ctx, &params, &cloud).unwrap();
            let mut index_mismatch = 0usize;
            let mut colour_diff = 0usize;
            let mut first = None;
            for pix in 0..cpu_idx.len() {
                // The winning surfel (or emptiness) must match; its depth (high word) may
                // differ by a few ulps (the GPU fuses the transform's multiply-adds).
                let (kc, kg) = (cpu_idx[pix], gpu_idx[pix]);
                let same_surfel = (kc == 0 && kg == 0)
                    || (kc != 0 && kg != 0 && kc & 0xffff_ffff == kg & 0xffff_ffff);
                if !same_surfel {
                    index_mismatch += 1;
                    first.get_or_insert((pix, kc, kg));
                    continue;
                }
                let depth_bits = |k: u64| !((k >> 32) as u32) as i64;
                assert!(
                    kc == 0 || (depth_bits(kc) - depth_bits(kg)).abs() <= MAX_DEPTH_ULPS,
                    "{name}/{}: pixel {pix} depth CPU {kc:x} GPU {kg:x}",
                    view.name()
                );
                let (a, b) = (cpu_rgba[pix], gpu_rgba[pix]);
                colour_diff += (a != b) as usize;
                for c in 0..4 {
                    let d = ((a >> (8 * c)) & 255) as i32 - ((b >> (8 * c)) & 255) as i32;
                    assert!(
                        d.abs() <= MAX_CHANNEL_DIFF,
                        "{name}/{}: pixel {pix} CPU {a:08x} GPU {b:08x}",
                        view.name()
                    );
                }
            }
            let frac = index_mismatch as f64 / cpu_idx.len() as f64;
            let colour_frac = colour_diff as f64 / cpu_idx.len() as f64;
            eprintln!(
                "{name}/{}: {colour_diff} pixels off by one level",
                view.name()
            );
            assert!(
                colour_frac <= MAX_COLOUR_DIFF_FRACTION,
                "{name}/{}: {colour_diff} pixels differ in colour",
                view.name()
            );
            eprintln!(
                "{name}/{}: {index_mismatch} index mismatches ({frac:.5})",
                view.name()
            );
            assert!(
                frac <= MAX_INDEX_MISMATCH_FRACTION,
                "{name}/{}: {index_mismatch} pixels differ, first {first:?} (pixel, CPU key, GPU key)",
                view.name()
            );
            // Determinism on the GPU as well: the atomics make the winner order-independent.
            let (gpu_idx2, gpu_rgba2) = renderer.render_raw(&ctx, &params, &cloud).unwrap();
            assert!(
                gpu_idx2 == gpu_idx && gpu_rgba2 == gpu_rgba,
                "GPU render not repeatable"
            );
        }
    }
    Completion::Completed
}

fn lidar_overlay_from_above() {
    use wgslam::render::outputs::{write_icp_overlays, OverlayViewpoint};
    let data = common::scans::fast_gicp_dir();
    let read = |name: &str| -> Vec<[f32; 4]> {
        let c = wgslam::scan::read::read_cloud(&data.join(name)).unwrap();
        c.points.iter().map(|p| [p[0], p[1], p[2], 1.0]).collect()
    };
    let (target, source) = (read("251370668.pcd"), read("251371071.pcd"));
    let t = wgslam::scan::read::read_matrix4(&data.join("relative.txt")).unwrap();
    let dir = common::temp_dir("render-lidar");
    let [before, after] = write_icp_overlays(
        &dir,
        &source,
        &target,
        &DMat4::IDENTITY,
        &t,
        OverlayViewpoint::TopDown { up: DVec3::Z },
    )
    .unwrap();
    for p in [&before, &after] {
        let img = image::open(p).unwrap().into_rgb8();
        keep(
            &format!("lidar_{}", p.file_name().unwrap().to_string_lossy()),
            &img,
        );
        let n = (img.width() * img.height()) as f64;
        let count = |c: [u8; 3]| img.pixels().filter(|q| q.0 == c).count() as f64 / n;
        // Sparse scans seen from tens of metres: each cloud still covers a visible share.
        const MIN_SHARE: f64 = 0.005;
        assert!(count(render::SOURCE_RGB) > MIN_SHARE && count(render::TARGET_RGB) > MIN_SHARE);
    }
}

pub fn tests() -> Vec<common::harness::Test> {
    vec![
        plain(
            "render_from_the_frames_own_pose_matches_its_photo",
            render_from_the_frames_own_pose_matches_its_photo,
        ),
        plain(
            "renders_are_deterministic_and_views_differ",
            renders_are_deterministic_and_views_differ,
        ),
        plain(
            "nearest_surfel_wins_and_ties_go_to_the_larger_index",
            nearest_surfel_wins_and_ties_go_to_the_larger_index,
        ),
        plain(
            "overlay_shows_both_clouds_and_alignment_changes_it",
            overlay_shows_both_clouds_and_alignment_changes_it,
        ),
        plain(
            "missing_attributes_fall_back_to_depth_and_say_so",
            missing_attributes_fall_back_to_depth_and_say_so,
        ),
        plain(
            "bad_sizes_and_clouds_are_refused",
            bad_sizes_and_clouds_are_refused,
        ),
        plain(
            "trajectory_plot_picks_the_horizontal_axes_and_is_deterministic",
            trajectory_plot_picks_the_horizontal_axes_and_is_deterministic,
        ),
        plain(
            "render_command_writes_pngs_and_refuses_bad_input",
            render_command_writes_pngs_and_refuses_bad_input,
        ),
        plain(
            "render_command_draws_a_bare_point_cloud_and_says_what_is_missing",
            render_command_draws_a_bare_point_cloud_and_says_what_is_missing,
        ),
        plain(
            "run_and_icp_outputs_are_written",
            run_and_icp_outputs_are_written,
        ),
        plain(
            "render_params_layout_matches_both_shaders",
            render_params_layout_matches_both_shaders,
        ),
        gpu(
            "gpu_matches_cpu_on_a_small_map",
            gpu_matches_cpu_on_a_small_map,
        ),
        plain("lidar_overlay_from_above", lidar_overlay_from_above),
    ]
}
