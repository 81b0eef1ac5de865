//! Hostile inputs, round 2 (issue 35): every reader bounded. FIFOs, folders, `/dev/zero`
//! and sparse giants in the place of each input file the first round did not cover
//! (manifests, `--params`, `batch.json`, 7-Scenes pose files, the first depth image,
//! `camera.json`, ground truth under `eval`), and a check of the sources that no reader
//! opens a file except through `wgslam::io::input`.

use super::*;

/// Longest a refused input may take, seconds: each case fails on the file's metadata in
/// milliseconds; a FIFO that blocked would hang until `timeout` kills it (exit 124).
pub(super) const REFUSE_WITHIN_S: u32 = 60;

/// `wgslam` under coreutils `timeout`, so a hang fails the test instead of blocking it.
fn timed() -> Command {
    let mut c = Command::new("timeout");
    c.args(["-k", "5", &REFUSE_WITHIN_S.to_string()])
        .arg(env!("CARGO_BIN_EXE_wgslam"));
    c
}

/// `wgslam args` with `env` under [`timed`].
pub(super) fn bounded<S: AsRef<std::ffi::OsStr>>(
    args: &[S],
    env: &[(&str, &str)],
) -> std::process::Output {
    let mut c = timed();
    c.args(args);
    for (k, v) in env {
        c.env(k, v);
    }
    c.output().expect("run wgslam under timeout")
}

/// Asserts that `o` is a refusal (exit 1: no panic, abort or hang) whose message holds
/// every one of `want`; `case` names the case in failures.
pub(super) fn refused_with(case: &str, o: &std::process::Output, want: &[&str]) {
    let t = text(o);
    assert_ne!(
        o.status.code(),
        Some(124),
        "{case}: hung ({REFUSE_WITHIN_S} s)"
    );
    assert_eq!(o.status.code(), Some(1), "{case}: {t}");
    assert!(!t.contains("panicked"), "{case}: {t}");
    for w in want {
        assert!(t.contains(w), "{case}: no {w:?} in: {t}");
    }
}

/// Makes a FIFO at `path` (no writer ever opens it).
pub(super) fn fifo(path: &Path) {
    let _ = std::fs::remove_file(path);
    let ok = Command::new("mkfifo").arg(path).status().unwrap().success();
    assert!(ok, "mkfifo {}", path.display());
}

/// A 7-Scenes folder of `n` frames (bundled ICL frames 1..=n renamed
/// `frame-00000i.{color,depth}.png`, depth rescaled to millimetres) with pose files of identity rotation moving 1 cm
/// along x a frame.
pub(super) fn seven_scenes(dir: &Path, n: usize) -> PathBuf {
    let root = dir.join("7scenes");
    std::fs::create_dir_all(&root).unwrap();
    let icl = common::bundled_icl();
    for i in 0..n {
        let stem = root.join(format!("frame-{i:06}"));
        let src = |kind: &str| icl.join(kind).join(format!("{}.png", i + 1));
        std::fs::copy(src("rgb"), stem.with_extension("color.png")).unwrap();
        // ICL-NUIM's 5000 units a metre as 7-Scenes' 1000.
        let mut depth = image::open(src("depth")).unwrap().into_luma16();
        depth.pixels_mut().for_each(|p| p.0[0] /= 5);
        depth.save(stem.with_extension("depth.png")).unwrap();
        let x = 0.01 * i as f64;
        std::fs::write(
            stem.with_extension("pose.txt"),
            format!("1 0 0 {x}\n0 1 0 0\n0 0 1 0\n0 0 0 1\n"),
        )
        .unwrap();
    }
    root
}

