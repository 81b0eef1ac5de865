//! Hostile inputs and faults (issue 27), as the cases were found: batch output folders that
//! are not the batch's, a crafted `batch.json` against the report, runs that must leave
//! their outputs complete or absent as a set, readers fed declared sizes they cannot hold,
//! silently wrong results and unclear messages. Each test names the case it reproduces.

use crate::common;

use std::path::{Path, PathBuf};
use std::process::{Child, Command};

use common::cli::{text, wgslam_env};
use common::harness::{gpu, plain};

fn wgslam(args: &[&str]) -> std::process::Output {
    wgslam_env(args, &[])
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// A one-job CPU manifest over 2 bundled frames at 160x120, job `name`, into `output`.
fn small_manifest(dir: &Path, file: &str, name: &str, output: &str) -> PathBuf {
    std::fs::create_dir_all(dir).unwrap();
    let path = dir.join(file);
    std::fs::write(
        &path,
        format!(
            "output = \"{output}\"\n[defaults]\nframes = \"1..2\"\ndownsample = 4\n\
             backend = \"cpu\"\n[[job]]\nname = \"{name}\"\nsequence = \"{}\"\n",
            common::bundled_icl().display()
        ),
    )
    .unwrap();
    path
}

// ---- 1. batch --out: never delete what the batch did not write -----------------------

fn batch_refuses_a_folder_with_files_it_did_not_write() {
    let dir = common::temp_dir("hostile-foreign");
    let out = dir.join("out");
    std::fs::create_dir_all(out.join("jobs/myjob")).unwrap();
    std::fs::write(out.join("jobs/myjob/thesis.tex"), "my thesis").unwrap();
    std::fs::write(out.join("summary.csv"), "my numbers").unwrap();
    let m = small_manifest(&dir, "m.toml", "myjob", "out");
    let o = wgslam(&["batch", s(&m)]);
    assert!(!o.status.success(), "{}", text(&o));
    assert!(text(&o).contains("not a batch folder"), "{}", text(&o));
    assert_eq!(
        std::fs::read_to_string(out.join("jobs/myjob/thesis.tex")).unwrap(),
        "my thesis"
    );
    assert_eq!(
        std::fs::read_to_string(out.join("summary.csv")).unwrap(),
        "my numbers"
    );
    assert!(!out.join("batch.json").exists());
}

fn batch_job_folder_keeps_a_file_it_did_not_write() {
    // The batch's own folder, but a user dropped a file into a job's folder: the job is
    // not started afresh (that would delete it), the file stays.
    let dir = common::temp_dir("hostile-jobfile");
    let m = small_manifest(&dir, "m.toml", "myjob", "out");
    let o = wgslam(&["batch", s(&m)]);
    assert!(o.status.success(), "{}", text(&o));
    let job = dir.join("out/jobs/myjob");
    std::fs::remove_file(job.join("job.json")).unwrap();
    std::fs::write(job.join("thesis.tex"), "my thesis").unwrap();
    std::fs::write(job.join("cpu/notes.txt"), "notes").unwrap();
    let o = wgslam(&["batch", s(&m)]);
    assert!(!o.status.success(), "{}", text(&o));
    assert!(
        text(&o).contains("thesis.tex") && text(&o).contains("did not write"),
        "{}",
        text(&o)
    );
    assert_eq!(
        std::fs::read_to_string(job.join("thesis.tex")).unwrap(),
        "my thesis"
    );
    assert_eq!(
        std::fs::read_to_string(job.join("cpu/notes.txt")).unwrap(),
        "notes"
    );
}

#[cfg(unix)]
fn batch_never_deletes_through_a_link() {
    let dir = common::temp_dir("hostile-link");
    let m = small_manifest(&dir, "m.toml", "myjob", "out");
    let o = wgslam(&["batch", s(&m)]);
    assert!(o.status.success(), "{}", text(&o));
    let elsewhere = dir.join("elsewhere");
    std::fs::create_dir_all(elsewhere.join("myjob")).unwrap();
    std::fs::write(elsewhere.join("myjob/precious.txt"), "keep").unwrap();
    let out = dir.join("out");
    std::fs::rename(out.join("jobs"), dir.join("old-jobs")).unwrap();
    std::os::unix::fs::symlink(&elsewhere, out.join("jobs")).unwrap();
    let o = wgslam(&["batch", s(&m)]);
    assert!(!o.status.success(), "{}", text(&o));
    assert!(text(&o).contains("link"), "{}", text(&o));
    assert_eq!(
        std::fs::read_to_string(elsewhere.join("myjob/precious.txt")).unwrap(),
        "keep"
    );
    // A link in place of a job's folder is not followed either.
    std::fs::remove_file(out.join("jobs")).unwrap();
    std::fs::create_dir(out.join("jobs")).unwrap();
    std::os::unix::fs::symlink(elsewhere.join("myjob"), out.join("jobs/myjob")).unwrap();
    let o = wgslam(&["batch", s(&m)]);
    assert!(!o.status.success(), "{}", text(&o));
    assert_eq!(
        std::fs::read_to_string(elsewhere.join("myjob/precious.txt")).unwrap(),
        "keep"
    );
}

fn two_manifests_cannot_share_a_folder() {
    let dir = common::temp_dir("hostile-two-manifests");
    let a = small_manifest(&dir, "a.toml", "job-a", "out");
    let b = small_manifest(&dir, "b.toml", "job-b", "out");
    let o = wgslam(&["batch", s(&a)]);
    assert!(o.status.success(), "{}", text(&o));
    let o = wgslam(&["batch", s(&b)]);
    assert!(!o.status.success(), "{}", text(&o));
    assert!(
        text(&o).contains("batch folder of manifest") && text(&o).contains("a.toml"),
        "{}",
        text(&o)
    );
    assert!(dir.join("out/jobs/job-a/job.json").is_file());
    assert!(!dir.join("out/jobs/job-b").exists());
    // The same manifest again resumes (skips its finished job).
    let o = wgslam(&["batch", s(&a)]);
    assert!(o.status.success(), "{}", text(&o));
    assert!(text(&o).contains("skipped"), "{}", text(&o));
}

fn batch_refuses_the_root_and_a_file() {
    let dir = common::temp_dir("hostile-root");
    let m = small_manifest(&dir, "m.toml", "j", "out");
    let o = wgslam(&["batch", s(&m), "--out", "/"]);
    assert!(!o.status.success(), "{}", text(&o));
    assert!(text(&o).contains("root"), "{}", text(&o));
    let file = dir.join("a-file");
    std::fs::write(&file, "x").unwrap();
    let o = wgslam(&["batch", s(&m), "--out", s(&file)]);
    assert!(!o.status.success(), "{}", text(&o));
    assert!(text(&o).contains("is a file"), "{}", text(&o));
    assert_eq!(std::fs::read_to_string(&file).unwrap(), "x");
}

/// Holds `path`'s flock(2) lock in a child `flock` process until [`release`]; returns once
/// the lock is held.
fn hold_lock(path: &Path) -> Child {
    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
    // -o: the lock stays with flock(1) itself, not with `cat`; `cat` ends when its stdin
    // closes, and flock with it, freeing the lock.
    let child = Command::new("flock")
        .arg("-o")
        .arg(path)
        .arg("cat")
        .stdin(std::process::Stdio::piped())
        .stdout(std::process::Stdio::null())
        .spawn()
        .expect("flock(1) from util-linux");
    for _ in 0..200 {
        let free = Command::new("flock")
            .args(["-n"])
            .arg(path)
            .arg("true")
            .status()
            .unwrap()
            .success();
        if !free {
            return child;
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    release(child);
    panic!("flock never took {}", path.display());
}

/// Ends a [`hold_lock`] holder and waits for it.
fn release(mut child: Child) {
    drop(child.stdin.take());
    let _ = child.wait();
}

fn a_second_batch_on_a_running_job_is_refused_by_its_lock() {
    let dir = common::temp_dir("hostile-lock");
    let m = small_manifest(&dir, "m.toml", "myjob", "out");
    let o = wgslam(&["batch", s(&m)]);
    assert!(o.status.success(), "{}", text(&o));
    std::fs::remove_file(dir.join("out/jobs/myjob/job.json")).unwrap();
    let holder = hold_lock(&dir.join("out/locks/myjob.lock"));
    let o = wgslam(&["batch", s(&m)]);
    release(holder);
    assert!(!o.status.success(), "{}", text(&o));
    assert!(text(&o).contains("being run by another"), "{}", text(&o));
    assert!(
        dir.join("out/jobs/myjob/cpu/map.ply").is_file(),
        "the other batch's job folder was touched"
    );
    let o = wgslam(&["batch", s(&m)]);
    assert!(o.status.success(), "lock released: {}", text(&o));
}

// ---- 2. report.html: no script, nothing from outside the batch folder ----------------

/// A `batch.json` of one job with `id` and `backends` (JSON), and that job's `job.json`
/// (failed, with `error`) if `record`.
fn crafted_batch(out: &Path, id: &str, backends: &str, error: &str, record: bool) {
    let spec = format!(
        r#"{{"id": {id}, "sequence": "/data/<script>alert('seq')</script>", "frames": "1..2",
        "downsample": 4, "profile": "robust", "backends": {backends},
        "overrides": [["icp-dist", "0.1\"><script>alert('o')</script>"]]}}"#,
        id = serde_json::to_string(id).unwrap()
    );
    std::fs::create_dir_all(out).unwrap();
    std::fs::write(
        out.join("batch.json"),
        format!(r#"{{"manifest": "m.toml", "jobs": [{spec}]}}"#),
    )
    .unwrap();
    if record {
        let job = out.join("jobs").join(id);
        std::fs::create_dir_all(&job).unwrap();
        std::fs::write(
            job.join("job.json"),
            format!(
                r#"{{"index": 0, "spec": {spec}, "status": "failed", "error": {},
                "runs": {{}}, "gpu_vs_cpu": null, "wall_s": 1.0}}"#,
                serde_json::to_string(error).unwrap()
            ),
        )
        .unwrap();
    }
}

