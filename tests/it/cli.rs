//! The `wgslam` executable as a user runs it: outputs written, errors clear, exit codes.

use crate::common;

use common::cli::{ok, text, wgslam};
use common::harness::{gpu, plain};

/// `wgslam bench --backends cpu --frames FRAMES ARGS...` on the bundled frames.
fn bench_cpu(frames: &str, args: &[&str]) -> std::process::Output {
    let mut all = vec!["bench", "--backends", "cpu", "--frames", frames];
    all.extend_from_slice(args);
    wgslam(&all)
}

/// `wgslam run` on the CPU over bundled `frames` into `out`, with `extra` flags.
fn run_bundled(out: &std::path::Path, frames: &str, extra: &[&str]) -> std::process::Output {
    let mut args = vec!["run", "--backend", "cpu", "--frames", frames];
    args.extend_from_slice(extra);
    args.extend_from_slice(&["--out", out.to_str().unwrap()]);
    wgslam(&args)
}

fn run_writes_all_outputs_on_bundled_data() {
    let out = common::temp_dir("cli-run");
    let o = ok(run_bundled(&out, "1..4", &[]));
    for f in [
        "trajectory.tum",
        "map.ply",
        "metrics.json",
        "frames.json",
        "map_color.png",
        "map_normals.png",
        "trajectory.png",
    ] {
        assert!(out.join(f).is_file(), "{f} missing: {}", text(&o));
    }
    let traj = std::fs::read_to_string(out.join("trajectory.tum")).unwrap();
    assert_eq!(traj.lines().filter(|l| !l.starts_with('#')).count(), 4);
    let m = common::read_json(out.join("metrics.json"));
    assert_eq!(m["frames"], 4);
    assert_eq!(m["params"]["profile"], "robust", "the default profile");
    assert!(m["accuracy"]["ate_rmse_aligned_m"].as_f64().unwrap() < 1e-3);
    // The written trajectory evaluates against the dataset's own ground truth.
    let gt = common::bundled_icl().join("livingRoom2.gt.freiburg");
    let o = ok(wgslam(&[
        "eval",
        out.join("trajectory.tum").to_str().unwrap(),
        gt.to_str().unwrap(),
    ]));
    assert!(text(&o).contains("ATE RMSE"), "{}", text(&o));
    // The map renders headlessly from the written PLY.
    let png = out.join("rerender.png");
    ok(wgslam(&[
        "render",
        out.join("map.ply").to_str().unwrap(),
        "--view",
        "normals",
        "--size",
        "320x240",
        "--backend",
        "cpu",
        "-o",
        png.to_str().unwrap(),
    ]));
    let img = image::open(&png).unwrap();
    assert_eq!((img.width(), img.height()), (320, 240));
}

/// `bench --rounds 2` on the CPU: round 1 with per-stage times, round 2 whole frames only,
/// both over the requested frames and tracking them as accurately as `run` does.
fn bench_rounds_write_every_round() {
    let out = common::temp_dir("cli-bench");
    let json = out.join("bench.json");
    let o = ok(bench_cpu(
        "1..3",
        &["--rounds", "2", "--json", json.to_str().unwrap()],
    ));
    assert!(text(&o).contains("round 2 (cpu)"), "{}", text(&o));
    let report = common::read_json(&json);
    let rounds = report["rounds"].as_array().unwrap();
    assert!(report["interleaved"].is_null());
    assert_eq!(rounds.len(), 2);
    for (k, round) in rounds.iter().enumerate() {
        let r = &round[0];
        assert_eq!(r["backend"], "cpu");
        assert_eq!(r["frames"], 3);
        assert!(r["frame_mean_s"].as_f64().unwrap() > 0.0);
        assert!(r["ate_rmse_aligned_m"].as_f64().unwrap() < 1e-3);
        // Decoding two 640x480 PNGs is measured apart from the frame time, never free.
        assert!(r["decode_ms_per_frame"].as_f64().unwrap() > 0.0);
        let stages = r["stages"].as_array().unwrap().len();
        assert_eq!(stages > 0, k == 0, "round {k}: {stages} stages");
    }
    let o = wgslam(&["bench", "--backends", "cpu", "--rounds", "0"]);
    assert!(!o.status.success(), "--rounds 0 accepted");
    // Dataset options reach the per-backend child that opens the sequence.
    let o = bench_cpu("1..2", &["--intrinsics", "1,2"]);
    assert!(
        !o.status.success(),
        "bad --intrinsics ignored: {}",
        text(&o)
    );
    assert!(text(&o).contains("intrinsics"), "{}", text(&o));
    // So does the ICP schedule.
    let o = bench_cpu("1..2", &["--icp-level-iters", "5,0"]);
    assert!(!o.status.success(), "bad schedule ignored: {}", text(&o));
    assert!(text(&o).contains("--icp-level-iters"), "{}", text(&o));
}

