//! Datasets as users have them (`wgslam::dataset`): each public layout, generated at test
//! time from the bundled ICL-NUIM frames re-written with that layout's conventions (file
//! names and numbering, depth units, JPEG colour, per-frame pose files, intrinsics files),
//! tracks to the same ATE as the frames in their TUM-compatible form; each layout's bad
//! inputs give an error naming the file; and the real-sensor sequences in
//! `../shared/data` (7-Scenes Kinect v1, SUN3D Asus Xtion) track against their reference
//! poses on both backends and pass `compare`.

use crate::common;

use std::fs;
use std::path::{Path, PathBuf};

use common::cli::{ok, text, wgslam};
use common::harness::{gpu_backend, gpu_shared, plain, shared};
use glam::DMat4;
use image::{ImageBuffer, Luma, RgbImage};
use wgslam::dataset::{self, Layout, Sequence, SequenceOptions};
use wgslam::geometry::camera::Intrinsics;
use wgslam::gpu::{GpuBackend, GpuContext};
use wgslam::slam::backend::{Backend, Inspect};
use wgslam::slam::cpu_backend::CpuBackend;
use wgslam::slam::params::{Profile, ValidParams};
use wgslam::tools::compare::{compare, Mode};
use wgslam::tools::run;

/// Bundled frames the fixtures hold: 1..=12 (frame 0 has no ground truth; 10..12 sort
/// before 2 as strings, so numeric ordering is tested too).
const FIXTURE_FRAMES: std::ops::RangeInclusive<usize> = 1..=12;

/// A fixture must track to the TUM form's ATE within this. The depth is the same (ICL-NUIM
/// is quantised to 1 mm, so millimetre files are exact) and so are the intrinsics; the
/// ground truth goes through another text form (a 4x4 matrix or a quaternion) and
/// `raw / 1000` and `raw / 5000` round differently in an f32's last bit. Measured
/// differences: 0.06 um on every layout but Replica; 10 um is far below what a wrong
/// convention costs (the TUM form's ATE is 0.06 mm, a lost frame is millimetres).
const LAYOUT_ATE_TOL_M: f64 = 1e-5;
/// Replica stores depth at 6553.5 per metre, so re-encoding 1 mm steps moves each depth by
/// up to 0.08 mm: measured 1.2 um of ATE difference on these 12 frames.
const LAYOUT_ATE_TOL_REPLICA_M: f64 = 2e-5;

pub fn tests() -> Vec<common::harness::Test> {
    vec![
        plain(
            "seven_scenes_fixture_tracks_like_the_tum_form",
            seven_scenes_fixture_tracks_like_the_tum_form,
        ),
        plain(
            "seven_scenes_seq_folders_and_default_intrinsics",
            seven_scenes_seq_folders_and_default_intrinsics,
        ),
        plain(
            "scannet_fixture_tracks_like_the_tum_form",
            scannet_fixture_tracks_like_the_tum_form,
        ),
        plain(
            "replica_fixture_tracks_like_the_tum_form",
            replica_fixture_tracks_like_the_tum_form,
        ),
        plain(
            "eth3d_fixture_tracks_like_the_tum_form",
            eth3d_fixture_tracks_like_the_tum_form,
        ),
        plain(
            "bonn_fixture_tracks_like_the_tum_form",
            bonn_fixture_tracks_like_the_tum_form,
        ),
        plain(
            "unknown_folder_lists_the_layouts",
            unknown_folder_lists_the_layouts,
        ),
        plain("bad_inputs_name_the_file", bad_inputs_name_the_file),
        plain(
            "every_layout_opens_from_memory_as_from_disk",
            every_layout_opens_from_memory_as_from_disk,
        ),
        plain(
            "a_run_from_memory_gives_the_bytes_run_writes",
            a_run_from_memory_gives_the_bytes_run_writes,
        ),
        shared("seven_scenes_real_kinect_tracks", |data| {
            real_sensor_tracks(
                CpuBackend::new(),
                &data.join(SEVEN_SCENES),
                &SEVEN_SCENES_BAR,
            )
        }),
        gpu_shared("gpu_seven_scenes_real_kinect_tracks", |ctx, data| {
            real_sensor_tracks(
                gpu_backend(ctx),
                &data.join(SEVEN_SCENES),
                &SEVEN_SCENES_BAR,
            )
        }),
        shared("sun3d_real_xtion_tracks", |data| {
            real_sensor_tracks(CpuBackend::new(), &data.join(SUN3D), &SUN3D_BAR)
        }),
        gpu_shared("gpu_sun3d_real_xtion_tracks", |ctx, data| {
            real_sensor_tracks(gpu_backend(ctx), &data.join(SUN3D), &SUN3D_BAR)
        }),
        shared(
            "a_real_references_jump_is_noted",
            a_real_references_jump_is_noted,
        ),
        gpu_shared(
            "compare_passes_on_real_sensors",
            compare_passes_on_real_sensors,
        ),
        shared(
            "cli_runs_and_evaluates_the_folder_as_it_is",
            cli_runs_and_evaluates_the_folder_as_it_is,
        ),
    ]
}

// ---------------------------------------------------------------------------------------
// Fixtures: the bundled frames in each layout.

