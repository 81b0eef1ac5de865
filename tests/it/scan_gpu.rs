//! Scan kernels on the GPU against their CPU twins (`crates/core/src/cpu/nn_brute.rs`, `nn_grid.rs`,
//! `cross_covariance.rs`), and GPU-backed ICP against the CPU ICP and relative.txt. Every
//! trial shows as ignored without a GPU adapter (tests/it/common/harness.rs).

use crate::common;

use common::harness::gpu;
use common::scans::{fast_gicp_pair, nn_params, v4, zeroed_results};

use glam::DMat4;
use wgslam::cpu::binding::Binding;
use wgslam::cpu::cross_covariance::{cross_covariance, decode};
use wgslam::cpu::nn_brute::nn_brute;
use wgslam::cpu::nn_grid::{nn_grid, HashGrid};
use wgslam::geometry::se3;
use wgslam::gpu::GpuContext;
use wgslam::layout::scan::*;
use wgslam::scan::gpu::{GpuTarget, NnMethod, ScanKernels};
use wgslam::scan::write::transform_points;
use wgslam::scan::{register, register_with, IcpParams, Samples};

const RADIUS: f32 = 0.5;

/// Squared distances: the GPU may contract `x*x + y*y + z*z` into FMAs, a few ULP apart.
const DIST_SQ_REL_TOL: f32 = 1e-5;
/// Queries whose chosen neighbour may differ: only exact or near ties (two target points
/// at the same distance within the FMA difference) or a distance on the radius boundary.
const NN_MISMATCH_FRACTION: f64 = 1e-3;

fn compare_nn(label: &str, gpu: &[ScanNnResult], cpu: &[ScanNnResult]) {
    assert_eq!(gpu.len(), cpu.len());
    let mut mismatches = 0;
    for (i, (g, c)) in gpu.iter().zip(cpu).enumerate() {
        if g.index == c.index {
            if c.index != SCAN_NN_NONE {
                let rel = (g.dist_sq - c.dist_sq).abs() / c.dist_sq.max(1e-12);
                assert!(
                    rel <= DIST_SQ_REL_TOL,
                    "{label} query {i}: gpu {g:?} cpu {c:?}"
                );
            }
        } else {
            // A different index is fine only for a tie in distance.
            let rel = (g.dist_sq - c.dist_sq).abs() / c.dist_sq.max(1e-12);
            assert!(
                rel <= DIST_SQ_REL_TOL,
                "{label} query {i}: gpu {g:?} cpu {c:?}"
            );
            mismatches += 1;
        }
    }
    assert!(
        mismatches as f64 <= NN_MISMATCH_FRACTION * gpu.len() as f64,
        "{label}: {mismatches} of {} indices differ",
        gpu.len()
    );
}

fn gpu_nn_kernels_match_twins(ctx: GpuContext) {
    let kernels = ScanKernels::new(&ctx).unwrap();
    let (source, target, rel) = fast_gicp_pair();
    let queries: Vec<[f32; 3]> = transform_points(&rel, &source)
        .into_iter()
        .step_by(23)
        .collect();
    let n = queries.len();
    let grid = HashGrid::build(&target, RADIUS);
    let params = nn_params(n, &target, RADIUS, &grid);
    let mut cpu_brute = zeroed_results(n);
    nn_brute(&mut [
        Binding::of(&params),
        Binding::read(&v4(&queries)),
        Binding::read(&v4(&target)),
        Binding::write(&mut cpu_brute),
    ]);
    let mut cpu_grid = cpu_brute.clone();
    nn_grid(&mut [
        Binding::of(&params),
        Binding::read(&v4(&queries)),
        Binding::read(&grid.points),
        Binding::read(&grid.bucket_start),
        Binding::write(&mut cpu_grid),
    ]);

    let brute = GpuTarget::new(&ctx, &kernels, &target, RADIUS, NnMethod::Brute).unwrap();
    compare_nn(
        "nn_brute",
        &brute.nearest_raw(&queries).unwrap(),
        &cpu_brute,
    );
    let gridded = GpuTarget::new(&ctx, &kernels, &target, RADIUS, NnMethod::Grid).unwrap();
    let g = gridded.nearest_raw(&queries).unwrap();
    // Beyond the radius the grid reports what it saw in 27 cells, not the global nearest:
    // compare within-radius answers only.
    for (i, (a, b)) in g.iter().zip(&cpu_grid).enumerate() {
        assert_eq!(
            a.index == SCAN_NN_NONE,
            b.index == SCAN_NN_NONE,
            "query {i}: {a:?} {b:?}"
        );
    }
    let keep = |r: &[ScanNnResult]| -> Vec<ScanNnResult> {
        r.iter()
            .map(|x| {
                if x.index == SCAN_NN_NONE {
                    ScanNnResult {
                        index: SCAN_NN_NONE,
                        dist_sq: 0.0,
                    }
                } else {
                    *x
                }
            })
            .collect()
    };
    compare_nn("nn_grid", &keep(&g), &keep(&cpu_grid));
}

