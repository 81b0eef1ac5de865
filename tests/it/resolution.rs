//! The resolution of a run that sets none (issue 45, item 1): every pixel on the GPU
//! backend, every second pixel on the CPU reference; a value the user sets (flag or
//! parameter file) wins on either; the choice is in the summary and in `metrics.json`
//! (`downsample_from`).

use crate::common;

use std::path::Path;

use common::cli::{ok, wgslam};
use common::harness::{gpu, plain};

pub fn tests() -> Vec<common::harness::Test> {
    vec![
        gpu("a_gpu_run_without_downsample_runs_every_pixel", |_ctx| {
            a_gpu_run_without_downsample_runs_every_pixel()
        }),
        plain(
            "a_cpu_run_without_downsample_runs_every_second_pixel",
            a_cpu_run_without_downsample_runs_every_second_pixel,
        ),
    ]
}

/// `wgslam run` over bundled frames 1..2 with `args`: the metrics' image size and
/// `downsample_from`, and the summary's first line.
fn run(dir: &Path, name: &str, args: &[&str]) -> ((u64, u64), String, String) {
    let out = dir.join(name);
    let mut all = vec!["run", "--frames", "1..2", "--out", out.to_str().unwrap()];
    all.extend(args);
    let o = ok(wgslam(&all));
    let m = common::read_json(out.join("metrics.json"));
    let size = (m["width"].as_u64().unwrap(), m["height"].as_u64().unwrap());
    let from = m["downsample_from"].as_str().unwrap().to_string();
    let stdout = String::from_utf8_lossy(&o.stdout);
    let summary = stdout
        .lines()
        .find(|l| l.starts_with("2 frames 1..2 on "))
        .unwrap_or_else(|| panic!("no summary line: {stdout}"))
        .to_string();
    (size, from, summary)
}

fn a_gpu_run_without_downsample_runs_every_pixel() {
    let dir = common::temp_dir("resolution-gpu");
    let (size, from, summary) = run(&dir, "default", &["--backend", "gpu"]);
    assert_eq!(size, (640, 480), "{summary}");
    assert_eq!(from, "gpu-default");
    assert!(
        summary.contains("on gpu (640x480, every pixel, the GPU backend's default"),
        "{summary}"
    );
    let (size, from, summary) = run(&dir, "flag", &["--backend", "gpu", "--downsample", "2"]);
    assert_eq!((size, from.as_str()), ((320, 240), "set"), "{summary}");
    assert!(summary.contains("on gpu (320x240): "), "{summary}");
    // A parameter file's `[input] downsample` is set as surely as the flag.
    let params = dir.join("params.toml");
    std::fs::write(&params, "[input]\ndownsample = 4\n").unwrap();
    let (size, from, _) = run(
        &dir,
        "file",
        &["--backend", "gpu", "--params", params.to_str().unwrap()],
    );
    assert_eq!((size, from.as_str()), ((160, 120), "set"));
}

fn a_cpu_run_without_downsample_runs_every_second_pixel() {
    let dir = common::temp_dir("resolution-cpu");
    let (size, from, summary) = run(&dir, "default", &["--backend", "cpu"]);
    assert_eq!(
        (size, from.as_str()),
        ((320, 240), "cpu-default"),
        "{summary}"
    );
    assert!(
        summary.contains("every 2nd pixel, the default where the CPU reference runs"),
        "{summary}"
    );
    let (size, from, _) = run(&dir, "flag", &["--backend", "cpu", "--downsample", "1"]);
    assert_eq!((size, from.as_str()), ((640, 480), "set"));
}