/// The bundled frames' depth (raw, 5000 per metre), colour and ground truth.
struct Source {
    depth: Vec<ImageBuffer<Luma<u16>, Vec<u16>>>,
    color: Vec<RgbImage>,
    gt: Vec<Option<DMat4>>,
}

fn source() -> Source {
    let root = common::bundled_icl();
    let gt = common::frames::load_gt(&root);
    let mut s = Source {
        depth: Vec::new(),
        color: Vec::new(),
        gt: Vec::new(),
    };
    for i in 0..=*FIXTURE_FRAMES.end() {
        s.depth.push(
            image::open(root.join(format!("depth/{i}.png")))
                .unwrap()
                .into_luma16(),
        );
        s.color.push(
            image::open(root.join(format!("rgb/{i}.png")))
                .unwrap()
                .into_rgb8(),
        );
        s.gt.push(common::frames::gt_at(&gt, i).copied());
    }
    s
}

/// Depth re-scaled from 5000 to `scale` raw units per metre (rounded).
fn rescaled(d: &ImageBuffer<Luma<u16>, Vec<u16>>, scale: f64) -> ImageBuffer<Luma<u16>, Vec<u16>> {
    let f = scale / 5000.0;
    ImageBuffer::from_fn(d.width(), d.height(), |u, v| {
        Luma([(d.get_pixel(u, v).0[0] as f64 * f).round() as u16])
    })
}

/// A pose as 4 rows of 4 numbers (row-major), as 7-Scenes and ScanNet write them.
fn pose_text(m: &DMat4) -> String {
    let a = m.to_cols_array_2d();
    (0..4)
        .map(|r| {
            (0..4)
                .map(|c| format!("{:.12e}", a[c][r]))
                .collect::<Vec<_>>()
                .join(" ")
                + "\n"
        })
        .collect()
}

/// The ICL-NUIM intrinsics as a 3x3 K (fy negative, as the dataset's own).
fn k3(k: &Intrinsics) -> String {
    format!("{} 0 {}\n0 {} {}\n0 0 1\n", k.fx, k.cx, k.fy, k.cy)
}

fn k4(k: &Intrinsics) -> String {
    format!(
        "{} 0 {} 0\n0 {} {} 0\n0 0 1 0\n0 0 0 1\n",
        k.fx, k.cx, k.fy, k.cy
    )
}

/// 7-Scenes / tsdf-fusion: `frame-NNNNNN.{color.jpg,depth.png,pose.txt}` in millimetres;
/// one depth pixel set to 65535 (the official release's "no reading").
fn write_seven_scenes(dir: &Path, s: &Source, intrinsics_file: bool) {
    fs::create_dir_all(dir).unwrap();
    for i in FIXTURE_FRAMES {
        let mut d = rescaled(&s.depth[i], 1000.0);
        d.put_pixel(0, 0, Luma([65535]));
        d.save(dir.join(format!("frame-{i:06}.depth.png"))).unwrap();
        s.color[i]
            .save(dir.join(format!("frame-{i:06}.color.jpg")))
            .unwrap();
        fs::write(
            dir.join(format!("frame-{i:06}.pose.txt")),
            pose_text(&s.gt[i].unwrap()),
        )
        .unwrap();
    }
    if intrinsics_file {
        fs::write(dir.join("camera-intrinsics.txt"), k3(&Intrinsics::ICL_NUIM)).unwrap();
    }
}

/// The colour camera of the ScanNet fixture: 1296x968, the depth camera's field of view.
fn scannet_color_k() -> Intrinsics {
    let k = Intrinsics::ICL_NUIM;
    let (sx, sy) = (1296.0 / 640.0, 968.0 / 480.0);
    Intrinsics {
        width: 1296,
        height: 968,
        fx: k.fx * sx,
        fy: k.fy * sy,
        cx: (k.cx + 0.5) * sx - 0.5,
        cy: (k.cy + 0.5) * sy - 0.5,
    }
}

/// ScanNet export: `color/N.jpg` at 1296x968, `depth/N.png` in millimetres, `pose/N.txt`,
/// both intrinsics files; frame 0 is in with an all `-inf` pose (ScanNet's failed pose).
fn write_scannet(dir: &Path, s: &Source) {
    for sub in ["color", "depth", "pose", "intrinsic"] {
        fs::create_dir_all(dir.join(sub)).unwrap();
    }
    for i in std::iter::once(0).chain(FIXTURE_FRAMES) {
        rescaled(&s.depth[i], 1000.0)
            .save(dir.join(format!("depth/{i}.png")))
            .unwrap();
        image::imageops::resize(
            &s.color[i],
            1296,
            968,
            image::imageops::FilterType::Triangle,
        )
        .save(dir.join(format!("color/{i}.jpg")))
        .unwrap();
        let pose = match &s.gt[i] {
            Some(m) => pose_text(m),
            None => "-inf -inf -inf -inf\n".repeat(4),
        };
        fs::write(dir.join(format!("pose/{i}.txt")), pose).unwrap();
    }
    fs::write(
        dir.join("intrinsic/intrinsic_depth.txt"),
        k4(&Intrinsics::ICL_NUIM),
    )
    .unwrap();
    fs::write(
        dir.join("intrinsic/intrinsic_color.txt"),
        k4(&scannet_color_k()),
    )
    .unwrap();
}