/// Every tag of `html`: its name is one the report uses, it has no event-handler
/// attribute (`on...=`) outside quoted values, and every `src` is a `data:` URI.
fn assert_inert(html: &str) {
    const TAGS: [&str; 21] = [
        "!DOCTYPE",
        "html",
        "head",
        "meta",
        "title",
        "style",
        "body",
        "h1",
        "h2",
        "p",
        "code",
        "table",
        "tr",
        "th",
        "td",
        "a",
        "pre",
        "div",
        "figure",
        "img",
        "figcaption",
    ];
    let mut rest = html;
    while let Some(start) = rest.find('<') {
        let after = &rest[start + 1..];
        let end = after.find('>').expect("an unclosed tag");
        let tag = &after[..end];
        let name = tag
            .trim_start_matches('/')
            .split_whitespace()
            .next()
            .unwrap_or("");
        assert!(
            TAGS.contains(&name),
            "tag <{tag}> is not one of the report's"
        );
        // Outside quoted values: no handler, no unquoted attribute value.
        let mut outside = String::new();
        let mut quoted = false;
        for c in tag.chars() {
            if c == '"' {
                quoted = !quoted;
            } else if !quoted {
                outside.push(c);
            }
        }
        assert!(!quoted, "<{tag}>: unbalanced quotes");
        let lower = outside.to_ascii_lowercase();
        assert!(
            !lower.split_whitespace().any(|w| w.starts_with("on")),
            "<{tag}> has an event handler"
        );
        for (k, _) in tag.match_indices("src=\"") {
            assert!(
                tag[k + 5..].starts_with("data:"),
                "<{tag}>: src not embedded"
            );
        }
        rest = &after[end + 1..];
    }
    assert!(!html.contains("<script"), "a script tag");
}

