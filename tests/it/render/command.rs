//! The `render` command and the pictures `run`, `icp` and scan registration write.

use crate::common;

use std::path::Path;

use common::harness::{plain, Test};
use glam::{DMat4, DVec3};
use wgslam::geometry::camera::Intrinsics;
use wgslam::layout::map::SurfelMap;
use wgslam::render::{self, View};

use super::{bundled_map, coverage, frame_maps, gt_poses, keep};

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
        fill_gaps: wgslam::render::DEFAULT_FILL_GAP_PX,
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

pub(super) fn tests() -> Vec<Test> {
    vec![
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
        plain("lidar_overlay_from_above", lidar_overlay_from_above),
    ]
}