/// Replica as NICE-SLAM ships it: `Replica/cam_params.json` beside `Replica/room0/` with
/// `results/frameNNNNNN.jpg`, `results/depthNNNNNN.png` (6553.5 per metre) and `traj.txt`.
/// Returns the sequence folder.
fn write_replica(top: &Path, s: &Source) -> PathBuf {
    let dir = top.join("room0");
    fs::create_dir_all(dir.join("results")).unwrap();
    let mut traj = String::new();
    for (n, i) in FIXTURE_FRAMES.enumerate() {
        rescaled(&s.depth[i], 6553.5)
            .save(dir.join(format!("results/depth{n:06}.png")))
            .unwrap();
        s.color[i]
            .save(dir.join(format!("results/frame{n:06}.jpg")))
            .unwrap();
        traj.push_str(pose_text(&s.gt[i].unwrap()).replace('\n', " ").trim_end());
        traj.push('\n');
    }
    fs::write(dir.join("traj.txt"), traj).unwrap();
    let k = Intrinsics::ICL_NUIM;
    fs::write(
        top.join("cam_params.json"),
        format!(
            r#"{{"camera": {{"w": 640, "h": 480, "fx": {}, "fy": {}, "cx": {}, "cy": {}, "scale": 6553.5}}}}"#,
            k.fx, k.fy, k.cx, k.cy
        ),
    )
    .unwrap();
    dir
}

/// TUM-style stamps for the fixtures: 30 Hz from an arbitrary start.
fn stamp(i: usize) -> f64 {
    1305031102.0 + i as f64 / 30.0
}

fn tum_line(t: f64, m: &DMat4) -> String {
    let (_, q, p) = m.to_scale_rotation_translation();
    format!(
        "{t:.6} {:.9} {:.9} {:.9} {:.9} {:.9} {:.9} {:.9}\n",
        p.x, p.y, p.z, q.x, q.y, q.z, q.w
    )
}

/// The TUM layout (`rgb/`, `depth/`, `rgb.txt`, `depth.txt`, `groundtruth.txt`) at 5000
/// per metre; `associated` adds ETH3D's `associated.txt` and `calibration.txt` and drops
/// the two lists.
fn write_tum_like(dir: &Path, s: &Source, eth3d: bool) {
    fs::create_dir_all(dir.join("rgb")).unwrap();
    fs::create_dir_all(dir.join("depth")).unwrap();
    let (mut rgb, mut depth, mut assoc, mut gt) =
        (String::new(), String::new(), String::new(), String::new());
    for i in FIXTURE_FRAMES {
        let t = stamp(i);
        s.depth[i]
            .save(dir.join(format!("depth/{t:.6}.png")))
            .unwrap();
        s.color[i]
            .save(dir.join(format!("rgb/{t:.6}.png")))
            .unwrap();
        rgb.push_str(&format!("{t:.6} rgb/{t:.6}.png\n"));
        depth.push_str(&format!("{t:.6} depth/{t:.6}.png\n"));
        assoc.push_str(&format!("{t:.6} rgb/{t:.6}.png {t:.6} depth/{t:.6}.png\n"));
        gt.push_str(&tum_line(t, &s.gt[i].unwrap()));
    }
    fs::write(dir.join("groundtruth.txt"), gt).unwrap();
    if eth3d {
        let k = Intrinsics::ICL_NUIM;
        fs::write(dir.join("associated.txt"), assoc).unwrap();
        fs::write(
            dir.join("calibration.txt"),
            format!("{} {} {} {}\n", k.fx, k.fy, k.cx, k.cy),
        )
        .unwrap();
    } else {
        fs::write(dir.join("rgb.txt"), rgb).unwrap();
        fs::write(dir.join("depth.txt"), depth).unwrap();
    }
}

// ---------------------------------------------------------------------------------------
// Tracking a fixture against the TUM form.

/// ATE (aligned, metres) of the robust profile over every frame of `seq` on the CPU.
fn ate_of(seq: &Sequence) -> f64 {
    let r = common::run_cpu(
        seq,
        0,
        seq.len() - 1,
        wgslam::SlamParams::profile(Profile::Robust),
    )
    .unwrap();
    assert_eq!(r.metrics.tracking.lost, 0);
    r.metrics.accuracy.expect("ground truth").ate_rmse_aligned_m
}

/// The bundled frames 1..=12 in their TUM-compatible (ICL-NUIM) form.
fn tum_form_ate() -> f64 {
    let seq = common::open_asset("icl_living_room_kt2");
    let r = common::run_cpu(
        &seq,
        *FIXTURE_FRAMES.start(),
        *FIXTURE_FRAMES.end(),
        wgslam::SlamParams::profile(Profile::Robust),
    )
    .unwrap();
    r.metrics.accuracy.unwrap().ate_rmse_aligned_m
}

fn assert_same_ate(layout: &str, seq: &Sequence, tol_m: f64) {
    let (ate, tum) = (ate_of(seq), tum_form_ate());
    eprintln!(
        "{layout}: ATE {:.4} mm, TUM form {:.4} mm, difference {:.2e} m",
        ate * 1e3,
        tum * 1e3,
        (ate - tum).abs()
    );
    assert!((ate - tum).abs() <= tol_m, "{layout}: {ate} vs {tum}");
}

