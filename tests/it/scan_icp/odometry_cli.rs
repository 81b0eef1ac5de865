//! Scan odometry (chained pairs, the AirSim layout), and the `scan register` and
//! `bench-scan` commands' outputs.

use crate::common;

use common::harness::{plain, Test};
use common::scans::fast_gicp_dir;
use glam::{DMat3, DMat4, DVec3};
use wgslam::geometry::se3;
use wgslam::scan::odometry;
use wgslam::scan::write::{format_matrix4, transform_points};
use wgslam::scan::*;

use super::real_data::{FAST_GICP_ROT_TOL_DEG, FAST_GICP_TRANS_TOL_M};
use super::synthetic::SYNTHETIC_TOL;
use super::{pose_err, surface, write};

/// Synthetic odometry: 4 scans of the surface seen from poses moving 2 cm and 1 degree
/// per step, written as text files, with a TUM ground-truth file keyed by file stem.
fn odometry_chains_pairs_in_the_right_direction() {
    let d = common::temp_dir("scan-odo");
    let scans = d.join("scans");
    std::fs::create_dir_all(&scans).unwrap();
    let world = surface();
    let step = se3::exp(&[0.004, 0.01, 0.017, 0.02, -0.01, 0.005]);
    let mut gt = vec![se3::from_rt(DMat3::IDENTITY, DVec3::new(0.1, 0.0, 0.0))];
    for _ in 0..3 {
        gt.push(*gt.last().unwrap() * step);
    }
    let mut tum = String::from("# stamp tx ty tz qx qy qz qw\n");
    for (i, t) in gt.iter().enumerate() {
        // Scan i holds the world points in scan coordinates: inv(t_scan_to_world) * p.
        let pts = transform_points(&se3::inverse_rigid(t), &world);
        let text: String = pts
            .iter()
            .map(|p| format!("{} {} {}\n", p[0], p[1], p[2]))
            .collect();
        write(&scans, &format!("{}.xyz", 100 + i), text.as_bytes());
        let (p, q) = se3::to_tum(t);
        tum.push_str(&format!(
            "{} {} {} {} {} {} {} {}\n",
            100 + i,
            p[0],
            p[1],
            p[2],
            q[0],
            q[1],
            q[2],
            q[3]
        ));
    }
    let gt_file = write(&d, "gt.tum", tum.as_bytes());
    let out = d.join("out");
    let args = wgslam::cli::scan::OdometryArgs {
        scans_dir: scans,
        gt: Some(gt_file),
        icp: wgslam::cli::scan::IcpArgs {
            samples: Samples::All,
            max_iters: 300,
            radius: 0.5,
            final_radius: None,
            threshold: 1e-9,
            seed: 0,
            min_inliers: 10,
            min_z: None,
            max_z: None,
        },
        out: Some(out.to_path_buf()),
    };
    let (seq, odo) = wgslam::cli::scan::run_odometry(&args).unwrap();
    assert_eq!(seq.scans.len(), 4);
    assert_eq!(odo.pairs.len(), 3);
    for (est, truth) in odo.t_scan_to_world.iter().zip(&gt) {
        let (r, p) = pose_err(est, truth);
        assert!(
            r.to_radians() < SYNTHETIC_TOL * 3.0 && p < SYNTHETIC_TOL * 3.0,
            "{r} {p}"
        );
    }
    let s = odometry::summarize(&seq, &odo).unwrap();
    assert!(s.max_translation_m < SYNTHETIC_TOL, "{s:?}");
    let tsv = std::fs::read_to_string(out.join("pairs.tsv")).unwrap();
    assert_eq!(tsv.lines().count(), 4);
    assert!(tsv
        .lines()
        .nth(1)
        .unwrap()
        .starts_with("101.xyz\t100.xyz\tconverged"));
    let traj = std::fs::read_to_string(out.join("trajectory.tum")).unwrap();
    assert_eq!(traj.lines().filter(|l| !l.starts_with('#')).count(), 4);
    assert!(out.join("errors.json").is_file());
}

fn airsim_layout_is_discovered_with_poses() {
    let dir = crate::common::asset("lidar/airsim_blocks");
    let seq = odometry::discover(&dir).unwrap();
    assert_eq!(seq.scans.len(), 20);
    let gt = seq.gt_scan_to_world.as_ref().expect("poses/Drone0 present");
    // Frame 1: position (0, 0, -2.3165) NED, identity rotation.
    let (r, p) = pose_err(
        &gt[0],
        &se3::from_rt(DMat3::IDENTITY, DVec3::new(0.0, 0.0, -2.316533327102661)),
    );
    assert!(r < 1e-9 && p < 1e-9);
    assert_eq!(seq.stamp(0), 1.0);
    let c = read_cloud(&seq.scans[0]).unwrap();
    assert!((5_000..7_000).contains(&c.len()), "{}", c.len());
}