/// Decoded f32 partial sums (different workgroup count and FMA on the GPU) against the
/// twin's: relative difference of each sum.
const COV_SUM_REL_TOL: f64 = 1e-4;

fn gpu_cross_covariance_matches_twin(ctx: GpuContext) {
    let kernels = ScanKernels::new(&ctx).unwrap();
    let (source, target, rel) = fast_gicp_pair();
    let dt = se3::exp(&[0.01, -0.02, 0.015, 0.1, -0.05, 0.02]);
    let queries: Vec<[f32; 3]> = transform_points(&(dt * rel), &source)
        .into_iter()
        .step_by(11)
        .collect();
    let gpu = GpuTarget::new(&ctx, &kernels, &target, 1.0, NnMethod::Grid).unwrap();
    let nn = gpu.nearest_raw(&queries).unwrap();
    let anchor = [1.5, -2.0, 0.3, 0.0];
    let partials = gpu.reduce_raw(&queries, anchor, 1.0).unwrap();
    let mut twin = vec![bytemuck::Zeroable::zeroed(); partials.len()];
    let params = ScanCovParams {
        anchor,
        n_pairs: queries.len() as u32,
        n_threads: partials.len() as u32 * 64,
        radius_sq: 1.0,
        _pad0: 0,
    };
    cross_covariance(&mut [
        Binding::of(&params),
        Binding::read(&v4(&queries)),
        Binding::read(&v4(&target)),
        Binding::read(&nn),
        Binding::write(&mut twin),
    ]);
    let (g, c) = (decode(&partials), decode(&twin));
    assert_eq!(g.count, c.count);
    assert!(c.count > 1000, "{}", c.count);
    let close = |x: f64, y: f64, what: &str| {
        assert!(
            (x - y).abs() <= COV_SUM_REL_TOL * y.abs().max(1.0),
            "{what}: gpu {x} twin {y}"
        );
    };
    close(g.sum_sq_dist, c.sum_sq_dist, "sum |p-q|^2");
    close(g.sum_p_sq, c.sum_p_sq, "sum |p|^2");
    for k in 0..3 {
        close(g.sum_p[k], c.sum_p[k], "sum p");
        close(g.sum_q[k], c.sum_q[k], "sum q");
        for j in 0..3 {
            close(g.sum_pq[k][j], c.sum_pq[k][j], "sum p q^T");
        }
    }
}

/// GPU-backed ICP follows the same samples as the CPU; f32 reductions can flip an inlier
/// or two, and the sampled estimate jitters by a few mm around the optimum.
const GPU_ICP_ROT_TOL_DEG: f64 = 0.1;
const GPU_ICP_TRANS_TOL_M: f64 = 0.02;

fn gpu_icp_matches_cpu_icp_on_fast_gicp_pair(ctx: GpuContext) {
    let kernels = ScanKernels::new(&ctx).unwrap();
    let (source, target, reference) = fast_gicp_pair();
    let params = IcpParams {
        radius: 1.0,
        final_radius: Some(0.2),
        max_iterations: 100,
        samples: Samples::Count(1000),
        ..Default::default()
    };
    let cpu = register(&source, &target, DMat4::IDENTITY, &params).unwrap();
    // Grid only: brute force gives the same neighbours (see gpu_nn_kernels_match_twins)
    // but costs ~50 s per registration on lavapipe.
    {
        let method = NnMethod::Grid;
        let gt = GpuTarget::new(&ctx, &kernels, &target, params.radius as f32, method).unwrap();
        let start = std::time::Instant::now();
        let gpu = register_with(&source, &gt, DMat4::IDENTITY, &params).unwrap();
        let secs = start.elapsed().as_secs_f64();
        let e = se3::inverse_rigid(&cpu.t_source_to_target) * gpu.t_source_to_target;
        let r = se3::inverse_rigid(&reference) * gpu.t_source_to_target;
        eprintln!(
            "GPU ICP ({method:?}): {} in {} its ({} on CPU), {secs:.3} s; vs CPU {:.4} deg {:.4} m; vs relative.txt {:.3} deg {:.4} m",
            gpu.status,
            gpu.iteration_count(),
            cpu.iteration_count(),
            se3::rotation_angle(&e).to_degrees(),
            se3::translation_norm(&e),
            se3::rotation_angle(&r).to_degrees(),
            se3::translation_norm(&r)
        );
        assert!(gpu.status.is_converged(), "{}", gpu.status);
        assert!(
            se3::rotation_angle(&e).to_degrees() < GPU_ICP_ROT_TOL_DEG
                && se3::translation_norm(&e) < GPU_ICP_TRANS_TOL_M
        );
    }
}

pub fn tests() -> Vec<common::harness::Test> {
    vec![
        gpu("gpu_nn_kernels_match_twins", gpu_nn_kernels_match_twins),
        gpu(
            "gpu_cross_covariance_matches_twin",
            gpu_cross_covariance_matches_twin,
        ),
        gpu(
            "gpu_icp_matches_cpu_icp_on_fast_gicp_pair",
            gpu_icp_matches_cpu_icp_on_fast_gicp_pair,
        ),
    ]
}
