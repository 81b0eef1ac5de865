//! Trajectory evaluation on synthetic trajectories with known answers, and on the bundled
//! ICL-NUIM ground truth.

use crate::common;

use common::harness::plain;
use glam::{DMat4, DVec3};
use wgslam::eval::{align_rigid, associate, ate, ate_with, rpe, rpe_with};
use wgslam::geometry::se3;
use wgslam::io::trajectory::{read_tum, write_tum};

/// f64 pipelines of a few dozen operations on metre-scale values stay below 1e-9.
const EXACT_TOL: f64 = 1e-9;

/// A smooth 3-D path: a rising helix with the camera turning about all three axes.
fn helix(n: usize) -> Vec<(f64, DMat4)> {
    (0..n)
        .map(|k| {
            let s = k as f64 * 0.1;
            let pose = se3::from_rt(
                glam::DMat3::from_euler(glam::EulerRot::ZYX, 0.7 * s, 0.2 * s.sin(), 0.1 * s),
                DVec3::new(2.0 * s.cos(), 2.0 * s.sin(), 0.3 * s),
            );
            (100.0 + k as f64 / 30.0, pose)
        })
        .collect()
}

fn moved(traj: &[(f64, DMat4)], world: DMat4) -> Vec<(f64, DMat4)> {
    traj.iter().map(|(s, p)| (*s, world * *p)).collect()
}

fn rotated_translated_copy_aligns_to_zero() {
    let gt = helix(60);
    let a = se3::exp(&[0.4, -0.9, 1.3, 5.0, -3.0, 2.0]);
    let est = moved(&gt, a);
    let s = ate(&est, &gt, true).unwrap();
    assert_eq!(s.pairs, 60);
    assert!(s.rmse_m < EXACT_TOL && s.max_m < EXACT_TOL, "{s:?}");
    let raw = ate(&est, &gt, false).unwrap();
    assert!(
        raw.rmse_m > 1.0,
        "unaligned ATE should see the offset: {raw:?}"
    );
    // The alignment is the inverse of the applied world transform.
    let e: Vec<DVec3> = est.iter().map(|p| p.1.w_axis.truncate()).collect();
    let g: Vec<DVec3> = gt.iter().map(|p| p.1.w_axis.truncate()).collect();
    let t = align_rigid(&e, &g).unwrap();
    let d = (t * a - DMat4::IDENTITY).to_cols_array();
    assert!(d.iter().all(|v| v.abs() < EXACT_TOL), "{t}");
}

fn planar_points_need_the_reflection_fix() {
    // Coplanar points: the cross-covariance has rank 2, where an unguarded SVD solution can
    // be a reflection. The result must be a proper rotation that maps the points exactly.
    let e: Vec<DVec3> = [(0.0, 0.0), (1.0, 0.0), (0.0, 2.0), (3.0, 1.0), (-1.0, 4.0)]
        .iter()
        .map(|&(x, y)| DVec3::new(x, y, 0.0))
        .collect();
    let a = se3::exp(&[2.0, 0.5, -1.0, 0.1, 0.2, 0.3]);
    let g: Vec<DVec3> = e.iter().map(|p| a.transform_point3(*p)).collect();
    let t = align_rigid(&e, &g).unwrap();
    let det = glam::DMat3::from_mat4(t).determinant();
    assert!((det - 1.0).abs() < EXACT_TOL, "det {det}");
    for (p, q) in e.iter().zip(&g) {
        assert!((t.transform_point3(*p) - *q).length() < EXACT_TOL);
    }
    // Mirrored data cannot be fitted by a rotation: the best fit leaves a residual.
    let mirrored: Vec<DVec3> = [
        (0.0, 0.0, 0.0),
        (1.0, 0.0, 0.0),
        (0.0, 1.0, 0.0),
        (0.0, 0.0, 1.0),
    ]
    .iter()
    .map(|&(x, y, z)| DVec3::new(x, y, z))
    .collect();
    let flipped: Vec<DVec3> = mirrored
        .iter()
        .map(|p| DVec3::new(p.x, p.y, -p.z))
        .collect();
    let t = align_rigid(&mirrored, &flipped).unwrap();
    assert!((glam::DMat3::from_mat4(t).determinant() - 1.0).abs() < EXACT_TOL);
    assert!(align_rigid(&[], &[]).is_err());
    assert!(align_rigid(&[DVec3::ZERO], &[]).is_err());
}

fn ate_statistics_of_known_errors() {
    let gt = helix(4);
    // Offsets of 1, 2, 3, 4 m in different directions, no alignment.
    let dirs = [DVec3::X, DVec3::Y, DVec3::Z, DVec3::new(0.6, 0.0, 0.8)];
    let est: Vec<(f64, DMat4)> = gt
        .iter()
        .enumerate()
        .map(|(k, (s, p))| {
            let mut q = *p;
            q.w_axis += (dirs[k] * (k + 1) as f64).extend(0.0);
            (*s, q)
        })
        .collect();
    let s = ate(&est, &gt, false).unwrap();
    assert_eq!(s.pairs, 4);
    assert!(
        (s.rmse_m - (30.0f64 / 4.0).sqrt()).abs() < EXACT_TOL,
        "{s:?}"
    );
    assert!((s.mean_m - 2.5).abs() < EXACT_TOL);
    assert!((s.median_m - 2.5).abs() < EXACT_TOL);
    assert!((s.max_m - 4.0).abs() < EXACT_TOL);
}

