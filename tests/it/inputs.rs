//! Bad and good inputs for the dataset loaders and file readers, written as real files
//! into a fresh temp directory per test (tiny PNGs generated here, no binary fixtures).

use crate::common;

use std::fs;
use std::path::Path;

use common::harness::{plain, shared};
use glam::{DMat4, DVec3};
use image::{GrayImage, ImageBuffer, Luma, Rgb, RgbImage, Rgba, RgbaImage};
use wgslam::dataset::{self, Layout, SequenceOptions};
use wgslam::geometry::camera::Intrinsics;
use wgslam::io::trajectory::{read_tum, write_tum};
use wgslam::{geometry::se3, Error};

/// Tiny frames keep every fixture under a few hundred bytes.
const W: u32 = 4;
const H: u32 = 3;

fn tiny_intrinsics() -> Intrinsics {
    Intrinsics {
        width: W,
        height: H,
        fx: 3.0,
        fy: 3.0,
        cx: 1.5,
        cy: 1.0,
    }
}

fn opts_tiny() -> SequenceOptions {
    SequenceOptions {
        intrinsics: Some(tiny_intrinsics()),
        ..Default::default()
    }
}

/// 16-bit depth with pixel `k` = `k * 100` (pixel 0 invalid).
fn write_depth(path: &Path, w: u32, h: u32) {
    fs::create_dir_all(path.parent().unwrap()).unwrap();
    let img: ImageBuffer<Luma<u16>, Vec<u16>> =
        ImageBuffer::from_fn(w, h, |u, v| Luma([((v * w + u) * 100) as u16]));
    img.save(path).unwrap();
}

fn write_rgb(path: &Path, w: u32, h: u32) {
    fs::create_dir_all(path.parent().unwrap()).unwrap();
    let img: RgbImage = ImageBuffer::from_fn(w, h, |u, v| Rgb([u as u8, v as u8, 7]));
    img.save(path).unwrap();
}

/// A TUM-layout sequence whose depth and colour stamps are deliberately interleaved so
/// that only greedy nearest-first association gives the expected pairs.
fn tum_fixture(name: &str) -> common::Scratch {
    let d = common::temp_dir(&format!("inputs-{name}"));
    // depth: 1.000 1.033 1.066 1.100 ; rgb: 0.990 1.030 1.040 1.200 (1.200 matches nothing)
    // Candidate |dt| < 0.02: d0-r0 .010, d1-r1 .003, d1-r2 .007, d2-r2 .026 (no).
    // Greedy: d1-r1, d0-r0; d2 and d3 have no partner left.
    let depth = [1.000, 1.033, 1.066, 1.100];
    let rgb = [0.990, 1.030, 1.040, 1.200];
    let mut dl = String::from("# depth maps\n# file: fixture\n# timestamp filename\n");
    let mut rl = String::from("# color images\n\n");
    for (k, s) in depth.iter().enumerate() {
        dl.push_str(&format!("{s:.6} depth/{k}.png\n"));
        write_depth(&d.join(format!("depth/{k}.png")), W, H);
    }
    for (k, s) in rgb.iter().enumerate() {
        rl.push_str(&format!("{s:.6} rgb/{k}.png\n"));
        write_rgb(&d.join(format!("rgb/{k}.png")), W, H);
    }
    fs::write(d.join("depth.txt"), dl).unwrap();
    fs::write(d.join("rgb.txt"), rl).unwrap();
    // GT at 1.005 (near d0) and 1.060 (more than 0.02 from d1 = 1.033).
    fs::write(
        d.join("groundtruth.txt"),
        "# timestamp tx ty tz qx qy qz qw\n1.005 1 2 3 0 0 0 1\n1.060 4 5 6 0 0 0 1\n",
    )
    .unwrap();
    d
}

