//! Hostile inputs, round 2 (issue 35): numbers validated where they enter (poses that are
//! not rigid motions, intrinsics beyond physical bounds, repeated or backwards stamps,
//! ground truth that covers no frame), caps checked at parse time (ICP iterations and
//! increment, revisit length), and the run's verdict when tracking never establishes
//! itself (depth all zero, on both backends).

use super::bounded::{bounded, icl_copy, refused_with, run_on, run_seq, seven_scenes};
use super::*;

/// 7-Scenes pose files that are not rigid motions (an all-zero rotation gave ATE 198 mm
/// instead of 1 mm), and a translation of 1e12 m: refused naming the file, nothing written.
fn poses_that_are_not_rigid_motions_are_refused() {
    let dir = common::temp_dir("hostile2-poses");
    let root = seven_scenes(&dir, 2);
    let out = dir.join("out");
    let pose = root.join("frame-000001.pose.txt");
    for (case, body, want) in [
        (
            "zero rotation",
            "0 0 0 0\n0 0 0 0\n0 0 0 0\n0 0 0 1\n",
            "not a rotation",
        ),
        (
            "1000 I",
            "1000 0 0 0\n0 1000 0 0\n0 0 1000 0\n0 0 0 1\n",
            "scaled",
        ),
        (
            "reflection",
            "-1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n",
            "a reflection",
        ),
        (
            "1e12 m",
            "1 0 0 1e12\n0 1 0 0\n0 0 1 0\n0 0 0 1\n",
            "beyond",
        ),
    ] {
        std::fs::write(&pose, body).unwrap();
        let o = run_seq(&root, "0..1", &out, &[]);
        refused_with(case, &o, &["frame-000001.pose.txt", want]);
        assert!(!out.exists(), "{case}: outputs written");
    }
}

/// Intrinsics of 1e39 and 1e300 passed the finite check and overflowed f32 into an empty
/// map: refused naming where they came from.
fn intrinsics_beyond_physical_bounds_are_refused() {
    let dir = common::temp_dir("hostile2-intrinsics");
    let root = seven_scenes(&dir, 2);
    let out = dir.join("out");
    for f in ["1e39", "1e300"] {
        std::fs::write(
            root.join("camera-intrinsics.txt"),
            format!("{f} 0 320\n0 {f} 240\n0 0 1\n"),
        )
        .unwrap();
        let o = run_seq(&root, "0..1", &out, &[]);
        refused_with(f, &o, &["camera-intrinsics.txt", "not a camera's"]);
        assert!(!out.exists(), "{f}: outputs written");
    }
}

/// A repeated stamp in `associations.txt` failed after every frame was computed ("the
/// estimate repeats stamps"): now before the first frame, nothing written.
fn repeated_stamps_fail_before_the_first_frame() {
    let dir = common::temp_dir("hostile2-stamps");
    let icl = icl_copy(&dir, 3);
    std::fs::write(
        icl.join("associations.txt"),
        "0 depth/0.png 0 rgb/0.png\n1 depth/1.png 1 rgb/1.png\n1 depth/2.png 1 rgb/2.png\n",
    )
    .unwrap();
    let out = dir.join("out");
    let o = run_seq(&icl, "0..2", &out, &[]);
    refused_with("repeated stamp", &o, &["share a stamp", "frame list"]);
    assert!(!out.exists(), "outputs written");
    // 7-Scenes frames 2^53 + 1 (one f64 stamp with 2^53) and beyond u64 (dropped).
    for big in ["9007199254740993", "99999999999999999999999"] {
        let root = seven_scenes(&dir.join(big), 2);
        for ext in ["color.png", "depth.png", "pose.txt"] {
            let from = root.join(format!("frame-000001.{ext}"));
            std::fs::rename(from, root.join(format!("frame-{big}.{ext}"))).unwrap();
        }
        let o = run_seq(&root, "0..1", &out, &[]);
        refused_with(big, &o, &[big, "frame number beyond"]);
        assert!(!out.exists(), "{big}: outputs written");
    }
}

/// A folder with a non-UTF-8 name ran every frame, then failed "cannot encode
/// .tmp-.../metrics.json": now refused before the first frame.
fn non_utf8_dataset_folder_is_refused_first() {
    use std::os::unix::ffi::OsStrExt;
    let dir = common::temp_dir("hostile2-utf8");
    let icl = icl_copy(&dir, 3);
    let odd = dir.join(std::ffi::OsStr::from_bytes(b"seq-\xff"));
    std::fs::rename(&icl, &odd).unwrap();
    let out = dir.join("out");
    let o = run_seq(&odd, "1..2", &out, &[]);
    refused_with("non-UTF-8 folder", &o, &["not UTF-8", "rename"]);
    assert!(!out.exists(), "outputs written");
}

