//! Scan kernels without a GPU: the WGSL of `nn_brute`, `nn_grid` and `cross_covariance`
//! parses and validates with naga, its structs match `layout::scan`, and the CPU twins
//! agree with the KD-tree and with the f64 reduction of the ICP on real scans; the CPU
//! engine's walk of the correspondence plan (`TwinTarget`) gives the twins' own results.

use crate::common;

use common::harness::plain;
use common::scans::{fast_gicp_pair, nn_params, v4, zeroed_results};
use common::wgsl::{self, rust_layout, RustLayout};
use glam::DVec3;
use wgslam::cpu::binding::Binding;
use wgslam::cpu::cross_covariance::{cross_covariance, decode, unshift};
use wgslam::cpu::nn_brute::nn_brute;
use wgslam::cpu::nn_grid::{nn_grid, HashGrid};
use wgslam::geometry::se3;
use wgslam::layout::scan::*;
use wgslam::scan::write::transform_points;
use wgslam::scan::{CrossCovariance, KdTreeTarget, NearestNeighbours, NnMethod, TwinTarget};

const SHADERS: [&str; 3] = ["nn_brute", "nn_grid", "cross_covariance"];

fn shader_text(name: &str) -> String {
    // As the runtime builds it: common.wgsl (which holds the scan structs) + the kernel.
    wgslam::gpu::shaders::source(name)
}

fn parse(name: &str) -> naga::Module {
    wgsl::parse(name, &shader_text(name))
}