fn report_escapes_every_string_and_runs_no_script() {
    let dir = common::temp_dir("hostile-report");
    let out = dir.join("out");
    let id = "<img src=x onerror=alert(1)>\"'&";
    crafted_batch(
        &out,
        id,
        r#"["cpu"]"#,
        "</pre><script>alert('error')</script>",
        true,
    );
    let o = wgslam(&["batch", "collect", s(&out)]);
    assert!(o.status.success(), "{}", text(&o));
    let html = std::fs::read_to_string(out.join("report.html")).unwrap();
    assert_inert(&html);
    assert!(
        html.contains("&lt;script&gt;alert(&#39;error&#39;)"),
        "{html}"
    );
    assert!(html.contains("&lt;img src=x onerror=alert(1)&gt;&quot;&#39;&amp;"));
}

fn crafted_batch_json_is_refused_not_reported() {
    let dir = common::temp_dir("hostile-batch-json");
    // A picture outside the batch folder that `jobs/../../secret/cpu/` would reach.
    let secret = dir.join("secret/cpu");
    std::fs::create_dir_all(&secret).unwrap();
    image_png(&secret.join("trajectory.png"));
    let cases: [(&str, &str, &str); 4] = [
        ("../../secret", r#"["cpu"]"#, "folder name"),
        ("job", r#"["\" onload=\"alert(1)"]"#, "backends"),
        ("job", r#"["cpu", "cpu"]"#, "backends"),
        ("a\u{0}b", r#"["cpu"]"#, "control character"),
    ];
    for (k, (id, backends, why)) in cases.iter().enumerate() {
        let out = dir.join(format!("out{k}"));
        crafted_batch(&out, id, backends, "x", false);
        let o = wgslam(&["batch", "collect", s(&out)]);
        assert!(!o.status.success(), "{id} {backends}: {}", text(&o));
        assert!(
            text(&o).contains(why) && text(&o).contains("batch.json"),
            "{id} {backends}: {}",
            text(&o)
        );
        assert!(!out.join("report.html").exists());
    }
}

/// A small PNG at `path`.
fn image_png(path: &Path) {
    image::RgbImage::from_pixel(8, 8, image::Rgb([200, 0, 0]))
        .save(path)
        .unwrap();
}

fn a_gt_override_never_quotes_the_file() {
    let dir = common::temp_dir("hostile-gt");
    let secret = dir.join("secret.txt");
    std::fs::write(&secret, "password=hunter2 1 2\nmore secrets\n").unwrap();
    let out = dir.join("out");
    let o = wgslam(&[
        "run",
        s(&common::bundled_icl()),
        "--frames",
        "1..2",
        "--downsample",
        "4",
        "--backend",
        "cpu",
        "--gt",
        s(&secret),
        "--out",
        s(&out),
    ]);
    assert!(!o.status.success(), "{}", text(&o));
    assert!(text(&o).contains("secret.txt:1"), "{}", text(&o));
    assert!(!text(&o).contains("hunter2"), "{}", text(&o));
}

// ---- 3. run / register outputs: complete or absent as a set --------------------------

/// `wgslam run` over the bundled frames 1..`last` at 160x120 on the CPU into `out`.
fn run_args(last: u32, out: &Path) -> Vec<String> {
    [
        "run",
        s(&common::bundled_icl()),
        "--frames",
        &format!("1..{last}"),
        "--downsample",
        "4",
        "--backend",
        "cpu",
        "--out",
        s(out),
    ]
    .iter()
    .map(|a| a.to_string())
    .collect()
}

/// The number of frames the run in `out` covered, if its four outputs agree on it; `None`
/// if the set is absent; panics on a mixed or partial set.
fn consistent_frames(out: &Path) -> Option<usize> {
    let files = ["trajectory.tum", "map.ply", "metrics.json", "frames.json"];
    let present: Vec<bool> = files.iter().map(|f| out.join(f).is_file()).collect();
    if present.iter().all(|p| !p) {
        return None;
    }
    assert!(
        present.iter().all(|p| *p),
        "partial set in {}: {present:?}",
        out.display()
    );
    let read = |f: &str| std::fs::read_to_string(out.join(f)).unwrap();
    let metrics: serde_json::Value = serde_json::from_str(&read("metrics.json")).unwrap();
    let frames: serde_json::Value = serde_json::from_str(&read("frames.json")).unwrap();
    let poses = read("trajectory.tum")
        .lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
        .count();
    let n = frames.as_array().unwrap().len();
    assert_eq!(
        metrics["frames"].as_u64(),
        Some(n as u64),
        "metrics vs frames.json"
    );
    assert_eq!(poses, n, "trajectory.tum vs frames.json: a mixed set");
    Some(n)
}

fn leftovers_beside(out: &Path) -> Vec<String> {
    let name = out.file_name().unwrap().to_string_lossy().into_owned();
    std::fs::read_dir(out.parent().unwrap())
        .unwrap()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with(&format!(".{name}.tmp-")))
        .collect()
}

fn killed_runs_leave_the_old_set_or_the_new_one() {
    let dir = common::temp_dir("hostile-kill-run");
    let out = dir.join("out");
    let o = wgslam(
        &run_args(2, &out)
            .iter()
            .map(String::as_str)
            .collect::<Vec<_>>(),
    );
    assert!(o.status.success(), "{}", text(&o));
    assert_eq!(consistent_frames(&out), Some(2));
    // Time one run of 4 frames, then kill runs at points spread over its last part, where
    // the outputs are written.
    let t0 = std::time::Instant::now();
    let o = wgslam(
        &run_args(4, &dir.join("timing"))
            .iter()
            .map(String::as_str)
            .collect::<Vec<_>>(),
    );
    assert!(o.status.success(), "{}", text(&o));
    let full = t0.elapsed().as_secs_f64();
    const TRIALS: usize = 12;
    let mut seen = [0usize; 2];
    for k in 0..TRIALS {
        // Back to the old set (2 frames) unless the last trial left it.
        let delay = full * (0.55 + 0.45 * k as f64 / TRIALS as f64);
        let mut child = Command::new(env!("CARGO_BIN_EXE_wgslam"))
            .args(run_args(4, &out))
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::null())
            .spawn()
            .unwrap();
        std::thread::sleep(std::time::Duration::from_secs_f64(delay));
        let _ = child.kill();
        let _ = child.wait();
        match consistent_frames(&out) {
            Some(2) => seen[0] += 1,
            Some(4) => seen[1] += 1,
            other => panic!("trial {k}: {other:?} frames in {}", out.display()),
        }
        if consistent_frames(&out) == Some(4) {
            let o = wgslam(
                &run_args(2, &out)
                    .iter()
                    .map(String::as_str)
                    .collect::<Vec<_>>(),
            );
            assert!(o.status.success(), "{}", text(&o));
        }
    }
    eprintln!(
        "killed runs: {} left the old set, {} the new one",
        seen[0], seen[1]
    );
    // The next run into the folder removes what the killed ones left beside it.
    let o = wgslam(
        &run_args(2, &out)
            .iter()
            .map(String::as_str)
            .collect::<Vec<_>>(),
    );
    assert!(o.status.success(), "{}", text(&o));
    assert_eq!(leftovers_beside(&out), Vec::<String>::new());
    let inside: Vec<String> = std::fs::read_dir(&out)
        .unwrap()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with('.'))
        .collect();
    assert_eq!(
        inside,
        Vec::<String>::new(),
        "temporary files inside the output folder"
    );
}

fn out_that_is_a_file_or_foreign_fails_before_the_run() {
    let dir = common::temp_dir("hostile-out-file");
    let file = dir.join("a-file");
    std::fs::write(&file, "x").unwrap();
    let o = wgslam(
        &run_args(2, &file)
            .iter()
            .map(String::as_str)
            .collect::<Vec<_>>(),
    );
    assert!(!o.status.success());
    assert!(text(&o).contains("is a file"), "{}", text(&o));
    assert_eq!(std::fs::read_to_string(&file).unwrap(), "x");
    let foreign = dir.join("mine");
    std::fs::create_dir_all(&foreign).unwrap();
    std::fs::write(foreign.join("thesis.tex"), "t").unwrap();
    let o = wgslam(
        &run_args(2, &foreign)
            .iter()
            .map(String::as_str)
            .collect::<Vec<_>>(),
    );
    assert!(!o.status.success());
    assert!(text(&o).contains("thesis.tex"), "{}", text(&o));
    assert!(!foreign.join("map.ply").exists());
    // register too, before reading the clouds.
    let o = wgslam(&[
        "register",
        "/nonexistent-a.pcd",
        "/nonexistent-b.pcd",
        "--out",
        s(&file),
    ]);
    assert!(!o.status.success());
    assert!(text(&o).contains("is a file"), "{}", text(&o));
}

fn a_failed_run_keeps_the_old_set_and_leaves_no_temporaries() {
    // `--intrinsics nan,...` used to write outputs and then fail; any failure after the
    // run must leave the folder as it was.
    let dir = common::temp_dir("hostile-failed-run");
    let out = dir.join("out");
    let o = wgslam(
        &run_args(2, &out)
            .iter()
            .map(String::as_str)
            .collect::<Vec<_>>(),
    );
    assert!(o.status.success(), "{}", text(&o));
    let before = std::fs::read(out.join("map.ply")).unwrap();
    let mut args = run_args(4, &out);
    args.extend(["--intrinsics".into(), "nan,120,80,60".into()]);
    let o = wgslam(&args.iter().map(String::as_str).collect::<Vec<_>>());
    assert!(!o.status.success(), "{}", text(&o));
    assert_eq!(consistent_frames(&out), Some(2));
    assert_eq!(std::fs::read(out.join("map.ply")).unwrap(), before);
    assert_eq!(leftovers_beside(&out), Vec::<String>::new());
}

// ---- 4. readers and sizes with bounds -------------------------------------------------

/// A PCD header with `fields`/`sizes`/`types`, `points` and `data` kind, then `body`.
fn pcd(path: &Path, fields: &str, sizes: &str, types: &str, points: &str, data: &str, body: &[u8]) {
    let counts = vec!["1"; fields.split_whitespace().count()].join(" ");
    let mut bytes = format!(
        "VERSION 0.7\nFIELDS {fields}\nSIZE {sizes}\nTYPE {types}\nCOUNT {counts}\nWIDTH 1\n\
         HEIGHT 1\nPOINTS {points}\nDATA {data}\n"
    )
    .into_bytes();
    bytes.extend_from_slice(body);
    std::fs::write(path, bytes).unwrap();
}

/// `wgslam register FILE OTHER` fails with a clear error (exit status 1: no panic, no
/// abort) that contains `want`, within seconds.
fn refused(file: &Path, other: &Path, want: &str) {
    let t0 = std::time::Instant::now();
    let o = wgslam(&["register", s(file), s(other)]);
    assert_eq!(o.status.code(), Some(1), "{}: {}", file.display(), text(&o));
    assert!(text(&o).contains(want), "{}: {}", file.display(), text(&o));
    assert!(!text(&o).contains("panicked"), "{}", text(&o));
    assert!(
        t0.elapsed().as_secs() < 20,
        "{}: took {:?}",
        file.display(),
        t0.elapsed()
    );
}

fn cloud_readers_check_declared_sizes_against_the_file() {
    let dir = common::temp_dir("hostile-readers");
    let other = dir.join("other.xyz");
    std::fs::write(&other, "0 0 0\n1 0 0\n0 1 0\n").unwrap();
    let f = |n: &str| dir.join(n);
    // PCD: 10^12 ascii points (was an allocation abort), 2^62 binary points (a panic,
    // "capacity overflow"), SIZE 2^64-1 on a skipped field (an index panic).
    pcd(
        &f("a.pcd"),
        "x y z",
        "4 4 4",
        "F F F",
        "1000000000000",
        "ascii",
        b"1 2 3\n",
    );
    refused(&f("a.pcd"), &other, "promises 1000000000000 points");
    pcd(
        &f("b.pcd"),
        "x y z",
        "4 4 4",
        "F F F",
        "4611686018427387904",
        "binary",
        &[0; 24],
    );
    refused(&f("b.pcd"), &other, "truncated");
    pcd(
        &f("c.pcd"),
        "x y z w",
        "4 4 4 18446744073709551615",
        "F F F U",
        "1",
        "binary",
        &[0; 24],
    );
    refused(&f("c.pcd"), &other, "SIZE 18446744073709551615");
    // PLY: 10^9 vertices of 2003 properties (a 268 GB reservation), 10^18 records of an
    // element before the vertices (a 50-year skip loop), binary and ASCII.
    let props: String = (0..2000)
        .map(|i| format!("property float p{i}\n"))
        .collect();
    let mut v = format!(
        "ply\nformat binary_little_endian 1.0\nelement vertex 1000000000\nproperty float x\n\
         property float y\nproperty float z\n{props}end_header\n"
    )
    .into_bytes();
    v.extend_from_slice(&[0; 64]);
    std::fs::write(f("a.ply"), v).unwrap();
    refused(&f("a.ply"), &other, "truncated PLY body");
    for (name, format, prop) in [
        ("b.ply", "binary_little_endian", "property uchar a"),
        ("c.ply", "binary_little_endian", "property list uchar int i"),
        ("d.ply", "ascii", "property uchar a"),
    ] {
        let mut v = format!(
            "ply\nformat {format} 1.0\nelement junk 1000000000000000000\n{prop}\n\
             element junk2 18446744073709551615\n{prop}\nelement vertex 1\nproperty float x\n\
             property float y\nproperty float z\nend_header\n"
        )
        .into_bytes();
        v.extend_from_slice(b"1\n2\n3 4 5\n");
        std::fs::write(f(name), v).unwrap();
        refused(&f(name), &other, "truncated PLY body");
    }
}

fn special_and_oversized_files_are_refused() {
    let dir = common::temp_dir("hostile-special");
    let other = dir.join("other.xyz");
    std::fs::write(&other, "0 0 0\n1 0 0\n0 1 0\n").unwrap();
    // /dev/zero grew until out of memory; a FIFO blocked forever.
    for args in [
        vec!["eval", "/dev/zero", "/dev/zero"],
        vec!["register", "/dev/zero", s(&other)],
    ] {
        let o = wgslam(&args);
        assert_eq!(o.status.code(), Some(1), "{}", text(&o));
        assert!(text(&o).contains("not a regular file"), "{}", text(&o));
    }
    #[cfg(unix)]
    {
        let fifo = dir.join("fifo.txt");
        let made = Command::new("mkfifo").arg(&fifo).status().unwrap();
        assert!(made.success());
        for args in [
            vec!["eval", s(&fifo), s(&fifo)],
            vec!["register", s(&fifo), s(&other)],
        ] {
            let o = wgslam(&args);
            assert_eq!(o.status.code(), Some(1), "{}", text(&o));
            assert!(text(&o).contains("not a regular file"), "{}", text(&o));
        }
    }
    let o = wgslam(&["eval", s(&dir), s(&dir)]);
    assert!(text(&o).contains("is a folder"), "{}", text(&o));
    // Past the documented input limit (lowered here through its variable).
    let big = dir.join("big.txt");
    std::fs::write(&big, vec![b'#'; 4096]).unwrap();
    let o = wgslam_env(
        &["eval", s(&big), s(&big)],
        &[("WGSLAM_MAX_INPUT_BYTES", "1000")],
    );
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    assert!(text(&o).contains("WGSLAM_MAX_INPUT_BYTES"), "{}", text(&o));
}

fn revisit_and_grid_sizes_are_bounded() {
    let dir = common::temp_dir("hostile-limits");
    let t0 = std::time::Instant::now();
    let o = wgslam(&[
        "run",
        "--revisit",
        "100000000000",
        "--out",
        s(&dir.join("o")),
    ]);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    assert!(
        text(&o).contains("WGSLAM_MAX_REVISIT_FRAMES"),
        "{}",
        text(&o)
    );
    // A 10-override grid of 4 values: 4^10 jobs (batch list ran for over 10 minutes).
    let overrides: Vec<String> = [
        "icp-dist",
        "icp-huber",
        "icp-angle",
        "fuse-dist",
        "fuse-angle",
        "max-depth",
        "min-depth",
        "icp-iters",
        "bilateral-sigma-space",
        "bilateral-sigma-depth",
    ]
    .iter()
    .map(|k| format!("{k} = [1, 2, 3, 4]"))
    .collect();
    let m = dir.join("grid.toml");
    std::fs::write(
        &m,
        format!(
            "output = \"o\"\n[[grid]]\nsequence = \"s\"\noverrides = {{ {} }}\n",
            overrides.join(", ")
        ),
    )
    .unwrap();
    let o = wgslam(&["batch", "list", s(&m)]);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    assert!(
        text(&o).contains("1048576 jobs") && text(&o).contains("WGSLAM_MAX_JOBS"),
        "{}",
        text(&o)
    );
    assert!(t0.elapsed().as_secs() < 20, "took {:?}", t0.elapsed());
}

// ---- 5. results that were silently wrong -----------------------------------------------

/// A synthetic cloud of `n` points (fixed seed), moved `dx` metres along x.
fn cloud_text(n: usize, dx: f64) -> String {
    let mut state = 12345u64;
    let mut next = || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    (0..n)
        .map(|_| {
            let (x, y, z) = (next() * 4.0, next() * 3.0, next() * 2.0);
            format!("{} {y} {z}\n", x + dx)
        })
        .collect()
}

fn odometry_orders_numbered_scans_by_number() {
    // Scans 1.bin..12.bin were chained 1->10->11->12->2 (string order).
    let dir = common::temp_dir("hostile-odometry-order");
    for i in 1..=12 {
        std::fs::write(
            dir.join(format!("{i}.xyz")),
            cloud_text(300, 0.01 * i as f64),
        )
        .unwrap();
    }
    let out = dir.join("out");
    let o = wgslam(&["odometry", s(&dir), "--out", s(&out)]);
    assert!(o.status.success(), "{}", text(&o));
    let stamps: Vec<String> = std::fs::read_to_string(out.join("trajectory.tum"))
        .unwrap()
        .lines()
        .filter(|l| !l.starts_with('#'))
        .map(|l| l.split_whitespace().next().unwrap().to_string())
        .collect();
    let want: Vec<String> = (1..=12).map(|i| i.to_string()).collect();
    assert_eq!(stamps, want);
}

fn eval_refuses_what_it_cannot_measure() {
    let dir = common::temp_dir("hostile-eval");
    let gt = std::fs::read_dir(common::bundled_icl())
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .find(|p| p.to_string_lossy().ends_with(".gt.freiburg"))
        .unwrap();
    let lines: Vec<String> = std::fs::read_to_string(&gt)
        .unwrap()
        .lines()
        .map(String::from)
        .collect();
    let write = |name: &str, f: &dyn Fn(usize, &str) -> String| {
        let p = dir.join(name);
        let body: String = lines
            .iter()
            .enumerate()
            .map(|(i, l)| f(i, l) + "\n")
            .collect();
        std::fs::write(&p, body).unwrap();
        p
    };
    // Every estimate stamp equal: RPE over 22 "pairs" of one pose.
    let same = write("same.tum", &|_, l| {
        let rest: Vec<&str> = l.split_whitespace().skip(1).collect();
        format!("5 {}", rest.join(" "))
    });
    let o = wgslam(&["eval", s(&same), s(&gt)]);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    assert!(text(&o).contains("repeats stamps"), "{}", text(&o));
    // A coordinate of 1e300 in the ground truth: "ATE NaN mm".
    let huge = write("huge.tum", &|i, l| {
        let mut f: Vec<String> = l.split_whitespace().map(String::from).collect();
        if i == 2 {
            f[1] = "1e300".into();
        }
        f.join(" ")
    });
    let o = wgslam(&["eval", s(&gt), s(&huge)]);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    assert!(!text(&o).contains("NaN"), "{}", text(&o));
    assert!(text(&o).contains("huge.tum:3"), "{}", text(&o));
}

fn run_with_nan_intrinsics_fails_before_writing() {
    let dir = common::temp_dir("hostile-nan-intrinsics");
    let out = dir.join("out");
    let mut args = run_args(2, &out);
    args.extend(["--intrinsics".into(), "nan,480,320,240".into()]);
    let o = wgslam(&args.iter().map(String::as_str).collect::<Vec<_>>());
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    assert!(text(&o).contains("finite"), "{}", text(&o));
    assert!(!out.exists(), "outputs written");
}

fn gpu_grid_refuses_a_radius_below_its_resolution() {
    // `--nn gpu-grid --radius 1e-9` found 577 of 1000 exact matches (the kd-tree 1000).
    let dir = common::temp_dir("hostile-gpu-radius");
    let a = dir.join("a.xyz");
    std::fs::write(&a, cloud_text(1000, 0.0)).unwrap();
    let o = wgslam(&[
        "register",
        s(&a),
        s(&a),
        "--nn",
        "gpu-grid",
        "--radius",
        "1e-9",
    ]);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    assert!(
        text(&o).contains("too small for the GPU grid"),
        "{}",
        text(&o)
    );
}

// ---- 6. messages -----------------------------------------------------------------------

/// A copy of the bundled sequence in `dir/seq`, for damaging.
fn copy_bundled(dir: &Path) -> PathBuf {
    let seq = dir.join("seq");
    let o = Command::new("cp")
        .arg("-r")
        .arg(common::bundled_icl())
        .arg(&seq)
        .status()
        .unwrap();
    assert!(o.success());
    seq
}

fn messages_say_what_is_wrong() {
    let dir = common::temp_dir("hostile-messages");
    let seq = copy_bundled(&dir);
    let run = |extra: &[&str]| {
        let mut a = vec![
            "run",
            s(&seq),
            "--frames",
            "1..3",
            "--downsample",
            "4",
            "--backend",
            "cpu",
        ];
        a.extend_from_slice(extra);
        wgslam(&a)
    };
    // A ground-truth path that is a folder, or a loop of links, was silently ignored.
    let o = run(&["--gt", s(&dir), "--out", s(&dir.join("o1"))]);
    assert!(text(&o).contains("is a folder"), "{}", text(&o));
    #[cfg(unix)]
    {
        std::os::unix::fs::symlink(dir.join("loop-b"), dir.join("loop-a")).unwrap();
        std::os::unix::fs::symlink(dir.join("loop-a"), dir.join("loop-b")).unwrap();
        let o = run(&["--gt", s(&dir.join("loop-a")), "--out", s(&dir.join("o2"))]);
        assert_eq!(o.status.code(), Some(1), "{}", text(&o));
        assert!(text(&o).contains("loop-a"), "{}", text(&o));
    }
    // `--max-time-diff 0` with identical stamps pairs them ("no pairs within 0 s").
    let out = dir.join("o3");
    let o = run(&["--max-time-diff", "0", "--out", s(&out)]);
    assert!(o.status.success(), "{}", text(&o));
    let metrics = std::fs::read_to_string(out.join("metrics.json")).unwrap();
    assert!(metrics.contains("ate_rmse_aligned_m"), "no ATE: {metrics}");
    // ICL-NUIM stamps near 1e15 ran the whole sequence and failed at the end.
    for name in ["associations.txt", "livingRoom2.gt.freiburg"] {
        let p = seq.join(name);
        let shifted: String = std::fs::read_to_string(&p)
            .unwrap()
            .lines()
            .map(|l| {
                let mut f: Vec<String> = l.split_whitespace().map(String::from).collect();
                for k in [0, 2] {
                    if k < f.len() && (k == 0 || name == "associations.txt") {
                        f[k] =
                            (1_000_000_000_000_000u64 + f[k].parse::<u64>().unwrap()).to_string();
                    }
                }
                f.join(" ") + "\n"
            })
            .collect();
        std::fs::write(&p, shifted).unwrap();
    }
    let o = run(&["--out", s(&dir.join("o4"))]);
    assert!(o.status.success(), "{}", text(&o));
    // An image entry that is a folder "does not exist".
    let rgb = seq.join("rgb/2.png");
    std::fs::remove_file(&rgb).unwrap();
    std::fs::create_dir(&rgb).unwrap();
    let o = run(&["--out", s(&dir.join("o5"))]);
    assert!(
        text(&o).contains("is a folder, not an image file"),
        "{}",
        text(&o)
    );
    // Manifests: a value of the wrong type, a NUL in a job name.
    let m = dir.join("m.toml");
    std::fs::write(
        &m,
        "output = \"o\"\n[defaults]\ndownsample = \"two\"\n[[job]]\nsequence = \"s\"\n",
    )
    .unwrap();
    let o = wgslam(&["batch", "list", s(&m)]);
    assert!(!text(&o).contains("untagged enum"), "{}", text(&o));
    assert!(
        text(&o).contains("downsample: a whole number"),
        "{}",
        text(&o)
    );
    std::fs::write(
        &m,
        "output = \"o\"\n[[job]]\nname = \"a\\u0000b\"\nsequence = \"s\"\n",
    )
    .unwrap();
    let o = wgslam(&["batch", "list", s(&m)]);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    assert!(text(&o).contains("control character"), "{}", text(&o));
}

fn a_closed_pipe_ends_the_output_quietly() {
    // `batch list | head -1` panicked on the broken pipe.
    let m = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("deploy/manifests/proof.toml");
    let mut child = Command::new(env!("CARGO_BIN_EXE_wgslam"))
        .args(["batch", "list", s(&m)])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take());
    let o = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!err.contains("panicked"), "{err}");
    assert_ne!(o.status.code(), Some(101), "{err}");
}