fn register_cli_writes_result_and_aligned_cloud() {
    let d = fast_gicp_dir();
    let dir = common::temp_dir("scan-register-out");
    // The output folder holds only register's outputs (they replace it as a set).
    let out = dir.join("out");
    let init = write(
        &dir,
        "init.txt",
        format_matrix4(&DMat4::IDENTITY).as_bytes(),
    );
    let args = wgslam::cli::scan::RegisterArgs {
        source: d.join("251371071.pcd"),
        target: d.join("251370668.pcd"),
        init: Some(init),
        icp: wgslam::cli::scan::IcpArgs {
            samples: Samples::Count(1000),
            max_iters: 50,
            radius: 1.0,
            final_radius: Some(0.25),
            threshold: 1e-5,
            seed: 3,
            min_inliers: 10,
            min_z: None,
            max_z: None,
        },
        nn: wgslam::cli::scan::NnBackend::Kdtree,
        out: Some(out.to_path_buf()),
    };
    let r = wgslam::cli::scan::run_register(&args).unwrap();
    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("result.json")).unwrap()).unwrap();
    assert_eq!(json["iterations"], r.iteration_count());
    let row0 = r.t_source_to_target.row(0);
    assert_eq!(json["t_source_to_target"][0][3].as_f64().unwrap(), row0.w);
    let aligned = read_ply_xyz(&out.join("aligned.ply")).unwrap();
    assert_eq!(aligned.len(), 69_792);
    // No temp files left behind.
    let leftovers: Vec<_> = std::fs::read_dir(&out)
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().contains(".tmp"))
        .collect();
    assert!(leftovers.is_empty());
}

/// Two converged 1000-sample registrations with different seeds differ by sampling jitter
/// only (measured: 0.03 degrees and 8 mm here); a bench that timed a broken or
/// different registration would be off by tenths of a degree and centimetres.
const BENCH_VS_RESEEDED_ROT_TOL_DEG: f64 = 0.1;

const BENCH_VS_RESEEDED_TRANS_TOL_M: f64 = 0.02;

fn bench_scan_cpu_only_reports_sane_rows() {
    let out = common::temp_dir("scan-bench-scan");
    let json_path = out.join("bench.json");
    let args = wgslam::cli::scan::BenchScanArgs {
        source: None,
        target: None,
        repeats: 1,
        queries: vec![1000],
        all_points_max_iters: 1,
        cpu_only: true,
        json: Some(json_path.clone()),
    };
    let report = wgslam::cli::scan::run_bench_scan(&args).unwrap();
    assert_eq!(
        (report.source_points, report.target_points),
        (69_792, 69_088)
    );
    assert_eq!(report.gpu_skipped.as_deref(), Some("--cpu-only"));
    assert!(report.gpu_adapter.is_none());
    assert!(report
        .registrations
        .iter()
        .all(|r| r.backend == "cpu-kdtree"));
    let sampled = report
        .registrations
        .iter()
        .find(|r| r.samples == Some(1000))
        .expect("a 1000-sample row");
    assert_eq!(sampled.timing.seconds.len(), 1);
    assert!(sampled.timing.iterations > 0);
    assert!(sampled.timing.median_seconds > 0.0);
    assert!(sampled.converged, "{}", sampled.status);
    let all = report
        .registrations
        .iter()
        .find(|r| r.samples.is_none())
        .expect("an all-points row");
    assert_eq!((all.timing.iterations, all.max_iterations), (1, 1));
    assert_eq!(report.nearest.len(), 1);
    assert_eq!(report.nearest[0].timing.queries, 1000);
    assert!(report.nearest[0].timing.median_seconds > 0.0);

    // The timed transform is the converged CPU registration: compare with an independent
    // (differently seeded) run of the same parameters and with relative.txt.
    let d = fast_gicp_dir();
    let source = read_pcd(&d.join("251371071.pcd")).unwrap().points;
    let target = read_pcd(&d.join("251370668.pcd")).unwrap().points;
    let reseeded = IcpParams {
        seed: 1,
        ..report.params
    };
    let r = register(&source, &target, DMat4::IDENTITY, &reseeded).unwrap();
    assert!(r.status.is_converged(), "{}", r.status);
    let m = sampled.t_source_to_target;
    let timed = DMat4::from_cols_array_2d(&m).transpose();
    let (rot, trans) = pose_err(&timed, &r.t_source_to_target);
    eprintln!("bench vs reseeded CPU registration: {rot:.4} deg {trans:.4} m");
    assert!(
        rot < BENCH_VS_RESEEDED_ROT_TOL_DEG && trans < BENCH_VS_RESEEDED_TRANS_TOL_M,
        "{rot} deg {trans} m"
    );
    let reference = read_matrix4(&d.join("relative.txt")).unwrap();
    let (rot, trans) = pose_err(&timed, &reference);
    assert!(
        rot < FAST_GICP_ROT_TOL_DEG && trans < FAST_GICP_TRANS_TOL_M,
        "{rot} deg {trans} m"
    );

    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&json_path).unwrap()).unwrap();
    assert_eq!(json["registrations"].as_array().unwrap().len(), 2);
    assert_eq!(
        json["registrations"][0]["t_source_to_target"][0][3],
        m[0][3]
    );
}

pub(super) fn tests() -> Vec<Test> {
    vec![
        plain(
            "odometry_chains_pairs_in_the_right_direction",
            odometry_chains_pairs_in_the_right_direction,
        ),
        plain(
            "airsim_layout_is_discovered_with_poses",
            airsim_layout_is_discovered_with_poses,
        ),
        plain(
            "register_cli_writes_result_and_aligned_cloud",
            register_cli_writes_result_and_aligned_cloud,
        ),
        plain(
            "bench_scan_cpu_only_reports_sane_rows",
            bench_scan_cpu_only_reports_sane_rows,
        ),
    ]
}