/// `--icp-level-iters` sets the pyramid's schedule: recorded in metrics.json, and each
/// tracked frame's iterations in frames.json name their level, coarse to fine.
fn run_with_an_icp_schedule() {
    let out = common::temp_dir("cli-levels");
    ok(run_bundled(&out, "1..3", &["--icp-level-iters", "3,2"]));
    let read = |f: &str| -> serde_json::Value { common::read_json(out.join(f)) };
    let m = read("metrics.json");
    assert_eq!(m["params"]["icp"]["level_iters"], serde_json::json!([3, 2]));
    assert!(m["accuracy"]["ate_rmse_aligned_m"].as_f64().unwrap() < 1e-3);
    let frames = read("frames.json");
    for f in &frames.as_array().unwrap()[1..] {
        let levels: Vec<u64> = f["report"]["iterations"]
            .as_array()
            .unwrap()
            .iter()
            .map(|it| it["level"].as_u64().unwrap())
            .collect();
        assert_eq!(levels.first(), Some(&1), "{levels:?}");
        assert_eq!(levels.last(), Some(&0), "{levels:?}");
    }
}

/// Either frame may come first. With the target before the source and a keyframe at
/// every frame (so that the target joins loop closure's pose graph), the graph panicked
/// on frames out of order before `wgslam icp` numbered its two frames 0 and 1.
fn icp_two_frames_prints_iterations_and_error() {
    let dir = common::temp_dir("cli-icp");
    let every_frame_a_keyframe = dir.join("keyframes.toml");
    std::fs::write(
        &every_frame_a_keyframe,
        "[relocalisation]\nkeyframe_distance_m = 0.001\n",
    )
    .unwrap();
    let params = every_frame_a_keyframe.to_str().unwrap();
    for (source, target) in [("10", "20"), ("20", "10")] {
        let o = wgslam(&[
            "icp",
            "--backend",
            "cpu",
            "--source",
            source,
            "--target",
            target,
            "--params",
            params,
        ]);
        assert!(o.status.success(), "{source} -> {target}: {}", text(&o));
        let t = text(&o);
        assert!(t.contains("against ground truth"), "{t}");
        assert!(t.contains("mean squared residual"), "{t}");
    }
}