/// An ICL-NUIM folder of the bundled frames 0..`n` (associations, images, ground truth,
/// `camera.json`).
pub(super) fn icl_copy(dir: &Path, n: usize) -> PathBuf {
    let root = dir.join("icl");
    let icl = common::bundled_icl();
    for sub in ["depth", "rgb"] {
        std::fs::create_dir_all(root.join(sub)).unwrap();
        for i in 0..n {
            let f = format!("{sub}/{i}.png");
            std::fs::copy(icl.join(&f), root.join(&f)).unwrap();
        }
    }
    let assoc: String = (0..n)
        .map(|i| format!("{i} depth/{i}.png {i} rgb/{i}.png\n"))
        .collect();
    std::fs::write(root.join("associations.txt"), assoc).unwrap();
    for f in ["camera.json", "livingRoom2.gt.freiburg"] {
        std::fs::copy(icl.join(f), root.join(f)).unwrap();
    }
    root
}

/// `wgslam run root` over frames `frames` at 160x120 on the CPU into `out`, bounded.
pub(super) fn run_seq(
    root: &Path,
    frames: &str,
    out: &Path,
    more: &[&str],
) -> std::process::Output {
    run_on("cpu", root, frames, out, more)
}

/// [`run_seq`] on `backend` (paths passed as they are, UTF-8 or not).
pub(super) fn run_on(
    backend: &str,
    root: &Path,
    frames: &str,
    out: &Path,
    more: &[&str],
) -> std::process::Output {
    timed()
        .arg("run")
        .arg(root)
        .args([
            "--frames",
            frames,
            "--downsample",
            "4",
            "--backend",
            backend,
        ])
        .arg("--out")
        .arg(out)
        .args(more)
        .output()
        .expect("run wgslam under timeout")
}

/// Manifests, `--params` files and `batch.json` that are FIFOs or `/dev/zero`: refused at
/// once, naming the file (they hung, or read without bound until the allocator aborted).
fn batch_and_params_inputs_that_are_not_files_are_refused() {
    let dir = common::temp_dir("hostile2-batch-fifo");
    let pipe = dir.join("pipe.toml");
    fifo(&pipe);
    let zero = "/dev/zero";
    for (case, args) in [
        ("batch FIFO", vec!["batch", s(&pipe)]),
        ("batch list FIFO", vec!["batch", "list", s(&pipe)]),
        ("batch list /dev/zero", vec!["batch", "list", zero]),
        ("batch diff /dev/zero", vec!["batch", "diff", zero, zero]),
    ] {
        let o = bounded(&args, &[]);
        refused_with(case, &o, &["not a regular file"]);
    }
    let out = dir.join("out");
    for p in [s(&pipe), zero] {
        let mut args = run_args(2, &out);
        args.extend(["--params".into(), p.into()]);
        refused_with(&format!("run --params {p}"), &bounded(&args, &[]), &[p]);
        assert!(!out.exists(), "run --params {p}: outputs written");
    }
    // batch collect over a folder whose batch.json is a FIFO, then /dev/zero.
    let batch = dir.join("batch");
    std::fs::create_dir_all(&batch).unwrap();
    fifo(&batch.join("batch.json"));
    let o = bounded(&["batch", "collect", s(&batch)], &[]);
    refused_with(
        "collect FIFO batch.json",
        &o,
        &["batch.json", "not a regular file"],
    );
    std::fs::remove_file(batch.join("batch.json")).unwrap();
    std::os::unix::fs::symlink(zero, batch.join("batch.json")).unwrap();
    let o = bounded(&["batch", "collect", s(&batch)], &[]);
    refused_with("collect /dev/zero batch.json", &o, &["batch.json"]);
    assert!(
        !batch.join("summary.csv").exists(),
        "collect wrote a summary"
    );
}

