//! Renderer tests: ground truth against the bundled real frames, determinism, the depth
//! test's key order, overlays, trajectory plots, bad input, and (with a GPU) GPU-vs-CPU
//! parity. Set `WGSLAM_RENDER_OUT=DIR` to keep the pictures for a look.

mod common;

use std::path::{Path, PathBuf};

use glam::{DMat4, DVec3};
use wgslam::camera::Intrinsics;
use wgslam::cpu::depth_to_vertex::depth_to_vertex;
use wgslam::cpu::vertex_to_normal::vertex_to_normal;
use wgslam::layout::{pack_rgba8, NormalParams, PreprocessParams};
use wgslam::map::SurfelMap;
use wgslam::render::{self, Cloud, RenderCamera, RenderSettings, View};
use wgslam::se3;

/// Ground-truth poses (`t_cam_to_world`) of the bundled frames, by frame index.
fn gt_poses(root: &Path) -> Vec<(usize, DMat4)> {
    let text = std::fs::read_to_string(root.join("livingRoom2.gt.freiburg")).expect("gt file");
    text.lines()
        .filter(|l| !l.trim().is_empty())
        .map(|l| {
            let v: Vec<f64> = l.split_whitespace().map(|x| x.parse().unwrap()).collect();
            (
                v[0] as usize,
                se3::from_tum([v[1], v[2], v[3]], [v[4], v[5], v[6], v[7]]),
            )
        })
        .collect()
}

/// Raw depth (u16) and packed RGBA of bundled frame `i`.
fn load_frame(root: &Path, i: usize) -> (Vec<u16>, Vec<u32>) {
    let depth = image::open(root.join(format!("depth/{i}.png")))
        .unwrap()
        .into_luma16();
    let rgb = image::open(root.join(format!("rgb/{i}.png")))
        .unwrap()
        .into_rgb8();
    let rgba = rgb.pixels().map(|p| pack_rgba8(p.0)).collect();
    (depth.into_raw(), rgba)
}

/// Camera-frame vertex, normal and colour maps of frame `i`, downsampled by `stride`.
fn frame_maps(
    root: &Path,
    i: usize,
    stride: u32,
) -> (Intrinsics, Vec<[f32; 4]>, Vec<[f32; 4]>, Vec<[f32; 4]>) {
    let k = Intrinsics::ICL_NUIM.downsampled(stride);
    let (depth, rgba) = load_frame(root, i);
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

#[test]
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
    let img = render::render_cpu(&Cloud::from_map(&map), &camera, View::Color, &settings).unwrap();
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

#[test]
fn renders_are_deterministic_and_views_differ() {
    let map = bundled_map(&[1, 10, 20], 4);
    let cloud = Cloud::from_map(&map);
    let up_fwd =
        render::trajectory_view_hint(&[gt_poses(&common::bundled_icl())[0].1], -480.0).unwrap();
    let camera =
        render::default_camera(&map.positions, 320, 240, up_fwd.0, up_fwd.1, true).unwrap();
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