/// A TUM folder from the bundled frames 0..`n` with depth stamps `stamps` (rgb the same),
/// `camera.json` for intrinsics, and `bom` before `rgb.txt`'s first line.
fn tum_copy(dir: &Path, stamps: &[f64], bom: bool) -> PathBuf {
    let icl = icl_copy(dir, stamps.len());
    let list = |kind: &str| -> String {
        let lines: String = stamps
            .iter()
            .enumerate()
            .map(|(i, t)| format!("{t:.6} {kind}/{i}.png\n"))
            .collect();
        format!("{}# {kind}\n{lines}", if bom { "\u{feff}" } else { "" })
    };
    std::fs::write(icl.join("rgb.txt"), list("rgb")).unwrap();
    std::fs::write(icl.join("depth.txt"), list("depth")).unwrap();
    std::fs::remove_file(icl.join("associations.txt")).unwrap();
    std::fs::remove_file(icl.join("livingRoom2.gt.freiburg")).unwrap();
    icl
}

/// Stamps that go backwards were reordered by time without a word; ground truth offset by
/// 100 s was dropped without a note; a BOM in `rgb.txt` was quoted as "\u{feff}". Now: a
/// note naming the list and the order used, a note that the ground truth covers no frame,
/// and the BOM read as the text encoding mark it is.
fn stamp_order_and_ground_truth_coverage_are_noted() {
    let dir = common::temp_dir("hostile2-order");
    let root = tum_copy(&dir, &[100.0, 100.2, 100.1], true);
    let gt: String = (0..3)
        .map(|i| format!("{} 0 0 0 0 0 0 1\n", 200.0 + 0.1 * i as f64))
        .collect();
    std::fs::write(root.join("groundtruth.txt"), gt).unwrap();
    let out = dir.join("out");
    let o = run_seq(&root, "0..2", &out, &[]);
    let t = text(&o);
    assert!(o.status.success(), "{t}");
    assert!(
        t.contains("depth.txt: stamps go backwards 1 time(s)"),
        "{t}"
    );
    assert!(t.contains("order of time"), "{t}");
    assert!(t.contains("covers none of the 3 frames"), "{t}");
    // The trajectory's stamps, in tenths of a second.
    let stamps = |out: &Path| -> Vec<i64> {
        let tum = std::fs::read_to_string(out.join("trajectory.tum")).unwrap();
        tum.lines()
            .filter(|l| !l.starts_with('#'))
            .map(|l| l.split_whitespace().next().unwrap().parse::<f64>().unwrap())
            .map(|t| (t * 10.0).round() as i64)
            .collect()
    };
    assert_eq!(stamps(&out), [1000, 1001, 1002]);
    // --stamp-order file keeps depth.txt's order, and the note says so.
    let file_order = dir.join("out-file-order");
    let o = run_seq(&root, "0..2", &file_order, &["--stamp-order", "file"]);
    let t = text(&o);
    assert!(o.status.success(), "{t}");
    assert!(t.contains("used in file order"), "{t}");
    assert_eq!(stamps(&file_order), [1000, 1002, 1001]);
}

/// Unclear messages of the issue: `frames = "5..2"` passed `batch list` and failed at run
/// time; `eval` against a TUM folder said "pass --intrinsics", which it neither takes nor
/// needs; an ICL-NUIM folder without `associations.txt` was called "closest: ScanNet"; a
/// BOM in `rgb.txt` was quoted as "\u{feff}".
fn messages_say_what_to_do() {
    let dir = common::temp_dir("hostile2-messages");
    let manifest = dir.join("m.toml");
    std::fs::write(
        &manifest,
        format!(
            "output = \"out\"\n[[job]]\nname = \"a\"\nsequence = \"{}\"\nframes = \"5..2\"\n",
            common::bundled_icl().display()
        ),
    )
    .unwrap();
    let o = bounded(&["batch", "list", s(&manifest)], &[]);
    refused_with("frames 5..2", &o, &["m.toml", "5..2", "A <= B"]);
    // eval against a TUM folder with no intrinsics at all, and a BOM in its lists.
    let tum = tum_copy(&dir, &[1.0, 2.0, 3.0], true);
    std::fs::remove_file(tum.join("camera.json")).unwrap();
    let gt: String = (1..=3)
        .map(|i| format!("{i} {} 0 0 0 0 0 1\n", 0.1 * i as f64))
        .collect();
    std::fs::write(tum.join("groundtruth.txt"), &gt).unwrap();
    let est = dir.join("est.tum");
    std::fs::write(&est, &gt).unwrap();
    let o = ok(bounded(&["eval", s(&est), s(&tum)], &[]));
    assert!(!text(&o).contains("--intrinsics"), "{}", text(&o));
    // ICL-NUIM without associations.txt.
    let icl = icl_copy(&dir.join("icl"), 2);
    std::fs::remove_file(icl.join("associations.txt")).unwrap();
    let o = run_seq(&icl, "0..1", &dir.join("out"), &[]);
    refused_with(
        "no associations.txt",
        &o,
        &["looks like ICL-NUIM", "associations.txt"],
    );
}