/// Dataset files that are a FIFO, `/dev/zero`, a folder or a 5 GB sparse file: a 7-Scenes
/// pose file, the first depth image, `camera.json`, intrinsics; each refused by name
/// before any output is written (they hung, aborted, or were taken as missing and replaced
/// by defaults).
fn dataset_files_that_are_not_files_are_refused_by_name() {
    let dir = common::temp_dir("hostile2-dataset-fifo");
    let root = seven_scenes(&dir, 2);
    let out = dir.join("out");
    let pose = root.join("frame-000001.pose.txt");
    let check = |case: &str, want: &[&str]| {
        refused_with(case, &run_seq(&root, "0..1", &out, &[]), want);
        assert!(!out.exists(), "{case}: outputs written");
    };
    fifo(&pose);
    check(
        "FIFO pose",
        &["frame-000001.pose.txt", "not a regular file"],
    );
    std::fs::remove_file(&pose).unwrap();
    std::os::unix::fs::symlink("/dev/zero", &pose).unwrap();
    check("/dev/zero pose", &["frame-000001.pose.txt"]);
    std::fs::remove_file(&pose).unwrap();
    let sparse = std::fs::File::create(&pose).unwrap();
    sparse.set_len(5 << 30).unwrap();
    check(
        "5 GB sparse pose",
        &["frame-000001.pose.txt", "more than the limit"],
    );
    std::fs::remove_file(&pose).unwrap();
    std::fs::write(&pose, "1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n").unwrap();
    // Intrinsics that are a folder were "missing" and the 7-Scenes defaults were used.
    let k = root.join("camera-intrinsics.txt");
    std::fs::create_dir_all(&k).unwrap();
    check("intrinsics folder", &["camera-intrinsics.txt", "a folder"]);
    std::fs::remove_dir(&k).unwrap();
    // The first depth image, whose header gives the image size, as a FIFO.
    let depth = root.join("frame-000000.depth.png");
    fifo(&depth);
    check("FIFO first depth", &["frame-000000.depth.png"]);

    // camera.json as a FIFO and as a folder in an ICL-NUIM folder.
    let icl = icl_copy(&dir, 2);
    let cam = icl.join("camera.json");
    fifo(&cam);
    refused_with(
        "FIFO camera.json",
        &run_seq(&icl, "0..1", &out, &[]),
        &["camera.json", "not a regular file"],
    );
    std::fs::remove_file(&cam).unwrap();
    std::fs::create_dir_all(&cam).unwrap();
    refused_with(
        "folder camera.json",
        &run_seq(&icl, "0..1", &out, &[]),
        &["camera.json", "a folder"],
    );
    assert!(!out.exists(), "outputs written");
    // eval against a folder whose ground truth is a FIFO.
    std::fs::remove_dir(&cam).unwrap();
    let gt = icl.join("livingRoom2.gt.freiburg");
    let est = dir.join("est.tum");
    std::fs::copy(&gt, &est).unwrap();
    fifo(&gt);
    refused_with(
        "eval FIFO ground truth",
        &bounded(&["eval", s(&est), s(&icl)], &[]),
        &["livingRoom2.gt.freiburg", "not a regular file"],
    );
}

/// A 7-Scenes colour JPEG cut to a third decoded (grey below the cut) without a word:
/// refused, naming the file.
fn truncated_jpeg_is_refused() {
    let dir = common::temp_dir("hostile2-jpeg");
    let root = seven_scenes(&dir, 2);
    for i in 0..2 {
        let png = root.join(format!("frame-{i:06}.color.png"));
        let jpg = root.join(format!("frame-{i:06}.color.jpg"));
        image::open(&png).unwrap().to_rgb8().save(&jpg).unwrap();
        std::fs::remove_file(png).unwrap();
    }
    let out = dir.join("out");
    let whole = run_seq(&root, "0..1", &out, &[]);
    assert!(whole.status.success(), "{}", text(&whole));
    let jpg = root.join("frame-000001.color.jpg");
    let bytes = std::fs::read(&jpg).unwrap();
    std::fs::write(&jpg, &bytes[..bytes.len() / 3]).unwrap();
    let out = dir.join("out-cut");
    let o = run_seq(&root, "0..1", &out, &[]);
    refused_with(
        "JPEG cut to a third",
        &o,
        &["frame-000001.color.jpg", "cut short"],
    );
    assert!(!out.exists(), "outputs written");
}