fn association_by_stamp() {
    let gt = helix(10);
    // Estimate stamps 5 ms late, every other frame, plus one stamp far from any GT.
    let mut est: Vec<(f64, DMat4)> = gt.iter().step_by(2).map(|(s, p)| (s + 0.005, *p)).collect();
    est.push((500.0, DMat4::IDENTITY));
    let pairs = associate(&est, &gt, 0.02);
    assert_eq!(pairs, vec![(0, 0), (1, 2), (2, 4), (3, 6), (4, 8)]);
    let s = ate(&est, &gt, false).unwrap();
    assert_eq!(s.pairs, 5);
    assert!(s.rmse_m < EXACT_TOL);
    // Too tight a window associates nothing: an error, not NaN.
    let msg = ate_with(&est, &gt, true, 0.001).unwrap_err().to_string();
    assert!(msg.contains("right files"), "{msg}");
    assert!(rpe_with(&est, &gt, 1, 0.001).is_err());
}

fn rpe_of_a_world_offset_is_zero() {
    let gt = helix(40);
    let est = moved(&gt, se3::exp(&[0.3, 0.2, -0.5, 1.0, 2.0, 3.0]));
    for delta in [1, 5, 39] {
        let s = rpe(&est, &gt, delta).unwrap();
        assert_eq!(s.pairs, 40 - delta);
        assert!(
            s.trans_rmse_m < EXACT_TOL && s.rot_rmse_deg < EXACT_TOL,
            "{s:?}"
        );
    }
    assert!(rpe(&est, &gt, 0).is_err());
    assert!(
        rpe(&est, &gt, 40).is_err(),
        "no pair 40 frames apart in 40 poses"
    );
}

fn rpe_of_a_known_per_step_error() {
    let gt = helix(30);
    // Each estimated step is the true step followed by the same small error D:
    // P_{k+1} = P_k (Q_k^-1 Q_{k+1}) D, so E = (Q_k^-1 Q_{k+1})^-1 (P_k^-1 P_{k+1}) = D.
    let d = se3::exp(&[0.01, -0.02, 0.005, 0.03, 0.0, -0.04]);
    let d_trans = se3::translation_norm(&d);
    let d_rot_deg = se3::rotation_angle(&d).to_degrees();
    let mut est = vec![gt[0]];
    for k in 1..gt.len() {
        let step = se3::inverse_rigid(&gt[k - 1].1) * gt[k].1;
        let prev = est[k - 1].1;
        est.push((gt[k].0, prev * step * d));
    }
    let s = rpe(&est, &gt, 1).unwrap();
    assert_eq!(s.pairs, 29);
    assert!(
        (s.trans_rmse_m - d_trans).abs() < EXACT_TOL,
        "{s:?} vs {d_trans}"
    );
    // acos near small angles loses ~1e-8 rad of precision.
    assert!(
        (s.rot_rmse_deg - d_rot_deg).abs() < 1e-6,
        "{s:?} vs {d_rot_deg}"
    );
    // The estimate drifts, so the aligned ATE is clearly non-zero.
    assert!(ate(&est, &gt, true).unwrap().rmse_m > 0.01);
}

fn bundled_icl_ground_truth_evaluates_against_itself() {
    let p = crate::common::asset("icl_living_room_kt2/livingRoom2.gt.freiburg");
    let gt = read_tum(&p).unwrap();
    // Frame indices as stamps associate one to one.
    let a = ate(&gt, &gt, true).unwrap();
    assert_eq!(a.pairs, gt.len());
    assert!(a.rmse_m < EXACT_TOL);
    let r = rpe(&gt, &gt, 1).unwrap();
    assert_eq!(r.pairs, gt.len() - 1);
    assert!(r.trans_rmse_m < EXACT_TOL);

    // Written estimate in another world frame: 9-decimal rounding only.
    let est = moved(&gt, se3::exp(&[0.0, 1.0, 0.0, 0.5, 0.0, -1.0]));
    let dir = std::env::temp_dir().join(format!("wgslam-eval-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let f = dir.join("est.txt");
    write_tum(&f, &est).unwrap();
    let back = read_tum(&f).unwrap();
    // Values printed with 9 decimals: the aligned error stays below 1e-8 m.
    assert!(ate(&back, &gt, true).unwrap().rmse_m < 1e-8);
    assert!(ate(&back, &gt, false).unwrap().rmse_m > 0.5);
    let _ = std::fs::remove_dir_all(&dir);
}

pub fn tests() -> Vec<common::harness::Test> {
    vec![
        plain(
            "rotated_translated_copy_aligns_to_zero",
            rotated_translated_copy_aligns_to_zero,
        ),
        plain(
            "planar_points_need_the_reflection_fix",
            planar_points_need_the_reflection_fix,
        ),
        plain(
            "ate_statistics_of_known_errors",
            ate_statistics_of_known_errors,
        ),
        plain("association_by_stamp", association_by_stamp),
        plain(
            "rpe_of_a_world_offset_is_zero",
            rpe_of_a_world_offset_is_zero,
        ),
        plain(
            "rpe_of_a_known_per_step_error",
            rpe_of_a_known_per_step_error,
        ),
        plain(
            "bundled_icl_ground_truth_evaluates_against_itself",
            bundled_icl_ground_truth_evaluates_against_itself,
        ),
    ]
}