/// An ICL-layout sequence of `n` tiny frames with GT for frames 1.. (frame 0 has none).
fn icl_fixture(name: &str, n: usize) -> common::Scratch {
    let d = common::temp_dir(&format!("inputs-{name}"));
    let mut assoc = String::new();
    let mut gt = String::new();
    for i in 0..n {
        assoc.push_str(&format!("{i} depth/{i}.png {i} rgb/{i}.png\n"));
        write_depth(&d.join(format!("depth/{i}.png")), W, H);
        write_rgb(&d.join(format!("rgb/{i}.png")), W, H);
        if i > 0 {
            gt.push_str(&format!("{i} 0 0 {} 0 0 0 1\n", i as f64 * 0.1));
        }
    }
    fs::write(d.join("associations.txt"), assoc).unwrap();
    fs::write(d.join("traj.gt.freiburg"), gt).unwrap();
    d
}

fn err_text<T: std::fmt::Debug>(r: wgslam::Result<T>) -> String {
    match r {
        Ok(v) => panic!("expected an error, got {v:?}"),
        Err(e) => e.to_string(),
    }
}

fn assert_contains(msg: &str, parts: &[&str]) {
    for p in parts {
        assert!(msg.contains(p), "error {msg:?} does not mention {p:?}");
    }
}

fn tum_association_is_greedy_nearest_first() {
    let d = tum_fixture("tum-assoc");
    let seq = dataset::open(&d, &opts_tiny()).unwrap();
    assert_eq!(seq.layout, Layout::Tum);
    assert_eq!(seq.depth_scale, 5000.0);
    let got: Vec<(f64, String, String)> = seq
        .frames
        .iter()
        .map(|f| {
            (
                f.timestamp,
                f.rgb_path.strip_prefix(&d).unwrap().display().to_string(),
                f.depth_path.strip_prefix(&d).unwrap().display().to_string(),
            )
        })
        .collect();
    assert_eq!(
        got,
        vec![
            (1.000, "rgb/0.png".into(), "depth/0.png".into()),
            (1.033, "rgb/1.png".into(), "depth/1.png".into()),
        ]
    );
    // GT 1.005 is within 0.02 of depth 1.000; GT 1.060 is 0.027 from depth 1.033.
    let g0 = seq.frames[0].gt_cam_to_world.expect("frame 0 has GT");
    assert_eq!(g0.w_axis.truncate(), DVec3::new(1.0, 2.0, 3.0));
    assert!(seq.frames[1].gt_cam_to_world.is_none());
    assert!(seq.has_ground_truth());

    // A wider window pairs more frames and picks up the second GT pose.
    let wide = SequenceOptions {
        max_time_diff: 0.03,
        ..opts_tiny()
    };
    let seq = dataset::open(&d, &wide).unwrap();
    let stamps: Vec<f64> = seq.frames.iter().map(|f| f.timestamp).collect();
    // |dt| < 0.03: d0-r0 .010, d1-r1 .003, d1-r2 .007, d2-r2 .026 -> d2 gets r2.
    assert_eq!(stamps, vec![1.000, 1.033, 1.066]);
    assert_eq!(
        seq.frames[2].rgb_path.strip_prefix(&d).unwrap(),
        Path::new("rgb/2.png")
    );
    let g1 = seq.frames[1].gt_cam_to_world.expect("GT within 0.03");
    assert_eq!(g1.w_axis.truncate(), DVec3::new(4.0, 5.0, 6.0));

    let f = seq.load(1).unwrap();
    assert_eq!((f.width, f.height), (W, H));
    assert_eq!(f.depth[5], 500);
    assert_eq!(f.rgb[5], [1, 1, 7]);
    assert_eq!(f.valid_depth_pixels(), (W * H - 1) as usize);
}