fn seven_scenes_fixture_tracks_like_the_tum_form() {
    let d = common::temp_dir("ds-7scenes");
    write_seven_scenes(&d, &source(), true);
    let seq = dataset::open(&d, &SequenceOptions::default()).unwrap();
    assert_eq!(seq.layout, Layout::SevenScenes);
    assert_eq!(seq.depth_scale, 1000.0);
    assert_eq!(seq.intrinsics, Intrinsics::ICL_NUIM);
    assert_eq!(seq.len(), FIXTURE_FRAMES.count());
    assert_eq!(seq.frames[0].timestamp, 1.0);
    assert!(seq.frames.iter().all(|f| f.gt_cam_to_world.is_some()));
    let f = seq.load(0).unwrap();
    assert_eq!(f.depth[0], 0, "65535 is no reading");
    assert_same_ate("7-Scenes", &seq, LAYOUT_ATE_TOL_M);
}

/// The official 7-Scenes form: a scene folder with `seq-NN/` folders; one opens, two ask
/// which; without `camera-intrinsics.txt` the 7-Scenes Kinect's intrinsics, with a note.
fn seven_scenes_seq_folders_and_default_intrinsics() {
    let d = common::temp_dir("ds-7scenes-seq");
    let s = source();
    write_seven_scenes(&d.join("seq-01"), &s, false);
    let seq = dataset::open(&d, &SequenceOptions::default()).unwrap();
    assert_eq!(seq.layout, Layout::SevenScenes);
    assert_eq!(seq.len(), FIXTURE_FRAMES.count());
    assert_eq!((seq.intrinsics.fx, seq.intrinsics.cx), (585.0, 320.0));
    assert!(
        seq.notes
            .iter()
            .any(|n| n.contains("camera-intrinsics.txt")),
        "{:?}",
        seq.notes
    );
    // 3DMatch keeps the intrinsics in the scene folder above seq-NN.
    fs::write(d.join("camera-intrinsics.txt"), k3(&Intrinsics::ICL_NUIM)).unwrap();
    let seq = dataset::open(&d, &SequenceOptions::default()).unwrap();
    assert_eq!(seq.intrinsics, Intrinsics::ICL_NUIM);
    assert!(seq.notes.is_empty(), "{:?}", seq.notes);
    write_seven_scenes(&d.join("seq-02"), &s, false);
    let msg = dataset::open(&d, &SequenceOptions::default())
        .unwrap_err()
        .to_string();
    assert!(msg.contains("seq-01, seq-02"), "{msg}");
    let seq = dataset::open(&d.join("seq-02"), &SequenceOptions::default()).unwrap();
    assert_eq!(seq.len(), FIXTURE_FRAMES.count());
}

fn scannet_fixture_tracks_like_the_tum_form() {
    let d = common::temp_dir("ds-scannet");
    let s = source();
    write_scannet(&d, &s);
    let seq = dataset::open(&d, &SequenceOptions::default()).unwrap();
    assert_eq!(seq.layout, Layout::ScanNet);
    assert_eq!(seq.depth_scale, 1000.0);
    assert_eq!(seq.intrinsics, Intrinsics::ICL_NUIM);
    let stamps: Vec<f64> = seq.frames.iter().map(|f| f.timestamp).collect();
    assert_eq!(
        stamps,
        (0..=12).map(|i| i as f64).collect::<Vec<_>>(),
        "numeric order"
    );
    assert!(
        seq.frames[0].gt_cam_to_world.is_none(),
        "-inf pose: no ground truth"
    );
    assert!(
        seq.notes.iter().any(|n| n.contains("-inf")),
        "{:?}",
        seq.notes
    );
    // Colour comes back at the depth image's size, matching the original pixels up to
    // JPEG and two resamplings.
    let f = seq.load(5).unwrap();
    assert_eq!((f.width, f.height), (640, 480));
    let err: f64 = f
        .rgb
        .iter()
        .zip(s.color[5].pixels())
        .map(|(a, b)| {
            (0..3)
                .map(|k| (a[k] as f64 - b.0[k] as f64).abs())
                .sum::<f64>()
                / 3.0
        })
        .sum::<f64>()
        / f.rgb.len() as f64;
    eprintln!("ScanNet colour resampled onto depth: mean abs difference {err:.2} levels");
    assert!(err < COLOR_RESAMPLE_MAX_MEAN_DIFF, "{err}");
    // Frame 0 has no ground truth, so the TUM form starts at frame 1 too.
    let seq = Sequence {
        frames: seq.frames[1..].to_vec(),
        ..seq
    };
    assert_same_ate("ScanNet", &seq, LAYOUT_ATE_TOL_M);
}

/// Colour up-sampled to 1296x968, saved as JPEG and mapped back: measured a mean absolute
/// difference of 1.2 levels of 255 against the original (JPEG and two bilinear
/// resamplings); 5 leaves room for another JPEG encoder.
const COLOR_RESAMPLE_MAX_MEAN_DIFF: f64 = 5.0;