/// Every value of a profile is a flag of its own and lands in metrics.json: the
/// assignment's profile with the robust fusion's values and others overridden.
fn profile_values_are_flags_recorded_in_metrics() {
    let out = common::temp_dir("cli-overrides");
    ok(run_bundled(
        &out,
        "1..3",
        &[
            "--profile",
            "assignment",
            "--fuse-association",
            "best-candidate",
            "--confidence-sigma",
            "0.3",
            "--min-depth",
            "0.2",
            "--icp-noise-weight",
            "true",
            "--icp-min-increment",
            "2e-6",
            "--removal-every",
            "3",
            "--pyramid-radius",
            "2",
        ],
    ));
    let m = common::read_json(out.join("metrics.json"));
    let p = &m["params"];
    assert_eq!(p["profile"], "assignment");
    assert_eq!(p["fusion"]["association"], "best-candidate");
    assert_eq!(p["fusion"]["confidence_sigma"].as_f64(), Some(0.3));
    assert_eq!(p["input"]["min_depth_m"].as_f64(), Some(0.2));
    assert_eq!(p["icp"]["noise_weight"], true);
    assert_eq!(p["icp"]["min_increment"].as_f64(), Some(2e-6));
    assert_eq!(p["fusion"]["unstable_removal"]["every_frames"], 3);
    assert_eq!(p["icp"]["pyramid"]["radius_px"], 2);
    // Values not overridden stay the assignment's.
    assert_eq!(p["fusion"]["normal_deg"].as_f64(), Some(5.0));
    assert_eq!(p["icp"]["level_iters"], serde_json::json!([10]));
}

fn clear_errors_for_bad_input() {
    let cases: [(&[&str], &str); 12] = [
        (
            &["render", "/nonexistent/map.ply", "-o", "/tmp/x.png"],
            "map.ply",
        ),
        (
            &["render", "Cargo.toml", "--size", "0x10", "-o", "/tmp/x.png"],
            "size",
        ),
        (&["run", "/nonexistent/seq"], "/nonexistent/seq"),
        (&["run", "--frames", "5..900"], "outside"),
        (&["run", "--frames", "banana"], "A..B"),
        (&["run", "--downsample", "0"], "downsample"),
        (&["run", "--max-depth", "0.05"], "--max-depth"),
        (&["run", "--removal-every", "0"], "--removal-every"),
        (&["run", "--confidence-sigma=-1"], "--confidence-sigma"),
        (&["run", "--icp-level-iters", "10,0,4"], "--icp-level-iters"),
        (
            &["run", "--icp-level-iters", "1,1,1,1,1"],
            "--icp-level-iters",
        ),
        (
            &["eval", "/nonexistent/a.tum", "/nonexistent/b.tum"],
            "a.tum",
        ),
    ];
    for (args, needle) in cases {
        let o = wgslam(args);
        assert!(!o.status.success(), "{args:?} should fail");
        let t = text(&o);
        assert!(t.contains(needle), "{args:?}: {t}");
        assert!(!t.contains("panicked"), "{args:?} panicked: {t}");
    }
}

/// Without the `rerun` feature, `run --rerun FILE` fails before running, names the feature
/// and writes no file (with the feature, tests/it/rerun.rs covers the flag).
#[cfg(not(feature = "rerun"))]
fn rerun_flag_names_the_missing_feature() {
    let out = common::temp_dir("cli-rerun");
    let rrd = out.join("run.rrd");
    let o = run_bundled(&out, "1..2", &["--rerun", rrd.to_str().unwrap()]);
    assert!(!o.status.success(), "{}", text(&o));
    assert!(
        text(&o).contains("--features rerun"),
        "no hint at the feature: {}",
        text(&o)
    );
    assert!(!rrd.exists());
    assert!(!out.join("trajectory.tum").exists(), "the run went ahead");
}

/// Map after the last pass over the map after the first, bounds: revisited noise-free
/// frames fuse into the surfels they made (measured 1.00 on 1..4; 0.95 over 1000 frames).
const REVISIT_MAP_GROWTH: std::ops::Range<f64> = 0.9..1.1;
/// ATE bound of the short noise-free revisit, mm (measured 0.18 mm at 160x120).
const REVISIT_ATE_MAX_MM: f64 = 1.0;

