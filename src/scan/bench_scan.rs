//! The `bench-scan` benchmark: scan registration and nearest-neighbour queries timed on
//! the CPU (KD-tree) and the GPU (hashed grid, brute force) over one pair of clouds, with
//! GPU/CPU ratios. It measures and returns a report; the CLI (`cli/scan.rs`) parses the
//! options and prints the table. The timing loops themselves are in [`super::bench`].

use std::path::PathBuf;

use glam::DMat4;

use super::icp::{IcpParams, IcpResult, Samples};
use super::write::transform_points;
use crate::{geometry::se3, Result};

/// Source points per iteration of the sampled registration rows.
pub const BENCH_SAMPLES: usize = 1000;
/// Brute-force GPU nearest neighbours are timed only up to this many queries (it is
/// O(queries x targets): ~20 s at 10k queries against 69k points on lavapipe).
pub const BENCH_BRUTE_MAX_QUERIES: usize = 10_000;
/// A row stops repeating once its runs took this long in total (seconds), so `--repeats`
/// is a maximum and slow GPU rows run once.
pub const BENCH_ROW_BUDGET_S: f64 = 2.0;
/// Iteration cap of the GPU brute-force registration row: ~2.8 s per iteration on
/// lavapipe, so a full 21-iteration run alone would take a minute; its per-iteration time
/// is the comparable figure.
pub const BENCH_BRUTE_MAX_ITERS: usize = 5;

/// What to time (the CLI's `bench-scan` options without the file names).
#[derive(Debug, Clone)]
pub struct BenchScanOptions {
    /// Maximum timed runs per row (a row stops once its runs took [`BENCH_ROW_BUDGET_S`]).
    pub repeats: usize,
    /// Nearest-neighbour-only rows at these query counts.
    pub queries: Vec<usize>,
    /// Iteration cap of the all-points registration rows.
    pub all_points_max_iters: usize,
    /// Time the CPU only (no GPU context is opened).
    pub cpu_only: bool,
}

/// ICP parameters of the sampled rows and of the all-points rows.
pub fn bench_scan_params(options: &BenchScanOptions) -> (IcpParams, IcpParams) {
    let sampled = IcpParams {
        samples: Samples::Count(BENCH_SAMPLES),
        max_iterations: 100,
        radius: 1.0,
        final_radius: Some(0.2),
        ..Default::default()
    };
    let all = IcpParams {
        samples: Samples::All,
        max_iterations: options.all_points_max_iters,
        ..sampled
    };
    (sampled, all)
}

/// One registration row of [`BenchScanReport`].
#[derive(Debug, Clone, serde::Serialize)]
pub struct RegistrationBench {
    /// `cpu-kdtree`, `gpu-grid` or `gpu-brute`.
    pub backend: String,
    /// Source points per iteration (`None`: all points).
    pub samples: Option<usize>,
    pub max_iterations: usize,
    pub timing: crate::scan::bench::RegisterTiming,
    pub status: String,
    pub converged: bool,
    /// Row-major 4x4, maps source coordinates to target coordinates (metres).
    pub t_source_to_target: [[f64; 4]; 4],
    /// Median time over the CPU row's with the same samples (`None` for CPU rows and when
    /// the iteration caps differ).
    pub gpu_over_cpu: Option<f64>,
    /// Per-iteration time over the CPU row's with the same samples (`None` for CPU rows).
    pub gpu_over_cpu_per_iteration: Option<f64>,
}

/// One nearest-neighbour row of [`BenchScanReport`].
#[derive(Debug, Clone, serde::Serialize)]
pub struct NearestBench {
    /// `cpu-kdtree`, `gpu-grid` or `gpu-brute`.
    pub backend: String,
    pub timing: crate::scan::bench::NearestTiming,
    /// Median time over the CPU row's at the same query count (`None` for CPU rows).
    pub gpu_over_cpu: Option<f64>,
}