fn replica_fixture_tracks_like_the_tum_form() {
    let top = common::temp_dir("ds-replica");
    let dir = write_replica(&top, &source());
    let seq = dataset::open(&dir, &SequenceOptions::default()).unwrap();
    assert_eq!(seq.layout, Layout::Replica);
    assert_eq!(seq.depth_scale, 6553.5);
    assert_eq!(seq.intrinsics, Intrinsics::ICL_NUIM);
    assert_same_ate("Replica", &seq, LAYOUT_ATE_TOL_REPLICA_M);
}

fn eth3d_fixture_tracks_like_the_tum_form() {
    let d = common::temp_dir("ds-eth3d");
    write_tum_like(&d, &source(), true);
    let seq = dataset::open(&d, &SequenceOptions::default()).unwrap();
    assert_eq!(seq.layout, Layout::Eth3d);
    assert_eq!(seq.intrinsics, Intrinsics::ICL_NUIM);
    assert!(seq.frames.iter().all(|f| f.gt_cam_to_world.is_some()));
    assert_same_ate("ETH3D", &seq, LAYOUT_ATE_TOL_M);
}

/// Bonn is the TUM layout in a folder named `rgbd_bonn_*`, read with the Bonn sensor's
/// intrinsics; these frames are ICL-NUIM's, so the user's `--camera icl` wins.
fn bonn_fixture_tracks_like_the_tum_form() {
    let top = common::temp_dir("ds-bonn");
    let d = top.join("rgbd_bonn_fixture");
    write_tum_like(&d, &source(), false);
    let seq = dataset::open(&d, &SequenceOptions::default()).unwrap();
    assert_eq!(seq.layout, Layout::Bonn);
    assert!(
        (seq.intrinsics.fx - 542.8228).abs() < 1e-3,
        "the Bonn sensor's fx"
    );
    let opts = SequenceOptions {
        intrinsics: Some(Intrinsics::ICL_NUIM),
        ..SequenceOptions::default()
    };
    let seq = dataset::open(&d, &opts).unwrap();
    assert_same_ate("Bonn", &seq, LAYOUT_ATE_TOL_M);
}

/// Every file under `dir`, held in memory under `at` joined with its path inside `dir`.
fn folder_in_memory(dir: &Path, at: &Path, files: &mut dataset::InMemoryFiles) {
    for entry in fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        let name = at.join(path.file_name().unwrap());
        if path.is_dir() {
            folder_in_memory(&path, &name, files);
        } else {
            files.insert(name, fs::read(&path).unwrap());
        }
    }
}

/// Where the in-memory copies live: a relative path that is not on disk, so a reader that
/// went to the disk instead of the source would fail.
const IN_MEMORY_TOP: &str = "in-memory-only";

/// The browser page's way in (`dataset::open_with` over files it holds, `src/web`): each
/// layout's fixture opens from memory to the same frames, intrinsics, depth scale and notes
/// as from disk, decodes to the same pixels, and a folder of no layout fails with the same
/// words (paths aside).
fn every_layout_opens_from_memory_as_from_disk() {
    let s = source();
    let top = common::temp_dir("ds-memory");
    let mut roots = Vec::new();
    for (name, eth3d) in [("tum", false), ("eth3d", true), ("rgbd_bonn_x", false)] {
        write_tum_like(&top.join(name), &s, eth3d);
        roots.push(top.join(name));
    }
    // Plain TUM records no intrinsics: a camera.json gives them (read through the source too).
    let k = Intrinsics::ICL_NUIM;
    let camera = format!(
        r#"{{"width": {}, "height": {}, "fx": {}, "fy": {}, "cx": {}, "cy": {}}}"#,
        k.width, k.height, k.fx, k.fy, k.cx, k.cy
    );
    fs::write(top.join("tum/camera.json"), camera).unwrap();
    write_seven_scenes(&top.join("7scenes/seq-01"), &s, false);
    roots.push(top.join("7scenes"));
    write_scannet(&top.join("scannet"), &s);
    roots.push(top.join("scannet"));
    roots.push(write_replica(&top.join("replica"), &s));
    let icl = crate::common::bundled_icl();
    roots.push(icl.clone());
    fs::create_dir_all(top.join("empty/rgb")).unwrap();
    fs::write(top.join("empty/rgb/0.png"), b"").unwrap();
    let opts = SequenceOptions::default();
    // Every fixture's files (and those around them: Replica's cam_params.json sits above
    // the sequence folder) in one set.
    let mut files = dataset::InMemoryFiles::default();
    let here = Path::new(IN_MEMORY_TOP);
    folder_in_memory(&top, &here.join("top"), &mut files);
    folder_in_memory(&icl, &here.join("icl"), &mut files);
    let files = std::sync::Arc::new(files);
    let in_memory = |p: &Path| match p.strip_prefix(&*top) {
        Ok(rest) => here.join("top").join(rest),
        Err(_) => here.join("icl").join(p.strip_prefix(&icl).unwrap()),
    };
    for root in &roots {
        let disk = dataset::open(root, &opts).unwrap();
        let memory = dataset::open_with(files.clone(), &in_memory(root), &opts).unwrap();
        let moved: Vec<dataset::FrameRecord> = disk
            .frames
            .iter()
            .map(|f| dataset::FrameRecord {
                rgb_path: in_memory(&f.rgb_path),
                depth_path: in_memory(&f.depth_path),
                ..f.clone()
            })
            .collect();
        let what = format!("{} ({})", root.display(), disk.layout.name());
        assert_eq!(memory.layout, disk.layout, "{what}");
        assert_eq!(memory.frames, moved, "{what}");
        assert_eq!(memory.intrinsics, disk.intrinsics, "{what}");
        assert_eq!(memory.depth_scale, disk.depth_scale, "{what}");
        assert_eq!(memory.conventions, disk.conventions, "{what}");
        let notes: Vec<String> = disk
            .notes
            .iter()
            .map(|n| n.replace(&*root.to_string_lossy(), &in_memory(root).to_string_lossy()))
            .collect();
        assert_eq!(memory.notes, notes, "{what}");
        let last = disk.len() - 1;
        assert_eq!(
            memory.load(last).unwrap(),
            disk.load(last).unwrap(),
            "{what}"
        );
    }
    let empty = top.join("empty");
    let memory = dataset::open_with(files, &in_memory(&empty), &opts);
    assert_eq!(
        memory.unwrap_err().to_string(),
        err_of(&empty).replace(
            &*empty.to_string_lossy(),
            &in_memory(&empty).to_string_lossy()
        ),
        "the same words for a folder of no layout"
    );
}