/// `bench --revisit`: frames 1..4 played forwards and backwards for 10 frames is three
/// passes of 3 frames (1-4, 4-1, 1-4) plus one frame; the map is read after each pass.
fn bench_revisit_reports_each_pass() {
    let out = common::temp_dir("cli-revisit");
    let json = out.join("revisit.json");
    ok(bench_cpu(
        "1..4",
        &[
            "--downsample",
            "4",
            "--revisit",
            "10",
            "--json",
            json.to_str().unwrap(),
        ],
    ));
    let v = common::read_json(&json);
    let r = &v["revisit"][0];
    assert_eq!(r["backend"], "cpu");
    assert_eq!(r["frames"], 10);
    assert_eq!(r["pass_frames"], 3);
    // Passes end at positions 3, 6 and 9 (the last frame).
    assert_eq!(r["map_after_pass"].as_array().unwrap().len(), 3, "{r}");
    // Frames seen again are fused, not appended: the map hardly grows after the first pass.
    let growth = r["map_last_over_first"].as_f64().unwrap();
    assert!(REVISIT_MAP_GROWTH.contains(&growth), "map grew {growth}x");
    assert!(
        r["ate_rmse_mm"].as_f64().unwrap() < REVISIT_ATE_MAX_MM,
        "{r}"
    );
    // Per pass: an ATE each (within the run's bound), and loop closure's count of loops
    // (none here: no keyframe is 60 frames old).
    let per_pass = r["ate_per_pass_mm"].as_array().unwrap();
    assert_eq!(per_pass.len(), 3, "{r}");
    assert!(
        per_pass
            .iter()
            .all(|a| a.as_f64().unwrap() < REVISIT_ATE_MAX_MM),
        "{r}"
    );
    let loops: Vec<u64> = r["loops_per_pass"]
        .as_array()
        .unwrap()
        .iter()
        .map(|n| n.as_u64().unwrap())
        .collect();
    assert_eq!(loops, vec![0, 0, 0], "{r}");
}

/// `--params FILE.toml`: the file's values reach the run as the flags' would, a flag given
/// too wins, and an unknown key, a bad value or an out-of-range one fails before anything
/// runs, naming it. `bench` hands the same file to its children.
fn params_file_sets_values_and_flags_win() {
    let dir = common::temp_dir("cli-params");
    let file = dir.join("p.toml");
    let write = |body: &str| std::fs::write(&file, body).unwrap();
    write(
        "profile = \"assignment\"\nicp-level-iters = [3, 2]\nicp-dist = 0.08\n\
         bilateral = true\ndownsample = 4\n",
    );
    let out = dir.join("run");
    ok(run_bundled(
        &out,
        "1..3",
        &["--params", file.to_str().unwrap(), "--icp-dist", "0.09"],
    ));
    let m = common::read_json(out.join("metrics.json"));
    let p = &m["params"];
    assert_eq!(p["profile"], "assignment", "from the file");
    assert_eq!(p["icp"]["level_iters"], serde_json::json!([3, 2]));
    assert_eq!(p["input"]["downsample"], 4);
    assert!(p["bilateral"].is_object(), "{p}");
    let icp_dist = p["icp"]["dist_m"].as_f64().unwrap();
    assert!((icp_dist - 0.09).abs() < 1e-6, "the flag wins: {icp_dist}");
    assert_eq!(m["width"], 160);
    // bench's children read the same parameters (160x120 from the file's downsample).
    let json = dir.join("bench.json");
    ok(bench_cpu(
        "1..2",
        &[
            "--params",
            file.to_str().unwrap(),
            "--json",
            json.to_str().unwrap(),
        ],
    ));
    let b = common::read_json(&json);
    assert_eq!(b["rounds"][0][0]["width"], 160, "{b}");
    for (body, needle) in [
        ("icp-dits = 0.1", "icp-dits"),
        ("fuse-association = \"nearest\"", "fuse-association"),
        ("icp-dist = \"far\"", "icp-dist"),
        ("fuse-dist = 0", "--fuse-dist"),
        ("icp-level-iters = [10, 0]", "--icp-level-iters"),
        ("frames = \"1..2\"", "unknown key `frames`"),
    ] {
        write(body);
        let out = dir.join("refused");
        let o = run_bundled(&out, "1..2", &["--params", file.to_str().unwrap()]);
        assert!(!o.status.success(), "{body} accepted");
        assert!(text(&o).contains(needle), "{body}: {}", text(&o));
        assert!(
            !out.join("trajectory.tum").exists(),
            "{body}: the run went ahead"
        );
    }
    let o = run_bundled(&dir.join("x"), "1..2", &["--params", "/nonexistent/p.toml"]);
    assert!(!o.status.success());
    assert!(text(&o).contains("/nonexistent/p.toml"), "{}", text(&o));
}