// ---- 7. a map cap ----------------------------------------------------------------------

fn the_map_cap_stops_the_run_with_a_clear_message() {
    // `--profile assignment` over 1000 revisiting frames grew to 75 M surfels unwarned.
    let dir = common::temp_dir("hostile-map-cap");
    let out = dir.join("out");
    let mut args = run_args(3, &out);
    args.extend(["--max-surfels".into(), "1000".into()]);
    let o = wgslam(&args.iter().map(String::as_str).collect::<Vec<_>>());
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    assert!(
        text(&o).contains("map capacity exceeded") && text(&o).contains("--max-surfels 1000"),
        "{}",
        text(&o)
    );
    assert!(!out.exists(), "outputs of a capped run");
}

pub fn tests() -> Vec<common::harness::Test> {
    #[allow(unused_mut)]
    let mut v = vec![
        plain(
            "batch_refuses_a_folder_with_files_it_did_not_write",
            batch_refuses_a_folder_with_files_it_did_not_write,
        ),
        plain(
            "batch_job_folder_keeps_a_file_it_did_not_write",
            batch_job_folder_keeps_a_file_it_did_not_write,
        ),
        plain(
            "two_manifests_cannot_share_a_folder",
            two_manifests_cannot_share_a_folder,
        ),
        plain(
            "batch_refuses_the_root_and_a_file",
            batch_refuses_the_root_and_a_file,
        ),
        plain(
            "a_second_batch_on_a_running_job_is_refused_by_its_lock",
            a_second_batch_on_a_running_job_is_refused_by_its_lock,
        ),
        plain(
            "report_escapes_every_string_and_runs_no_script",
            report_escapes_every_string_and_runs_no_script,
        ),
        plain(
            "crafted_batch_json_is_refused_not_reported",
            crafted_batch_json_is_refused_not_reported,
        ),
        plain(
            "a_gt_override_never_quotes_the_file",
            a_gt_override_never_quotes_the_file,
        ),
        plain(
            "killed_runs_leave_the_old_set_or_the_new_one",
            killed_runs_leave_the_old_set_or_the_new_one,
        ),
        plain(
            "out_that_is_a_file_or_foreign_fails_before_the_run",
            out_that_is_a_file_or_foreign_fails_before_the_run,
        ),
        plain(
            "a_failed_run_keeps_the_old_set_and_leaves_no_temporaries",
            a_failed_run_keeps_the_old_set_and_leaves_no_temporaries,
        ),
        plain(
            "cloud_readers_check_declared_sizes_against_the_file",
            cloud_readers_check_declared_sizes_against_the_file,
        ),
        plain(
            "special_and_oversized_files_are_refused",
            special_and_oversized_files_are_refused,
        ),
        plain(
            "revisit_and_grid_sizes_are_bounded",
            revisit_and_grid_sizes_are_bounded,
        ),
        plain(
            "odometry_orders_numbered_scans_by_number",
            odometry_orders_numbered_scans_by_number,
        ),
        plain(
            "eval_refuses_what_it_cannot_measure",
            eval_refuses_what_it_cannot_measure,
        ),
        plain(
            "run_with_nan_intrinsics_fails_before_writing",
            run_with_nan_intrinsics_fails_before_writing,
        ),
        gpu("gpu_grid_refuses_a_radius_below_its_resolution", |_ctx| {
            gpu_grid_refuses_a_radius_below_its_resolution()
        }),
        plain("messages_say_what_is_wrong", messages_say_what_is_wrong),
        plain(
            "a_closed_pipe_ends_the_output_quietly",
            a_closed_pipe_ends_the_output_quietly,
        ),
        plain(
            "the_map_cap_stops_the_run_with_a_clear_message",
            the_map_cap_stops_the_run_with_a_clear_message,
        ),
    ];
    #[cfg(unix)]
    v.push(plain(
        "batch_never_deletes_through_a_link",
        batch_never_deletes_through_a_link,
    ));
    v
}
