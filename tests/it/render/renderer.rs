//! The renderer on the CPU: ground truth against the bundled real frames, determinism, the
//! depth test's key order, overlays, fallbacks and bad input, and trajectory plots.

use crate::common;

use common::harness::{plain, Test};
use glam::{DMat4, DVec3};
use wgslam::geometry::camera::Intrinsics;
use wgslam::layout::pack_rgba8;
use wgslam::render::{self, Cloud, MapCloud, RenderCamera, RenderSettings, View};

use super::{bundled_map, coverage, frame_maps, gt_poses, keep};

/// A cloud of `positions` with `colors` and no normals or weights.
fn cloud_of<'a>(positions: &'a [[f32; 4]], colors: Option<&'a [[f32; 4]]>) -> Cloud<'a> {
    Cloud {
        positions,
        normals: None,
        colors,
        weights: None,
    }
}

/// A `size` x `size` camera at the origin, looking along +z.
fn camera_at_origin(size: u32) -> RenderCamera {
    RenderCamera {
        t_cam_to_world: DMat4::IDENTITY,
        intrinsics: render::framing_intrinsics(size, size, false),
    }
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
    let cloud = cloud_of(&positions, Some(&colors[..]));
    let camera = camera_at_origin(9);
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
    let cloud = cloud_of(&positions, None);
    for view in [View::Color, View::Normals, View::Weight] {
        let (used, why) = cloud.usable_view(view);
        assert_eq!(used, View::Depth);
        assert!(why.unwrap().contains("no "), "{view:?}");
    }
    assert_eq!(cloud.usable_view(View::Depth), (View::Depth, None));
    let camera = camera_at_origin(16);
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
    let cloud = cloud_of(&positions, Some(&colors[..]));
    let camera = camera_at_origin(16);
    assert!(render::render_cpu(&cloud, &camera, View::Color, &RenderSettings::default()).is_err());
    // NaN and far-off points are skipped, not drawn across the picture.
    let wild = [
        [f32::NAN, 0.0, 1.0, 1.0],
        [1.0e9, 0.0, 1.0, 1.0],
        [f32::INFINITY; 4],
    ];
    let cloud = cloud_of(&wild, None);
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

pub(super) fn tests() -> Vec<Test> {
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
    ]
}