/// `compare` takes every pipeline option `run` does (`--fuse-dist` among them) and checks
/// them before opening a backend.
fn compare_takes_the_pipeline_options() {
    let o = wgslam(&["compare", "--frames", "1..2", "--fuse-dist", "0"]);
    assert!(!o.status.success());
    assert!(text(&o).contains("--fuse-dist"), "{}", text(&o));
    let help = text(&wgslam(&["compare", "--help"]));
    for flag in ["--fuse-dist", "--icp-dist", "--stable-weight", "--params"] {
        assert!(help.contains(flag), "compare --help lacks {flag}");
    }
}

/// `compare --fuse-dist` runs (lockstep on the GPU against the CPU) within the tolerances.
fn compare_runs_with_fuse_dist() {
    let o = ok(wgslam(&[
        "compare",
        "--frames",
        "1..3",
        "--downsample",
        "4",
        "--fuse-dist",
        "0.04",
    ]));
    assert!(text(&o).contains("backends agree"), "{}", text(&o));
}

/// The CPU reference's outputs do not depend on its threads (issue 48): `--threads 1` and
/// `--threads 2` write the same trajectory.tum and map.ply, byte for byte, at full
/// resolution (every twin over 640x480, the reductions' blocks more than once).
fn cpu_outputs_are_the_same_on_any_number_of_threads() {
    let run = |threads: &str| {
        let out = common::temp_dir(&format!("cli-threads-{threads}"));
        ok(run_bundled(
            &out,
            "1..3",
            &["--downsample", "1", "--threads", threads],
        ));
        out
    };
    let (one, two) = (run("1"), run("2"));
    for f in ["trajectory.tum", "map.ply"] {
        let (a, b) = (std::fs::read(one.join(f)), std::fs::read(two.join(f)));
        assert!(
            a.unwrap() == b.unwrap(),
            "{f} differs between 1 and 2 threads"
        );
    }
}

pub fn tests() -> Vec<common::harness::Test> {
    let tests = vec![
        plain(
            "run_writes_all_outputs_on_bundled_data",
            run_writes_all_outputs_on_bundled_data,
        ),
        plain(
            "bench_rounds_write_every_round",
            bench_rounds_write_every_round,
        ),
        plain(
            "icp_two_frames_prints_iterations_and_error",
            icp_two_frames_prints_iterations_and_error,
        ),
        plain("run_with_an_icp_schedule", run_with_an_icp_schedule),
        plain(
            "profile_values_are_flags_recorded_in_metrics",
            profile_values_are_flags_recorded_in_metrics,
        ),
        plain("clear_errors_for_bad_input", clear_errors_for_bad_input),
        plain(
            "cpu_outputs_are_the_same_on_any_number_of_threads",
            cpu_outputs_are_the_same_on_any_number_of_threads,
        ),
        plain(
            "bench_revisit_reports_each_pass",
            bench_revisit_reports_each_pass,
        ),
        plain(
            "params_file_sets_values_and_flags_win",
            params_file_sets_values_and_flags_win,
        ),
        plain(
            "compare_takes_the_pipeline_options",
            compare_takes_the_pipeline_options,
        ),
        gpu("compare_runs_with_fuse_dist", |_ctx| {
            compare_runs_with_fuse_dist()
        }),
    ];
    #[cfg(not(feature = "rerun"))]
    let tests = {
        let mut tests = tests;
        tests.push(plain(
            "rerun_flag_names_the_missing_feature",
            rerun_flag_names_the_missing_feature,
        ));
        tests
    };
    tests
}