/// `odometry` skipped a scan that is a FIFO and took `1.xyz` and `01.xyz` as one stamp:
/// both refused, naming the files.
fn odometry_scans_that_are_fifos_or_share_a_stamp_are_refused() {
    let dir = common::temp_dir("hostile2-odometry");
    let cloud = "0 0 0\n1 0 0\n0 1 0\n0 0 1\n";
    for name in ["1.xyz", "2.xyz"] {
        std::fs::write(dir.join(name), cloud).unwrap();
    }
    fifo(&dir.join("3.xyz"));
    let o = bounded(&["odometry", s(&dir), "--out", s(&dir.join("out"))], &[]);
    refused_with("FIFO scan", &o, &["3.xyz", "not a regular file"]);
    std::fs::remove_file(dir.join("3.xyz")).unwrap();
    std::fs::write(dir.join("01.xyz"), cloud).unwrap();
    let o = bounded(&["odometry", s(&dir), "--out", s(&dir.join("out"))], &[]);
    refused_with("1.xyz and 01.xyz", &o, &["1.xyz", "same stamp 1"]);
    assert!(!dir.join("out").exists(), "outputs written");
}

/// Every file the workspace reads goes through `crates/data/src/io/input.rs`: no other
/// source file under `src/` or `crates/` may call the standard library's or `image`'s own readers, except the ones listed
/// here with the reason they are not input files.
fn every_reader_goes_through_the_bounded_input_module() {
    const READERS: [&str; 6] = [
        "fs::read(",
        "read_to_string(",
        "File::open(",
        "image::open(",
        "ImageReader::open(",
        "image_dimensions(",
    ];
    // (file, pattern): why it may read directly.
    const ALLOWED: [(&str, &str); 3] = [
        // The GPU's pipeline cache, a file this program writes, read with a size bound; the
        // GPU engine is a floor below the data crate's input module.
        ("crates/gpu/src/pipeline_cache.rs", "File::open("),
        // Its own temporary recording file, written by this process a moment before.
        ("src/tools/rerun_log.rs", "File::open("),
        // /proc/self/status: the kernel's report of this process's memory.
        ("src/tools/run/mod.rs", "read_to_string("),
    ];
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let mut files = vec![root.join("src"), root.join("crates")];
    let mut found = Vec::new();
    while let Some(p) = files.pop() {
        if p.is_dir() {
            files.extend(std::fs::read_dir(&p).unwrap().map(|e| e.unwrap().path()));
            continue;
        }
        let rel = p.strip_prefix(&root).unwrap().to_path_buf();
        let rel = rel.to_string_lossy().to_string();
        if rel == "crates/data/src/io/input.rs" || !rel.ends_with(".rs") {
            continue;
        }
        let code = std::fs::read_to_string(&p).unwrap();
        // Unit tests read the fixtures they wrote.
        let code = code.split("#[cfg(test)]").next().unwrap();
        for (n, line) in code.lines().enumerate() {
            if line.trim_start().starts_with("//") {
                continue;
            }
            for r in READERS {
                if line.contains(r) && !ALLOWED.contains(&(rel.as_str(), r)) {
                    found.push(format!("{rel}:{}: {}", n + 1, line.trim()));
                }
            }
        }
    }
    assert!(
        found.is_empty(),
        "readers that bypass wgslam::io::input (use read_kind / open_kind):\n{}",
        found.join("\n")
    );
}

pub fn tests() -> Vec<common::harness::Test> {
    vec![
        plain(
            "batch_and_params_inputs_that_are_not_files_are_refused",
            batch_and_params_inputs_that_are_not_files_are_refused,
        ),
        plain(
            "dataset_files_that_are_not_files_are_refused_by_name",
            dataset_files_that_are_not_files_are_refused_by_name,
        ),
        plain("truncated_jpeg_is_refused", truncated_jpeg_is_refused),
        plain(
            "odometry_scans_that_are_fifos_or_share_a_stamp_are_refused",
            odometry_scans_that_are_fifos_or_share_a_stamp_are_refused,
        ),
        plain(
            "every_reader_goes_through_the_bounded_input_module",
            every_reader_goes_through_the_bounded_input_module,
        ),
    ]
}