/// The scan kernels parse and validate on their own (without common.wgsl) and need no
/// optional capability.
fn scan_shaders_validate() {
    let failures: Vec<String> = SHADERS
        .iter()
        .filter_map(|name| {
            wgsl::check(
                name,
                &shader_text(name),
                naga::valid::Capabilities::empty(),
                |line| (format!("shaders/{name}.wgsl"), line),
            )
        })
        .collect();
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

fn scan_structs_match_wgsl_layout() {
    let nn_params = || {
        rust_layout!(ScanNnParams {
            n_queries,
            n_targets,
            radius_sq,
            n_threads,
            cell_size,
            table_mask,
            target_begin,
            target_end
        })
    };
    let nn_result = || rust_layout!(ScanNnResult { index, dist_sq });
    let expected: Vec<(&str, RustLayout)> = vec![
        ("nn_brute", nn_params()),
        ("nn_grid", nn_params()),
        ("nn_brute", nn_result()),
        ("nn_grid", nn_result()),
        ("cross_covariance", nn_result()),
        (
            "cross_covariance",
            rust_layout!(ScanCovParams {
                anchor,
                n_pairs,
                n_threads,
                radius_sq,
                _pad0
            }),
        ),
        (
            "cross_covariance",
            rust_layout!(ScanCovPartial {
                count_sq,
                sum_p,
                sum_q,
                pq0,
                pq1,
                pq2
            }),
        ),
    ];
    let mut failures = Vec::new();
    for (shader, rust) in &expected {
        let module = parse(shader);
        failures.extend(wgsl::layout_mismatches(
            &format!("{shader}.wgsl"),
            &module,
            rust,
        ));
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// A real scan pair: 1500 queries (the source moved by relative.txt, every 46th point)
/// against the 69,088-point target.
fn real_pair() -> (Vec<[f32; 3]>, Vec<[f32; 3]>) {
    let (source, target, rel) = fast_gicp_pair();
    let queries: Vec<[f32; 3]> = transform_points(&rel, &source)
        .into_iter()
        .step_by(46)
        .collect();
    (queries, target)
}

const RADIUS: f32 = 0.5;

/// Each query's nearest target point within [`RADIUS`] by the twins, called directly over
/// the whole target: `(brute force, grid)`.
fn nn_by_twins(queries: &[[f32; 3]], target: &[[f32; 3]]) -> [Vec<ScanNnResult>; 2] {
    let n = queries.len();
    let grid = HashGrid::build(target, RADIUS);
    let params = nn_params(n, target, RADIUS, &grid);
    let (q4, t4) = (v4(queries), v4(target));
    let mut brute = zeroed_results(n);
    nn_brute(&mut [
        Binding::of(&params),
        Binding::read(&q4),
        Binding::read(&t4),
        Binding::write(&mut brute),
    ]);
    let mut gridded = brute.clone();
    let grid_params = ScanNnParams {
        n_targets: grid.points.len() as u32,
        ..params
    };
    nn_grid(&mut [
        Binding::of(&grid_params),
        Binding::read(&q4),
        Binding::read(&grid.points),
        Binding::read(&grid.bucket_start),
        Binding::write(&mut gridded),
    ]);
    [brute, gridded]
}

fn nn_twins_agree_with_each_other_and_the_kd_tree() {
    let (queries, target) = real_pair();
    let n = queries.len();
    let [brute, gridded] = nn_by_twins(&queries, &target);
    let tree = KdTreeTarget::new(&target).unwrap();
    let mut kd = vec![(0u32, 0f32); n];
    tree.nearest(&queries, &mut kd).unwrap();
    let mut inliers = 0;
    for i in 0..n {
        // Grid and brute force share the distance formula and tie rule: exact equality.
        assert_eq!(
            brute[i].index, gridded[i].index,
            "query {i}: brute {:?} grid {:?}",
            brute[i], gridded[i]
        );
        if brute[i].index != SCAN_NN_NONE {
            assert_eq!(brute[i].dist_sq, gridded[i].dist_sq, "query {i}");
            inliers += 1;
        }
        // kiddo computes the distance its own way: compare distances, not indices (ties).
        let within = kd[i].1 <= RADIUS * RADIUS;
        assert_eq!(
            within,
            brute[i].index != SCAN_NN_NONE,
            "query {i}: kd {:?} brute {:?}",
            kd[i],
            brute[i]
        );
        assert!(
            (kd[i].1 - brute[i].dist_sq).abs() <= 1e-6 * brute[i].dist_sq.max(1e-6),
            "query {i}: kd {:?} brute {:?}",
            kd[i],
            brute[i]
        );
    }
    assert!(inliers > n * 3 / 4, "{inliers} of {n} within {RADIUS} m");
}

/// f32 partial sums of ~1500 anchored products (metres up to ~50) against f64: the solved
/// transforms differ by a few micro-radians / micrometres.
const COV_ROT_TOL_RAD: f64 = 1e-4;
const COV_TRANS_TOL_M: f64 = 1e-4;

fn cross_covariance_twin_matches_f64_reduction() {
    let (queries, target) = real_pair();
    // Perturb the queries so the solve has something to find.
    let dt = se3::exp(&[0.01, -0.02, 0.015, 0.1, -0.05, 0.02]);
    let queries = transform_points(&dt, &queries);
    let n = queries.len();
    let (q4, t4) = (v4(&queries), v4(&target));
    let mut nn = zeroed_results(n);
    let p = ScanNnParams {
        n_queries: n as u32,
        n_targets: target.len() as u32,
        radius_sq: 4.0,
        n_threads: 64,
        cell_size: 0.0,
        table_mask: 0,
        target_begin: 0,
        target_end: target.len() as u32,
    };
    nn_brute(&mut [
        Binding::of(&p),
        Binding::read(&q4),
        Binding::read(&t4),
        Binding::write(&mut nn),
    ]);
    let centroid = queries.iter().fold(DVec3::ZERO, |a, q| {
        a + DVec3::new(q[0] as f64, q[1] as f64, q[2] as f64)
    }) / n as f64;
    let anchor = [centroid.x as f32, centroid.y as f32, centroid.z as f32, 0.0];
    let workgroups = 3;
    let params = ScanCovParams {
        anchor,
        n_pairs: n as u32,
        n_threads: workgroups * 64,
        radius_sq: 1.0,
        _pad0: 0,
    };
    let mut partials = vec![bytemuck::Zeroable::zeroed(); workgroups as usize];
    cross_covariance(&mut [
        Binding::of(&params),
        Binding::read(&q4),
        Binding::read(&t4),
        Binding::read(&nn),
        Binding::write(&mut partials),
    ]);
    let shifted = decode(&partials);

    let mut reference = CrossCovariance::default();
    for (q, r) in queries.iter().zip(&nn) {
        if r.index != SCAN_NN_NONE && r.dist_sq <= 1.0 {
            let t = target[r.index as usize];
            reference.add(
                DVec3::new(q[0] as f64, q[1] as f64, q[2] as f64),
                DVec3::new(t[0] as f64, t[1] as f64, t[2] as f64),
            );
        }
    }
    assert_eq!(shifted.count, reference.count);
    assert!(reference.count > 100);
    assert!(
        (shifted.rmse() - reference.rmse()).abs() < 1e-5,
        "{} {}",
        shifted.rmse(),
        reference.rmse()
    );
    let a = unshift(&shifted.solve().unwrap(), anchor);
    let b = reference.solve().unwrap();
    let e = se3::inverse_rigid(&b) * a;
    assert!(
        se3::rotation_angle(&e) < COV_ROT_TOL_RAD && se3::translation_norm(&e) < COV_TRANS_TOL_M,
        "{} rad {} m",
        se3::rotation_angle(&e),
        se3::translation_norm(&e)
    );
}

/// The correspondence plan run by the CPU engine over the twins' pool (`TwinTarget`: the
/// brute force in ranges of `SCAN_BRUTE_CHUNK` targets, the grid, the reduction) gives the
/// twins' results called directly over the whole target, bit for bit.
fn twin_target_runs_the_plan_as_the_twins_run() {
    let (queries, target) = real_pair();
    assert!(
        target.len() > SCAN_BRUTE_CHUNK as usize,
        "several ranges of targets"
    );
    let n = queries.len();
    let [brute, gridded] = nn_by_twins(&queries, &target);
    let (q4, t4) = (v4(&queries), v4(&target));
    let bytes = |r: &[ScanNnResult]| bytemuck::cast_slice::<_, u8>(r).to_vec();
    for (method, expected) in [(NnMethod::Brute, &brute), (NnMethod::Grid, &gridded)] {
        let twin = TwinTarget::new(&target, RADIUS, method, 3).unwrap();
        let got = twin.nearest_raw(&queries).unwrap();
        assert!(bytes(&got) == bytes(expected), "{method:?}");
    }
    let anchor = [1.5, -2.0, 0.3, 0.0];
    let cov = ScanCovParams {
        anchor,
        n_pairs: n as u32,
        n_threads: 3 * 64,
        radius_sq: 0.2,
        _pad0: 0,
    };
    let mut partials = vec![bytemuck::Zeroable::zeroed(); 3];
    cross_covariance(&mut [
        Binding::of(&cov),
        Binding::read(&q4),
        Binding::read(&t4),
        Binding::read(&gridded),
        Binding::write(&mut partials),
    ]);
    let twin = TwinTarget::new(&target, RADIUS, NnMethod::Grid, 3).unwrap();
    let got = twin.reduce_raw(&queries, anchor, 0.2).unwrap();
    let bytes = |p: &[ScanCovPartial]| bytemuck::cast_slice::<_, u8>(p).to_vec();
    assert!(bytes(&got) == bytes(&partials));
}

pub fn tests() -> Vec<common::harness::Test> {
    vec![
        plain("scan_shaders_validate", scan_shaders_validate),
        plain(
            "scan_structs_match_wgsl_layout",
            scan_structs_match_wgsl_layout,
        ),
        plain(
            "nn_twins_agree_with_each_other_and_the_kd_tree",
            nn_twins_agree_with_each_other_and_the_kd_tree,
        ),
        plain(
            "cross_covariance_twin_matches_f64_reduction",
            cross_covariance_twin_matches_f64_reduction,
        ),
        plain(
            "twin_target_runs_the_plan_as_the_twins_run",
            twin_target_runs_the_plan_as_the_twins_run,
        ),
    ]
}