/// ICP with `icp-level-iters = [4000000000]` or `icp-min-increment = 1e-300` never ended;
/// `--revisit` under a raised `WGSLAM_MAX_REVISIT_FRAMES` allocated 1.9 PB and aborted:
/// all refused at parse time; so is an image wider than the image-size cap.
fn caps_are_checked_at_parse_time() {
    let dir = common::temp_dir("hostile2-caps");
    let out = dir.join("out");
    let with = |more: &[&str]| {
        let mut args = run_args(2, &out);
        args.extend(more.iter().map(|m| m.to_string()));
        args
    };
    for (case, more, want) in [
        (
            "iterations",
            ["--icp-level-iters", "4000000000"],
            "icp.level_iters",
        ),
        (
            "increment",
            ["--icp-min-increment", "1e-300"],
            "icp.min_increment",
        ),
    ] {
        let args = with(&more);
        refused_with(case, &bounded(&args, &[]), &[want]);
        assert!(!out.exists(), "{case}: outputs written");
    }
    let args = with(&["--revisit", "10000000000000"]);
    let o = bounded(&args, &[("WGSLAM_MAX_REVISIT_FRAMES", "100000000000000")]);
    refused_with("revisit", &o, &["WGSLAM_MAX_REVISIT_FRAMES", "beyond"]);
    assert!(!out.exists(), "revisit: outputs written");
    // An image wider than the cap (16385 x 1 pixels, a few bytes of PNG).
    let root = seven_scenes(&dir, 2);
    let wide = root.join("frame-000000.depth.png");
    image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::new(16_385, 1)
        .save(&wide)
        .unwrap();
    let o = run_seq(&root, "0..1", &out, &[]);
    refused_with("16385 px wide", &o, &["frame-000000.depth.png", "16385x1"]);
    assert!(!out.exists(), "wide image: outputs written");
}

/// Writes a 16-bit depth PNG of 640x480 at `path`, every pixel `value` (0: no depth).
fn flat_depth(path: &Path, value: u16) {
    image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::from_pixel(640, 480, image::Luma([value]))
        .save(path)
        .unwrap();
}

/// Writes an all-zero 16-bit depth PNG of 640x480 at `path`.
fn zero_depth(path: &Path) {
    flat_depth(path, 0);
}

/// Depth all 0 ended "tracking health: ok" with 0 poses and an empty map; depth zeroed on
/// every other frame panicked (the median of an empty history). Now: `LOST`, tracking never
/// established, and no panic, on `backend`.
fn runs_that_never_track_are_lost(backend: &str) {
    let dir = common::temp_dir(&format!("hostile2-verdict-{backend}"));
    let icl = icl_copy(&dir, 4);
    for i in 0..4 {
        zero_depth(&icl.join(format!("depth/{i}.png")));
    }
    let out = dir.join("out");
    let o = run_on(backend, &icl, "0..3", &out, &[]);
    let t = text(&o);
    assert!(o.status.success(), "{t}");
    assert!(t.contains("tracking health: LOST"), "{t}");
    assert!(t.contains("never established"), "{t}");
    let metrics = std::fs::read_to_string(out.join("metrics.json")).unwrap();
    assert!(metrics.contains("\"LOST\""), "{metrics}");
    // Every other frame without depth, from the start.
    let icl = icl_copy(&dir.join("alternate"), 4);
    for i in [0, 2] {
        zero_depth(&icl.join(format!("depth/{i}.png")));
    }
    let out = dir.join("out-alternate");
    let o = ok(run_on(backend, &icl, "0..3", &out, &[]));
    assert!(!text(&o).contains("panicked"), "{}", text(&o));
    // A flat wall 2 m ahead in every frame (ICL depth scale 5000 per metre): ICP holds the
    // in-plane directions on every tracked frame; the run said "health ok".
    let icl = icl_copy(&dir.join("wall"), 4);
    for i in 0..4 {
        flat_depth(&icl.join(format!("depth/{i}.png")), 10_000);
    }
    let out = dir.join("out-wall");
    let o = run_on(backend, &icl, "0..3", &out, &[]);
    let t = text(&o);
    assert!(
        o.status.success() && t.contains("tracking health: degenerate"),
        "{t}"
    );
}

pub fn tests() -> Vec<common::harness::Test> {
    vec![
        plain(
            "poses_that_are_not_rigid_motions_are_refused",
            poses_that_are_not_rigid_motions_are_refused,
        ),
        plain(
            "intrinsics_beyond_physical_bounds_are_refused",
            intrinsics_beyond_physical_bounds_are_refused,
        ),
        plain(
            "repeated_stamps_fail_before_the_first_frame",
            repeated_stamps_fail_before_the_first_frame,
        ),
        plain(
            "stamp_order_and_ground_truth_coverage_are_noted",
            stamp_order_and_ground_truth_coverage_are_noted,
        ),
        plain(
            "caps_are_checked_at_parse_time",
            caps_are_checked_at_parse_time,
        ),
        plain("messages_say_what_to_do", messages_say_what_to_do),
        plain(
            "non_utf8_dataset_folder_is_refused_first",
            non_utf8_dataset_folder_is_refused_first,
        ),
        plain("cpu_runs_that_never_track_are_lost", || {
            runs_that_never_track_are_lost("cpu")
        }),
        gpu("gpu_runs_that_never_track_are_lost", |_ctx| {
            runs_that_never_track_are_lost("gpu")
        }),
    ]
}
