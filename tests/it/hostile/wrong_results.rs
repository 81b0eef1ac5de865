//! Hostile inputs: Results that were silently wrong: scan order, evaluation, NaN intrinsics, grid radius.

use super::*;

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
    ok(wgslam(&["odometry", s(&dir), "--out", s(&out)]));
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
    let said = run_fails(2, &out, &["--intrinsics", "nan,480,320,240"]);
    assert!(said.contains("finite"), "{said}");
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

pub fn tests() -> Vec<common::harness::Test> {
    vec![
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
    ]
}