/// The browser's downloads (`run::output_bytes`) are the files `wgslam run` writes
/// (`run::write_outputs`), byte for byte, and a run over the bundled frames held in memory
/// gives the same trajectories and map as from disk (the CPU backend is deterministic).
fn a_run_from_memory_gives_the_bytes_run_writes() {
    let icl = crate::common::bundled_icl();
    let opts = SequenceOptions::default();
    let disk = dataset::open(&icl, &opts).unwrap();
    let mut files = dataset::InMemoryFiles::default();
    folder_in_memory(&icl, Path::new(IN_MEMORY_TOP), &mut files);
    let memory =
        dataset::open_with(std::sync::Arc::new(files), Path::new(IN_MEMORY_TOP), &opts).unwrap();
    let run_of = |seq: &Sequence| {
        common::run_cpu(seq, 1, 4, wgslam::SlamParams::profile(Profile::Robust)).unwrap()
    };
    let (from_disk, from_memory) = (run_of(&disk), run_of(&memory));
    let out = common::temp_dir("ds-memory-outputs");
    run::write_outputs(&out, &from_disk).unwrap();
    let bytes = run::output_bytes(&from_disk).unwrap();
    assert_eq!(bytes.len(), 5);
    for (name, b) in &bytes {
        assert!(
            fs::read(out.join(name)).unwrap() == *b,
            "{name} differs from the file"
        );
    }
    let memory_bytes = run::output_bytes(&from_memory).unwrap();
    for name in ["trajectory.tum", "trajectory_odometry.tum", "map.ply"] {
        let of = |set: &[(&str, Vec<u8>)]| set.iter().find(|(n, _)| *n == name).unwrap().1.clone();
        assert!(
            of(&bytes) == of(&memory_bytes),
            "{name}: memory and disk differ"
        );
    }
}

// ---------------------------------------------------------------------------------------
// Bad inputs.

fn err_of(root: &Path) -> String {
    match dataset::open(root, &SequenceOptions::default()) {
        Ok(s) => panic!(
            "expected an error opening {}, got {} frames",
            root.display(),
            s.len()
        ),
        Err(e) => e.to_string(),
    }
}

fn assert_mentions(msg: &str, parts: &[&str]) {
    for p in parts {
        assert!(msg.contains(p), "error {msg:?} does not mention {p:?}");
    }
}

/// A folder of no layout: the error lists every layout tried and what the closest lacks.
fn unknown_folder_lists_the_layouts() {
    let d = common::temp_dir("ds-unknown");
    let msg = err_of(&d);
    eprintln!("{msg}");
    for name in [
        "TUM RGB-D",
        "ICL-NUIM",
        "ETH3D",
        "Bonn",
        "7-Scenes",
        "ScanNet",
        "Replica",
    ] {
        assert_mentions(&msg, &[name]);
    }
    assert_mentions(&msg, &["no file of any of them"]);
    // Depth frames but no colour: 7-Scenes is closest and lacks the colour files.
    let png: ImageBuffer<Luma<u16>, Vec<u16>> = ImageBuffer::from_pixel(4, 3, Luma([1000]));
    png.save(d.join("frame-000000.depth.png")).unwrap();
    let msg = err_of(&d);
    eprintln!("{msg}");
    assert_mentions(&msg, &["closest is 7-Scenes", "lacks frame-N.color.jpg"]);
}