fn tum_without_intrinsics_asks_for_them() {
    let d = tum_fixture("tum-nok");
    let msg = err_text(dataset::open(&d, &SequenceOptions::default()));
    assert_contains(&msg, &["--intrinsics", "camera.json"]);
    // camera.json fills them in, with its depth scale; an explicit override beats it.
    fs::write(
        d.join("camera.json"),
        r#"{"width": 4, "height": 3, "fx": 3, "fy": 3, "cx": 1.5, "cy": 1, "depth_scale": 1000}"#,
    )
    .unwrap();
    let seq = dataset::open(&d, &SequenceOptions::default()).unwrap();
    assert_eq!(seq.intrinsics, tiny_intrinsics());
    assert_eq!(seq.depth_scale, 1000.0);
    let mut k = tiny_intrinsics();
    k.fx = 9.0;
    let o = SequenceOptions {
        intrinsics: Some(k),
        depth_scale: Some(10.0),
        ..Default::default()
    };
    let seq = dataset::open(&d, &o).unwrap();
    assert_eq!((seq.intrinsics.fx, seq.depth_scale), (9.0, 10.0));
    fs::write(d.join("camera.json"), r#"{"width": 4}"#).unwrap();
    let msg = err_text(dataset::open(&d, &SequenceOptions::default()));
    assert_contains(&msg, &["camera.json", "fx"]);
}

fn icl_layout_defaults_and_frame_index_stamps() {
    let d = icl_fixture("icl", 3);
    // No camera.json: the ICL-NUIM preset (640x480), so loading the 4x3 frames must fail.
    let seq = dataset::open(&d, &SequenceOptions::default()).unwrap();
    assert_eq!(seq.layout, Layout::IclNuim);
    assert_eq!(seq.intrinsics, Intrinsics::ICL_NUIM);
    let msg = err_text(seq.load(0));
    assert_contains(&msg, &["4x3", "640x480", "0.png"]);

    let seq = dataset::open(&d, &opts_tiny()).unwrap();
    assert_eq!(
        seq.frames.iter().map(|f| f.timestamp).collect::<Vec<_>>(),
        vec![0.0, 1.0, 2.0]
    );
    assert!(seq.frames[0].gt_cam_to_world.is_none());
    let g2 = seq.frames[2].gt_cam_to_world.unwrap();
    assert!((g2.w_axis.z - 0.2).abs() < 1e-12);
    assert_eq!(seq.ground_truth().len(), 2);
    assert_eq!(seq.select(1, 2).unwrap(), 1..=2);
}

fn missing_directory_and_files() {
    let d = common::temp_dir("inputs-missing");
    let msg = err_text(dataset::open(&d.join("nope"), &opts_tiny()));
    assert_contains(&msg, &["nope", "does not exist"]);
    let msg = err_text(dataset::open(&d, &opts_tiny()));
    assert_contains(&msg, &["rgb.txt", "associations.txt"]);

    let d = icl_fixture("missing-img", 2);
    fs::remove_file(d.join("rgb/1.png")).unwrap();
    let msg = err_text(dataset::open(&d, &opts_tiny()));
    assert_contains(&msg, &["rgb/1.png", "does not exist"]);

    let d = icl_fixture("missing-gt", 2);
    let o = SequenceOptions {
        gt_path: Some(d.join("other.txt")),
        ..opts_tiny()
    };
    let msg = err_text(dataset::open(&d, &o));
    assert_contains(&msg, &["other.txt"]);
}

fn empty_sequence() {
    let d = common::temp_dir("inputs-empty");
    fs::write(d.join("associations.txt"), "# nothing here\n\n").unwrap();
    let msg = err_text(dataset::open(&d, &opts_tiny()));
    assert_contains(&msg, &["empty sequence"]);
    // TUM: streams that never come within the window.
    let d = tum_fixture("empty-tum");
    let o = SequenceOptions {
        max_time_diff: 0.001,
        ..opts_tiny()
    };
    let msg = err_text(dataset::open(&d, &o));
    assert_contains(&msg, &["empty sequence", "0.001"]);
}

fn malformed_lists() {
    let d = icl_fixture("bad-assoc", 2);
    fs::write(
        d.join("associations.txt"),
        "0 depth/0.png 0 rgb/0.png\n1 depth/1.png\n",
    )
    .unwrap();
    let msg = err_text(dataset::open(&d, &opts_tiny()));
    assert_contains(&msg, &["associations.txt:2", "depth/1.png"]);

    let d = tum_fixture("bad-list");
    fs::write(d.join("rgb.txt"), "# c\nabc rgb/0.png\n").unwrap();
    let msg = err_text(dataset::open(&d, &opts_tiny()));
    assert_contains(&msg, &["rgb.txt:2", "abc"]);
}

fn malformed_ground_truth() {
    let cases: [(&str, &str, &[&str]); 4] = [
        ("1 0 0 -2.25 0 0 0\n", "gt-fields", &["found 7"]),
        (
            "1 0 0 -2.25 0 0 0 1\n2 0 zero 0 0 0 0 1\n",
            "gt-number",
            &[":2:", "field 3 is not a number"],
        ),
        (
            "# c\n1 0 0 0 0.5 0 0 0.5\n",
            "gt-norm",
            &[":2:", "norm 0.707107"],
        ),
        ("1 0 0 0 inf 0 0 1\n", "gt-inf", &[":1:", "not finite"]),
    ];
    for (text, name, parts) in cases {
        let d = icl_fixture(name, 2);
        fs::write(d.join("traj.gt.freiburg"), text).unwrap();
        let msg = err_text(dataset::open(&d, &opts_tiny()));
        assert_contains(&msg, &["traj.gt.freiburg"]);
        assert_contains(&msg, parts);
    }
}

fn bad_images() {
    let d = icl_fixture("bad-img", 6);
    // 1: 8-bit grey depth. 2: 8-bit grey colour. 3: truncated depth PNG.
    // 4: colour of another size. 5: RGBA colour (accepted, alpha dropped).
    let grey: GrayImage = ImageBuffer::from_pixel(W, H, Luma([9]));
    grey.save(d.join("depth/1.png")).unwrap();
    grey.save(d.join("rgb/2.png")).unwrap();
    let bytes = fs::read(d.join("depth/3.png")).unwrap();
    fs::write(d.join("depth/3.png"), &bytes[..bytes.len() / 2]).unwrap();
    write_rgb(&d.join("rgb/4.png"), W + 1, H);
    let rgba: RgbaImage = ImageBuffer::from_pixel(W, H, Rgba([10, 20, 30, 40]));
    rgba.save(d.join("rgb/5.png")).unwrap();

    let seq = dataset::open(&d, &opts_tiny()).unwrap();
    assert!(seq.load(0).is_ok());
    let msg = err_text(seq.load(1));
    assert_contains(&msg, &["depth/1.png", "16-bit single-channel", "L8"]);
    let msg = err_text(seq.load(2));
    assert_contains(&msg, &["rgb/2.png", "8-bit RGB or RGBA", "L8"]);
    let msg = err_text(seq.load(3));
    assert_contains(&msg, &["depth/3.png", "truncated"]);
    let msg = err_text(seq.load(4));
    assert_contains(&msg, &["rgb/4.png", "5x3", "4x3"]);
    let f = seq.load(5).unwrap();
    assert!(f.rgb.iter().all(|&p| p == [10, 20, 30]));
    let e = seq.load(6).unwrap_err();
    assert!(matches!(e, Error::Argument(_)), "{e}");
}

fn frame_range_outside_sequence() {
    let d = icl_fixture("range", 3);
    let seq = dataset::open(&d, &opts_tiny()).unwrap();
    assert_eq!(seq.select(0, 2).unwrap(), 0..=2);
    let msg = err_text(seq.select(1, 3));
    assert_contains(&msg, &["1..3", "0..2"]);
    assert!(seq.select(2, 1).is_err());
    let (a, b) = dataset::parse_range("1..200").unwrap();
    assert_contains(&err_text(seq.select(a, b)), &["1..200"]);
}

fn bundled_icl_frame_1() {
    let root = crate::common::bundled_icl();
    let seq = dataset::open(&root, &SequenceOptions::default()).unwrap();
    assert_eq!(seq.layout, Layout::IclNuim);
    assert_eq!(seq.intrinsics, Intrinsics::ICL_NUIM);
    assert_eq!(seq.depth_scale, 5000.0);
    assert_eq!(seq.len(), 24);
    assert!(seq.frames[0].gt_cam_to_world.is_none());
    let f = seq.load(1).unwrap();
    assert_eq!((f.width, f.height), (640, 480));
    // The release has almost no holes.
    assert!(f.valid_depth_pixels() > 640 * 480 * 9 / 10);
    let g = seq.frames[1].gt_cam_to_world.unwrap();
    assert_eq!(
        g,
        se3::from_rt(glam::DMat3::IDENTITY, DVec3::new(0.0, 0.0, -2.25))
    );
}

fn shared_icl_sequence_if_present(data: &Path) {
    let root = common::shared_icl(data);
    let seq = dataset::open(&root, &SequenceOptions::default()).unwrap();
    assert_eq!(seq.len(), 210);
    assert_eq!(seq.select(1, 200).unwrap(), 1..=200);
    assert_eq!(seq.ground_truth().len(), 209);
    let f = seq.load(200).unwrap();
    assert_eq!((f.width, f.height), (640, 480));
}

fn trajectory_round_trip() {
    let d = common::temp_dir("inputs-traj");
    let poses: Vec<(f64, DMat4)> = (0..5)
        .map(|k| {
            let x = k as f64;
            (
                1305031102.175304 + 0.033 * x,
                se3::exp(&[0.1 * x, -0.2, 0.05 * x, x, -2.0 * x, 0.5]),
            )
        })
        .collect();
    let p = d.join("est.txt");
    write_tum(&p, &poses).unwrap();
    let back = read_tum(&p).unwrap();
    assert_eq!(back.len(), poses.len());
    // Written with 6 decimals for stamps and 9 for values: 1e-6 s and ~1e-8 in the matrix.
    const STAMP_TOL: f64 = 1e-6;
    const POSE_TOL: f64 = 1e-8;
    for ((s0, t0), (s1, t1)) in poses.iter().zip(&back) {
        assert!((s0 - s1).abs() < STAMP_TOL, "{s0} vs {s1}");
        let d = (*t0 - *t1).to_cols_array();
        assert!(d.iter().all(|v| v.abs() < POSE_TOL), "{t0} vs {t1}");
    }
    // Integer stamps (frame indices) print as integers.
    write_tum(&p, &[(7.0, DMat4::IDENTITY)]).unwrap();
    let text = fs::read_to_string(&p).unwrap();
    assert!(
        text.lines().any(|l| l.starts_with("7 0.000000000")),
        "{text}"
    );
    // A non-finite pose is refused and the old file stays.
    let bad = [(8.0, DMat4::from_cols_array(&[f64::NAN; 16]))];
    assert!(write_tum(&p, &bad).is_err());
    assert_eq!(fs::read_to_string(&p).unwrap(), text);
}

fn bundled_icl_ground_truth_reads() {
    let p = crate::common::asset("icl_living_room_kt2/livingRoom2.gt.freiburg");
    let gt = read_tum(&p).unwrap();
    assert!(gt.len() >= 23);
    assert_eq!(gt[0].0, 1.0);
    assert_eq!(gt[0].1.w_axis.truncate(), DVec3::new(0.0, 0.0, -2.25));
    // Round trip through write_tum keeps indices as integers and poses to 1e-8.
    let d = common::temp_dir("inputs-icl-gt");
    let q = d.join("gt.txt");
    write_tum(&q, &gt).unwrap();
    let back = read_tum(&q).unwrap();
    for ((s0, t0), (s1, t1)) in gt.iter().zip(&back) {
        assert_eq!(s0, s1);
        assert!((*t0 - *t1).to_cols_array().iter().all(|v| v.abs() < 1e-8));
    }
}

fn surfel_map() -> wgslam::layout::map::SurfelMap {
    let mut m = wgslam::layout::map::SurfelMap::default();
    m.push(
        [0.5, -1.25, 3.0],
        [0.0, 0.0, -1.0],
        [255.0, 0.4, 127.6],
        1.0,
        0,
    );
    m.push(
        [1e-3, 2.0, -7.5],
        [0.6, 0.8, 0.0],
        [12.0, 300.0, -4.0],
        17.5,
        3,
    );
    m.push([0.0; 3], [1.0, 0.0, 0.0], [1.0, 2.0, 3.0], 2.0, 9);
    m
}

fn ply_round_trip() {
    let d = common::temp_dir("inputs-ply-rt");
    let p = d.join("map.ply");
    let m = surfel_map();
    wgslam::io::write_surfel_map(&p, &m).unwrap();
    let bytes = fs::read(&p).unwrap();
    let header_end = bytes
        .windows(11)
        .position(|w| w == b"end_header\n")
        .unwrap()
        + 11;
    let header = std::str::from_utf8(&bytes[..header_end]).unwrap();
    assert!(header.starts_with("ply\nformat binary_little_endian 1.0\n"));
    assert!(header.contains("element vertex 3\n"));
    // 6 floats + 3 bytes + 1 float per vertex.
    assert_eq!(bytes.len() - header_end, 3 * 31);

    let c = wgslam::io::read_ply(&p).unwrap();
    let pos: Vec<[f32; 3]> = (0..m.len()).map(|i| m.position(i)).collect();
    let nrm: Vec<[f32; 3]> = (0..m.len()).map(|i| m.normal(i)).collect();
    assert_eq!(c.positions, pos, "f32 round trip is exact");
    assert_eq!(c.normals.unwrap(), nrm);
    // Colours are rounded and clamped to 0..255.
    assert_eq!(
        c.colors.unwrap(),
        vec![[255, 0, 128], [12, 255, 0], [1, 2, 3]]
    );
    let weights: Vec<f32> = (0..m.len()).map(|i| m.weight(i)).collect();
    assert_eq!(c.weights.unwrap(), weights);

    let empty = d.join("empty.ply");
    wgslam::io::write_surfel_map(&empty, &Default::default()).unwrap();
    assert!(wgslam::io::read_ply(&empty).unwrap().positions.is_empty());
}

fn ply_ascii_any_order_and_types() {
    let d = common::temp_dir("inputs-ply-ascii");
    let p = d.join("a.ply");
    fs::write(
        &p,
        "ply\nformat ascii 1.0\ncomment made by hand\nelement camera 1\nproperty float view_px\n\
         element vertex 2\nproperty uint8 blue\nproperty double z\nproperty uchar green\n\
         property float32 y\nproperty int16 weight\nproperty uchar red\nproperty float x\n\
         element face 1\nproperty list uchar int vertex_indices\nend_header\n\
         0.5\n\
         3 1.5 2 -2.5 4 1 0.25\n\
         \n\
         250 -1e-3 251 7 -1 252 100\n\
         3 0 1 1\n",
    )
    .unwrap();
    let c = wgslam::io::read_ply(&p).unwrap();
    assert_eq!(c.positions, vec![[0.25, -2.5, 1.5], [100.0, 7.0, -1e-3]]);
    assert_eq!(c.colors.unwrap(), vec![[1, 2, 3], [252, 251, 250]]);
    assert_eq!(c.weights.unwrap(), vec![4.0, -1.0]);
    assert!(c.normals.is_none());
}

fn ply_binary_skips_elements_before_vertices() {
    let d = common::temp_dir("inputs-ply-bin");
    let p = d.join("b.ply");
    let mut b = b"ply\r\nformat binary_little_endian 1.0\nelement meta 2\nproperty short a\n\
property list uchar uint ids\nelement vertex 2\nproperty double x\nproperty char q\n\
property float y\nproperty float z\nproperty float red\nproperty float green\n\
property float blue\nend_header\n"
        .to_vec();
    // meta: (a=1, ids=[7]) and (a=2, ids=[8, 9]).
    b.extend_from_slice(&1i16.to_le_bytes());
    b.push(1);
    b.extend_from_slice(&7u32.to_le_bytes());
    b.extend_from_slice(&2i16.to_le_bytes());
    b.push(2);
    b.extend_from_slice(&8u32.to_le_bytes());
    b.extend_from_slice(&9u32.to_le_bytes());
    for (x, y, z, col) in [(1.0f64, 2.0f32, 3.0f32, 1.0f32), (-4.0, 5.0, 6.5, 0.5)] {
        b.extend_from_slice(&x.to_le_bytes());
        b.push(0xff); // char q = -1, ignored
        b.extend_from_slice(&y.to_le_bytes());
        b.extend_from_slice(&z.to_le_bytes());
        for _ in 0..3 {
            b.extend_from_slice(&col.to_le_bytes());
        }
    }
    fs::write(&p, &b).unwrap();
    let c = wgslam::io::read_ply(&p).unwrap();
    assert_eq!(c.positions, vec![[1.0, 2.0, 3.0], [-4.0, 5.0, 6.5]]);
    // Float colours are 0..1.
    assert_eq!(c.colors.unwrap(), vec![[255; 3], [128; 3]]);
    assert!(c.weights.is_none());

    // One byte short of the last vertex: the error gives the offset needed and the size.
    let cut = d.join("cut.ply");
    fs::write(&cut, &b[..b.len() - 1]).unwrap();
    let msg = err_text(wgslam::io::read_ply(&cut));
    let need = format!("offset {}", b.len());
    let has = format!("file has {}", b.len() - 1);
    assert_contains(&msg, &["cut.ply", "truncated", &need, &has]);
}

fn ply_malformed() {
    let d = common::temp_dir("inputs-ply-bad");
    let cases: [(&str, &[u8], &[&str]); 6] = [
        (
            "notply.ply",
            b"solid cube\nfacet normal 0 0 1\n",
            &["not a PLY"],
        ),
        (
            "be.ply",
            b"ply\nformat binary_big_endian 1.0\nelement vertex 0\nend_header\n",
            &["big-endian", "not supported", ":2:"],
        ),
        (
            "noxyz.ply",
            b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n\
end_header\n1 2\n",
            &["no x, y and z", "has: x y"],
        ),
        (
            "short.ply",
            b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
property float z\nend_header\n1 2 3\n4 5 6\n",
            &["truncated", "3 vertices declared, only 2"],
        ),
        (
            "badnum.ply",
            b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n\
property float z\nend_header\n1 two 3\n",
            &[":8:", "\"two\""],
        ),
        (
            "noend.ply",
            b"ply\nformat ascii 1.0\nelement vertex 1\n",
            &["end_header"],
        ),
    ];
    for (name, bytes, parts) in cases {
        let p = d.join(name);
        fs::write(&p, bytes).unwrap();
        let msg = err_text(wgslam::io::read_ply(&p));
        assert_contains(&msg, &[name]);
        assert_contains(&msg, parts);
    }
    let msg = err_text(wgslam::io::read_ply(&d.join("absent.ply")));
    assert_contains(&msg, &["absent.ply"]);
}

pub fn tests() -> Vec<common::harness::Test> {
    vec![
        plain(
            "tum_association_is_greedy_nearest_first",
            tum_association_is_greedy_nearest_first,
        ),
        plain(
            "tum_without_intrinsics_asks_for_them",
            tum_without_intrinsics_asks_for_them,
        ),
        plain(
            "icl_layout_defaults_and_frame_index_stamps",
            icl_layout_defaults_and_frame_index_stamps,
        ),
        plain("missing_directory_and_files", missing_directory_and_files),
        plain("empty_sequence", empty_sequence),
        plain("malformed_lists", malformed_lists),
        plain("malformed_ground_truth", malformed_ground_truth),
        plain("bad_images", bad_images),
        plain("frame_range_outside_sequence", frame_range_outside_sequence),
        plain("bundled_icl_frame_1", bundled_icl_frame_1),
        shared(
            "shared_icl_sequence_if_present",
            shared_icl_sequence_if_present,
        ),
        plain("trajectory_round_trip", trajectory_round_trip),
        plain(
            "bundled_icl_ground_truth_reads",
            bundled_icl_ground_truth_reads,
        ),
        plain("ply_round_trip", ply_round_trip),
        plain(
            "ply_ascii_any_order_and_types",
            ply_ascii_any_order_and_types,
        ),
        plain(
            "ply_binary_skips_elements_before_vertices",
            ply_binary_skips_elements_before_vertices,
        ),
        plain("ply_malformed", ply_malformed),
    ]
}