/// What `bench-scan` measured (also its `--json` output).
#[derive(Debug, Clone, serde::Serialize)]
pub struct BenchScanReport {
    pub source: PathBuf,
    pub target: PathBuf,
    pub source_points: usize,
    pub target_points: usize,
    /// ICP parameters of the sampled rows (the all-points rows differ in `samples` and
    /// `max_iterations` only).
    pub params: IcpParams,
    /// The GPU adapter's name, or `None` when the GPU was not used.
    pub gpu_adapter: Option<String>,
    /// Why the GPU rows are missing (`--cpu-only`, no adapter, ...), else `None`.
    pub gpu_skipped: Option<String>,
    pub registrations: Vec<RegistrationBench>,
    pub nearest: Vec<NearestBench>,
}

/// `n` queries from `points` (non-empty): evenly strided when `n` <= their count, else
/// cycling through all of them (so large counts repeat points).
fn spread_queries(points: &[[f32; 3]], n: usize) -> Vec<[f32; 3]> {
    let len = points.len();
    (0..n)
        .map(|i| {
            if n <= len {
                points[i * len / n]
            } else {
                points[i % len]
            }
        })
        .collect()
}

fn registration_row(
    backend: &str,
    params: &IcpParams,
    timing: crate::scan::bench::RegisterTiming,
    result: &IcpResult,
) -> RegistrationBench {
    RegistrationBench {
        backend: backend.into(),
        samples: match params.samples {
            Samples::All => None,
            Samples::Count(n) => Some(n),
        },
        max_iterations: params.max_iterations,
        timing,
        status: result.status.to_string(),
        converged: result.status.is_converged(),
        t_source_to_target: se3::to_rows(&result.t_source_to_target),
        gpu_over_cpu: None,
        gpu_over_cpu_per_iteration: None,
    }
}

/// Times registration (KD-tree or GPU target build included; GPU context and pipeline
/// creation and the first-dispatch shader compile excluded) and nearest-neighbour queries
/// of `source` onto `target` (metres). Without a GPU adapter the report has the CPU rows
/// and says why in `gpu_skipped`. Also returns the queries' source: the source moved by
/// the sampled CPU estimate.
pub fn bench_scan(
    source_path: PathBuf,
    target_path: PathBuf,
    source: &[[f32; 3]],
    target: &[[f32; 3]],
    options: &BenchScanOptions,
) -> Result<(BenchScanReport, Vec<[f32; 3]>)> {
    let (sampled, all) = bench_scan_params(options);
    let mut report = BenchScanReport {
        source: source_path,
        target: target_path,
        source_points: source.len(),
        target_points: target.len(),
        params: sampled,
        gpu_adapter: None,
        gpu_skipped: None,
        registrations: Vec::new(),
        nearest: Vec::new(),
    };

    // CPU rows.
    let budget = BENCH_ROW_BUDGET_S;
    let (t, cpu_sampled) =
        crate::scan::bench::bench_register_with(options.repeats, budget, || {
            crate::scan::register(source, target, DMat4::IDENTITY, &sampled)
        })?;
    report
        .registrations
        .push(registration_row("cpu-kdtree", &sampled, t, &cpu_sampled));
    let (t, r) = crate::scan::bench::bench_register(source, target, DMat4::IDENTITY, &all, 1)?;
    report
        .registrations
        .push(registration_row("cpu-kdtree", &all, t, &r));
    // Queries: the source moved into the target frame by the CPU estimate, i.e. the
    // queries of ICP's last iterations.
    let moved = transform_points(&cpu_sampled.t_source_to_target, source);
    let query_sets: Vec<Vec<[f32; 3]>> = options
        .queries
        .iter()
        .map(|&n| spread_queries(&moved, n))
        .collect();
    let tree = crate::scan::KdTreeTarget::new(target)?;
    for q in &query_sets {
        let timing = crate::scan::bench::bench_nearest(&tree, q, options.repeats, budget)?;
        report.nearest.push(NearestBench {
            backend: "cpu-kdtree".into(),
            timing,
            gpu_over_cpu: None,
        });
    }

    // GPU rows.
    if options.cpu_only {
        report.gpu_skipped = Some("--cpu-only".into());
    } else {
        match crate::gpu::GpuContext::new()
            .and_then(|ctx| crate::scan::gpu::ScanKernels::new(&ctx).map(|k| (ctx, k)))
        {
            Err(e) => report.gpu_skipped = Some(e.to_string()),
            Ok((ctx, kernels)) => {
                report.gpu_adapter = Some(ctx.adapter_info().name.clone());
                bench_gpu(
                    options,
                    &ctx,
                    &kernels,
                    (source, target),
                    (&sampled, &all),
                    &query_sets,
                    &mut report,
                )?;
            }
        }
    }
    Ok((report, moved))
}