/// Each layout's bad inputs: an error naming the file (or a logged recovery, for the
/// missing 7-Scenes intrinsics tested above and `-inf` poses).
fn bad_inputs_name_the_file() {
    let s = source();
    // 7-Scenes: a pose file with 12 numbers; a colour image without its depth.
    let d = common::temp_dir("ds-bad-7scenes");
    write_seven_scenes(&d, &s, true);
    fs::write(
        d.join("frame-000003.pose.txt"),
        "1 0 0 0\n0 1 0 0\n0 0 1 0\n",
    )
    .unwrap();
    let msg = err_of(&d);
    eprintln!("{msg}");
    assert_mentions(&msg, &["frame-000003.pose.txt", "16 numbers", "found 12"]);
    write_seven_scenes(&d, &s, true);
    fs::remove_file(d.join("frame-000007.depth.png")).unwrap();
    let msg = err_of(&d);
    eprintln!("{msg}");
    assert_mentions(&msg, &["frame-000007.color.jpg", "11 depth and 12 colour"]);

    // ScanNet: no depth intrinsics; a short pose; colour at another size without colour
    // intrinsics.
    let d = common::temp_dir("ds-bad-scannet");
    write_scannet(&d, &s);
    fs::remove_file(d.join("intrinsic/intrinsic_depth.txt")).unwrap();
    let msg = err_of(&d);
    eprintln!("{msg}");
    assert_mentions(&msg, &["intrinsic_depth.txt", "missing"]);
    fs::write(
        d.join("intrinsic/intrinsic_depth.txt"),
        k4(&Intrinsics::ICL_NUIM),
    )
    .unwrap();
    fs::write(d.join("pose/4.txt"), "1 0 0 0 0 1 0 0").unwrap();
    let msg = err_of(&d);
    eprintln!("{msg}");
    assert_mentions(&msg, &["pose/4.txt", "found 8"]);
    fs::write(d.join("pose/4.txt"), pose_text(&s.gt[4].unwrap())).unwrap();
    fs::remove_file(d.join("intrinsic/intrinsic_color.txt")).unwrap();
    let msg = err_of(&d);
    eprintln!("{msg}");
    assert_mentions(&msg, &["intrinsic_color.txt", "1296x968", "640x480"]);

    // Replica: no cam_params.json; a traj.txt line with 15 numbers; one pose too few.
    let top = common::temp_dir("ds-bad-replica");
    let dir = write_replica(&top, &s);
    fs::remove_file(top.join("cam_params.json")).unwrap();
    let msg = err_of(&dir);
    eprintln!("{msg}");
    assert_mentions(&msg, &["cam_params.json", "--intrinsics"]);
    let dir = write_replica(&top, &s);
    let traj = fs::read_to_string(dir.join("traj.txt")).unwrap();
    let mut lines: Vec<String> = traj.lines().map(String::from).collect();
    lines.pop();
    fs::write(dir.join("traj.txt"), lines.join("\n")).unwrap();
    let msg = err_of(&dir);
    eprintln!("{msg}");
    assert_mentions(&msg, &["traj.txt", "11 poses", "12 frames"]);
    lines[2] = lines[2].rsplit_once(' ').unwrap().0.to_string();
    fs::write(dir.join("traj.txt"), lines.join("\n")).unwrap();
    let msg = err_of(&dir);
    eprintln!("{msg}");
    assert_mentions(&msg, &["traj.txt:3", "found 15"]);

    // ETH3D: calibration.txt with three numbers.
    let d = common::temp_dir("ds-bad-eth3d");
    write_tum_like(&d, &s, true);
    fs::write(d.join("calibration.txt"), "481.2 -480 319.5\n").unwrap();
    let msg = err_of(&d);
    eprintln!("{msg}");
    assert_mentions(&msg, &["calibration.txt", "fx fy cx cy"]);
}

// ---------------------------------------------------------------------------------------
// Real sensors in ../shared/data.

/// 7-Scenes "redkitchen" as the tsdf-fusion demo ships it (Kinect v1, JPEG colour).
const SEVEN_SCENES: &str = "7scenes_redkitchen";
/// SUN3D office as the 3DMatch demo ships it (Asus Xtion, PNG colour, frames from 3160).
const SUN3D: &str = "sun3d_office_frag2";

/// What a real-sensor run must show: its frames and the bars on ATE, with the reason for
/// each number.
struct RealBar {
    /// Positions in the sequence, inclusive.
    frames: (usize, usize),
    /// After rigid alignment: the tracker's own drift.
    ate_aligned_max_m: f64,
    /// Without alignment (the first pose is the reference's): on a few dozen frames the
    /// alignment absorbs much of a wrong camera model, this does not.
    ate_unaligned_max_m: f64,
}

/// 7-Scenes frames 0..=39 at the default downsample (robust profile). Measured 3.53 mm
/// aligned and 7.91 mm unaligned on the CPU and the GPU alike (the reference poses are
/// KinectFusion's, good to 1-2 cm). With the wrong intrinsics (525, the generic Kinect's,
/// instead of the file's 585) unaligned is 13.4 mm, with depth scaled 5% wrong 8.8 mm.
/// The bars are 1.4x and 1.25x the measurements: they catch those, not float noise.
const SEVEN_SCENES_BAR: RealBar = RealBar {
    frames: (0, 39),
    ate_aligned_max_m: 5e-3,
    ate_unaligned_max_m: 10e-3,
};
/// SUN3D frames 0..=29 at the default downsample. Measured 6.78 mm aligned and 18.30 mm
/// unaligned on both backends (the poses are structure-from-motion; the Xtion's depth at
/// 2-4 m is noisy). With intrinsics 525 instead of 570.3 unaligned is 22.6 mm, with depth
/// scaled 5% wrong 24.5 mm (aligned 10.1 mm); the bars are 1.3x and 1.15x the measurements.
const SUN3D_BAR: RealBar = RealBar {
    frames: (0, 29),
    ate_aligned_max_m: 9e-3,
    ate_unaligned_max_m: 21e-3,
};

