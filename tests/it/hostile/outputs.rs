//! Hostile inputs: `run` / `register` outputs: complete or absent as a set, killed or failed; the map cap.

use super::*;

// ---- 3. run / register outputs: complete or absent as a set --------------------------

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
    ok(wgslam(&run_args(2, &out)));
    assert_eq!(consistent_frames(&out), Some(2));
    // Time one run of 4 frames, then kill runs at points spread over its last part, where
    // the outputs are written.
    let t0 = std::time::Instant::now();
    ok(wgslam(&run_args(4, &dir.join("timing"))));
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
            ok(wgslam(&run_args(2, &out)));
        }
    }
    eprintln!(
        "killed runs: {} left the old set, {} the new one",
        seen[0], seen[1]
    );
    // The next run into the folder removes what the killed ones left beside it.
    ok(wgslam(&run_args(2, &out)));
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
    let o = wgslam(&run_args(2, &file));
    assert!(!o.status.success());
    assert!(text(&o).contains("is a file"), "{}", text(&o));
    assert_eq!(std::fs::read_to_string(&file).unwrap(), "x");
    let foreign = dir.join("mine");
    std::fs::create_dir_all(&foreign).unwrap();
    std::fs::write(foreign.join("thesis.tex"), "t").unwrap();
    let o = wgslam(&run_args(2, &foreign));
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
    ok(wgslam(&run_args(2, &out)));
    let before = std::fs::read(out.join("map.ply")).unwrap();
    run_fails(4, &out, &["--intrinsics", "nan,120,80,60"]);
    assert_eq!(consistent_frames(&out), Some(2));
    assert_eq!(std::fs::read(out.join("map.ply")).unwrap(), before);
    assert_eq!(leftovers_beside(&out), Vec::<String>::new());
}

// ---- 7. a map cap ----------------------------------------------------------------------

fn the_map_cap_stops_the_run_with_a_clear_message() {
    // `--profile assignment` over 1000 revisiting frames grew to 75 M surfels unwarned.
    let dir = common::temp_dir("hostile-map-cap");
    let out = dir.join("out");
    let said = run_fails(3, &out, &["--max-surfels", "1000"]);
    assert!(
        said.contains("map capacity exceeded") && said.contains("--max-surfels 1000"),
        "{said}"
    );
    assert!(!out.exists(), "outputs of a capped run");
}

pub fn tests() -> Vec<common::harness::Test> {
    vec![
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
            "the_map_cap_stops_the_run_with_a_clear_message",
            the_map_cap_stops_the_run_with_a_clear_message,
        ),
    ]
}