/// The GPU rows of [`bench_scan`], appended to `report` with their GPU/CPU ratios.
fn bench_gpu(
    options: &BenchScanOptions,
    ctx: &crate::gpu::GpuContext,
    kernels: &crate::scan::gpu::ScanKernels,
    (source, target): (&[[f32; 3]], &[[f32; 3]]),
    (sampled, all): (&IcpParams, &IcpParams),
    query_sets: &[Vec<[f32; 3]>],
    report: &mut BenchScanReport,
) -> Result<()> {
    use crate::scan::bench::{bench_nearest, bench_register_with};
    use crate::scan::gpu::{GpuTarget, NnMethod};
    let radius = sampled.radius as f32;
    let grid = GpuTarget::new(ctx, kernels, target, radius, NnMethod::Grid)?;
    let brute = GpuTarget::new(ctx, kernels, target, radius, NnMethod::Brute)?;
    // Warm-up: Mesa compiles each pipeline on its first dispatch.
    let warm = &source[..source.len().min(64)];
    for t in [&grid, &brute] {
        t.nearest_raw(warm)?;
        crate::scan::NearestNeighbours::reduce_pairs(t, warm, sampled.radius * sampled.radius)?;
    }
    let brute_params = IcpParams {
        max_iterations: BENCH_BRUTE_MAX_ITERS,
        ..*sampled
    };
    let rows: [(&str, NnMethod, &IcpParams, usize); 3] = [
        ("gpu-grid", NnMethod::Grid, sampled, options.repeats),
        ("gpu-brute", NnMethod::Brute, &brute_params, 1),
        ("gpu-grid", NnMethod::Grid, all, 1),
    ];
    for (name, method, params, repeats) in rows {
        let (t, r) = bench_register_with(repeats, BENCH_ROW_BUDGET_S, || {
            let nn = GpuTarget::new(ctx, kernels, target, radius, method)?;
            crate::scan::register_with(source, &nn, DMat4::IDENTITY, params)
        })?;
        let mut row = registration_row(name, params, t, &r);
        if let Some(cpu) = report
            .registrations
            .iter()
            .find(|c| c.backend == "cpu-kdtree" && c.samples == row.samples)
        {
            // Whole runs compare only under the same iteration cap.
            if cpu.max_iterations == row.max_iterations {
                row.gpu_over_cpu = Some(row.timing.median_seconds / cpu.timing.median_seconds);
            }
            row.gpu_over_cpu_per_iteration =
                Some(row.timing.seconds_per_iteration() / cpu.timing.seconds_per_iteration());
        }
        report.registrations.push(row);
    }
    for q in query_sets {
        let mut backends = vec![("gpu-grid", &grid)];
        if q.len() <= BENCH_BRUTE_MAX_QUERIES {
            backends.push(("gpu-brute", &brute));
        }
        for (name, nn) in backends {
            let timing = bench_nearest(nn, q, options.repeats, BENCH_ROW_BUDGET_S)?;
            let cpu = report
                .nearest
                .iter()
                .find(|c| c.backend == "cpu-kdtree" && c.timing.queries == q.len())
                .map(|c| c.timing.median_seconds);
            report.nearest.push(NearestBench {
                backend: name.into(),
                gpu_over_cpu: cpu.map(|c| timing.median_seconds / c),
                timing,
            });
        }
    }
    Ok(())
}