/// 7-Scenes' reference moves 36 mm and turns 1.4 degrees between frames 121 and 122, about
/// five times its neighbours' steps (two-frame ICP at full resolution measures 5-7 mm there):
/// a run over them says so. SUN3D's and ICL-NUIM's references have no such step, and a run
/// of frames 0..99 is not told of it (issue 46: it was, as "included in ATE and RPE").
fn a_real_references_jump_is_noted(data: &Path) {
    let open = |name: &str| dataset::open(&data.join(name), &SequenceOptions::default()).unwrap();
    let jump = |name: &str| open(name).jump_note(0..=open(name).len() - 1);
    assert_eq!(open(SEVEN_SCENES).jump_note(0..=99), None);
    let n = jump(SEVEN_SCENES).expect("7-Scenes' reference jump is noted");
    assert!(
        n.contains("1 time(s)") && n.contains("36.3 mm") && n.contains("frames 121 and 122"),
        "{n}"
    );
    for quiet in [SUN3D, "icl_living_room_kt2", "icl_living_room_kt2_noisy"] {
        assert_eq!(jump(quiet), None, "{quiet}");
    }
}

fn real_sensor_tracks<B: Backend + Inspect>(backend: B, root: &Path, bar: &RealBar) {
    let name = backend.name();
    let seq = dataset::open(root, &SequenceOptions::default()).unwrap();
    assert_eq!(seq.layout, Layout::SevenScenes);
    assert_eq!(seq.depth_scale, 1000.0);
    assert!(seq.frames.iter().all(|f| f.gt_cam_to_world.is_some()));
    let (a, b) = bar.frames;
    let r = run::run(
        backend,
        &seq,
        a,
        b,
        ValidParams::profile(Profile::Robust),
        |_| {},
    )
    .unwrap();
    let acc = r.metrics.accuracy.unwrap();
    eprintln!(
        "{name} {} {a}..={b}: ATE aligned {:.3} mm, unaligned {:.3} mm, RPE {:.3} mm; {} \
         surfels; median {:.1} ms/frame",
        root.display(),
        acc.ate_rmse_aligned_m * 1e3,
        acc.ate_rmse_unaligned_m * 1e3,
        acc.rpe_trans_rmse_m * 1e3,
        r.map.len(),
        r.metrics.time_per_frame_median_s * 1e3
    );
    assert_eq!(r.metrics.tracking.lost, 0);
    assert!(acc.ate_rmse_aligned_m < bar.ate_aligned_max_m, "{acc:?}");
    assert!(
        acc.ate_rmse_unaligned_m < bar.ate_unaligned_max_m,
        "{acc:?}"
    );
}

/// `compare` in lockstep, GPU against the CPU reference, over the first frames of both
/// real sequences with the robust profile: no tolerance of `src/tools/compare` exceeded.
fn compare_passes_on_real_sensors(ctx: GpuContext, data: &Path) {
    let mut ctx = Some(ctx);
    for dir in [SEVEN_SCENES, SUN3D] {
        let last = COMPARE_LAST_FRAME;
        let seq = dataset::open(&data.join(dir), &SequenceOptions::default()).unwrap();
        let gpu = match ctx.take() {
            Some(ctx) => gpu_backend(ctx),
            None => GpuBackend::open().expect("a second GPU backend"),
        };
        let c = compare(
            CpuBackend::new(),
            gpu,
            &seq,
            0,
            last,
            ValidParams::profile(Profile::Robust),
            Mode::LOCKSTEP,
        )
        .unwrap();
        eprintln!("{dir} 0..={last}: worst {:?}", c.worst);
        assert!(c.violations.is_empty(), "{dir}: {:#?}", c.violations);
        assert_eq!(c.frames.len(), last + 1);
    }
}

/// Frames `compare` runs on each real sequence (0..=this): enough for fusion and the
/// removal of unstable surfels (every 10th frame) to run twice.
const COMPARE_LAST_FRAME: usize = 20;

/// `wgslam run FOLDER` on the 7-Scenes folder as the demo ships it, with no dataset flag,
/// then `wgslam eval trajectory.tum FOLDER` against the folder's own pose files: the same
/// ATE `run` reported.
fn cli_runs_and_evaluates_the_folder_as_it_is(data: &Path) {
    let root = data.join(SEVEN_SCENES);
    let out = common::temp_dir("ds-cli");
    ok(wgslam(&[
        "run",
        root.to_str().unwrap(),
        "--backend",
        "cpu",
        "--frames",
        "0..9",
        "--out",
        out.to_str().unwrap(),
    ]));
    let m = common::read_json(out.join("metrics.json"));
    let ate = m["accuracy"]["ate_rmse_aligned_m"].as_f64().unwrap();
    let traj = out.join("trajectory.tum");
    let o = ok(wgslam(&[
        "eval",
        traj.to_str().unwrap(),
        root.to_str().unwrap(),
    ]));
    let expected = format!("ATE RMSE {:.3} mm aligned", ate * 1e3);
    assert!(
        text(&o).contains(&expected),
        "{expected:?} not in {}",
        text(&o)
    );
}
