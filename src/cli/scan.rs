//! Command-line front ends of scan registration: `register`, `odometry` and `bench-scan`
//! (clap argument structs and run functions the main CLI dispatches to). Parsing and
//! printing only; the algorithms live in [`crate::scan`], the bench-scan benchmark in
//! `crate::scan::bench_scan`.

use std::path::{Path, PathBuf};

use glam::DMat4;

use crate::io::outputs::OutputSet;
use crate::scan::bench_scan::{
    bench_scan, bench_scan_params, BenchScanOptions, BenchScanReport, BENCH_BRUTE_MAX_ITERS,
    BENCH_BRUTE_MAX_QUERIES, BENCH_ROW_BUDGET_S, BENCH_SAMPLES,
};
use crate::scan::odometry::{self, Odometry, ScanSequence};
use crate::scan::write::{format_matrix4, transform_points, write_atomic, write_ply_xyz};
use crate::scan::{read_cloud, read_matrix4, IcpParams, IcpResult, Samples};
use crate::{geometry::se3, Error, Result};

/// ICP options shared by `register` and `odometry`.
#[derive(clap::Args, Debug, Clone)]
pub struct IcpArgs {
    /// Source points per iteration: a count or `all`.
    #[arg(long, default_value = "1000")]
    pub samples: Samples,
    /// Maximum ICP iterations.
    #[arg(long, default_value_t = 50)]
    pub max_iters: usize,
    /// Rejection radius in metres: farther nearest neighbours are outliers.
    #[arg(long, default_value_t = 1.0)]
    pub radius: f64,
    /// Coarse-to-fine: halve the radius at each convergence down to this many metres.
    #[arg(long)]
    pub final_radius: Option<f64>,
    /// Convergence threshold on the update: radians of rotation and metres of translation
    /// (raised by the sampling noise floor when sampling a subset).
    #[arg(long, default_value_t = 1e-5)]
    pub threshold: f64,
    /// Seed of the random sampling.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Fewer inliers than this stops ICP with status "too few inliers".
    #[arg(long, default_value_t = 10)]
    pub min_inliers: usize,
    /// Drop points with z below this (sensor frame, metres) from both clouds.
    #[arg(long)]
    pub min_z: Option<f32>,
    /// Drop points with z above this (sensor frame, metres), e.g. the ground of a NED
    /// LiDAR scan (z down), whose rings pull point-to-point ICP towards zero motion.
    #[arg(long)]
    pub max_z: Option<f32>,
}

impl IcpArgs {
    /// The z crop `(min, max)` in metres, or `None` when neither bound is given.
    pub fn z_range(&self) -> Option<(f32, f32)> {
        match (self.min_z, self.max_z) {
            (None, None) => None,
            (lo, hi) => Some((lo.unwrap_or(f32::NEG_INFINITY), hi.unwrap_or(f32::INFINITY))),
        }
    }

    /// The [`IcpParams`] these options describe.
    pub fn params(&self) -> IcpParams {
        IcpParams {
            max_iterations: self.max_iters,
            samples: self.samples,
            radius: self.radius,
            final_radius: self.final_radius,
            threshold: self.threshold,
            seed: self.seed,
            min_inliers: self.min_inliers,
        }
    }
}

/// Where `register` finds nearest neighbours (and, on the GPU, reduces the pairs).
#[derive(clap::ValueEnum, Debug, Clone, Copy, PartialEq, Eq)]
pub enum NnBackend {
    /// CPU KD-tree (kiddo), pairs reduced in f64 on the CPU.
    Kdtree,
    /// GPU hashed voxel grid + GPU cross-covariance reduction.
    GpuGrid,
    /// GPU brute force + GPU cross-covariance reduction.
    GpuBrute,
}

/// `register SOURCE TARGET`: align SOURCE onto TARGET with point-to-point ICP. The printed
/// transform maps SOURCE coordinates into TARGET coordinates (t_source_to_target).
#[derive(clap::Args, Debug, Clone)]
pub struct RegisterArgs {
    /// Source cloud (.pcd, .ply, .bin KITTI, or x y z text).
    pub source: PathBuf,
    /// Target cloud (same formats).
    pub target: PathBuf,
    /// Initial t_source_to_target: a text file with a 4x4 matrix (row-major).
    #[arg(long)]
    pub init: Option<PathBuf>,
    #[command(flatten)]
    pub icp: IcpArgs,
    /// Nearest-neighbour backend: `kdtree` (CPU, kiddo), `gpu-grid` (hashed voxel grid
    /// on the GPU) or `gpu-brute` (brute force on the GPU; slow, for checking).
    #[arg(long, value_enum, default_value_t = NnBackend::Kdtree)]
    pub nn: NnBackend,
    /// Output directory for result.json and aligned.ply (the whole source, uncropped, moved
    /// into the target frame).
    #[arg(long)]
    pub out: Option<PathBuf>,
}

/// What `register --out` writes, as a set.
const REGISTER_OUTPUTS: [&str; 2] = ["result.json", "aligned.ply"];
/// What `odometry --out` writes, as a set.
const ODOMETRY_OUTPUTS: [&str; 3] = ["trajectory.tum", "pairs.tsv", "errors.json"];

/// JSON written as `result.json` by `register`.
#[derive(serde::Serialize)]
struct RegisterReport<'a> {
    source: &'a Path,
    target: &'a Path,
    source_stats: crate::scan::CloudStats,
    target_stats: crate::scan::CloudStats,
    params: IcpParams,
    /// Row-major 4x4, maps source coordinates to target coordinates (metres).
    t_source_to_target: [[f64; 4]; 4],
    status: String,
    converged: bool,
    iterations: usize,
    rmse_m: f64,
    outlier_ratio: f64,
    per_iteration: &'a [crate::scan::IterationStats],
    seconds: f64,
}

/// Runs `register`: prints the transform, iterations, inlier RMSE and outlier ratio, and
/// with `--out` writes `result.json` and `aligned.ply`. A registration that does not
/// converge is printed with its status and returned, not turned into an error.
pub fn run_register(args: &RegisterArgs) -> Result<IcpResult> {
    // Staged beside --out and moved in as a set; a bad --out fails before the work.
    let outputs = args
        .out
        .as_deref()
        .map(|d| OutputSet::begin(d, &REGISTER_OUTPUTS))
        .transpose()?;
    let source = read_cloud(&args.source)?;
    let target = read_cloud(&args.target)?;
    let init = match &args.init {
        Some(p) => read_matrix4(p)?,
        None => DMat4::IDENTITY,
    };
    let params = args.icp.params();
    let (src_pts, tgt_pts) = match args.icp.z_range() {
        Some((lo, hi)) => (
            crate::scan::crop_z(&source.points, lo, hi),
            crate::scan::crop_z(&target.points, lo, hi),
        ),
        None => (source.points.clone(), target.points.clone()),
    };
    let start = std::time::Instant::now();
    let result = match args.nn {
        NnBackend::Kdtree => crate::scan::register(&src_pts, &tgt_pts, init, &params)?,
        NnBackend::GpuGrid | NnBackend::GpuBrute => {
            use crate::scan::gpu::{GpuTarget, NnMethod, ScanKernels};
            let ctx = crate::gpu::GpuContext::new()?;
            let kernels = ScanKernels::new(&ctx)?;
            let method = if args.nn == NnBackend::GpuGrid {
                NnMethod::Grid
            } else {
                NnMethod::Brute
            };
            let target = GpuTarget::new(&ctx, &kernels, &tgt_pts, params.radius as f32, method)?;
            crate::scan::register_with(&src_pts, &target, init, &params)?
        }
    };
    let seconds = start.elapsed().as_secs_f64();
    for (name, c) in [("source", &source), ("target", &target)] {
        if c.stats.dropped_non_finite > 0 {
            println!(
                "{name}: dropped {} of {} points with NaN/inf coordinates",
                c.stats.dropped_non_finite, c.stats.records
            );
        }
    }
    println!("t_source_to_target (maps source coordinates into target coordinates):");
    print!("{}", format_matrix4(&result.t_source_to_target));
    println!("status:        {}", result.status);
    println!("iterations:    {}", result.iteration_count());
    println!("inlier rmse:   {:.6} m", result.final_stats.rmse);
    println!(
        "outlier ratio: {:.4} ({} of {} sampled within {} m)",
        result.final_stats.outlier_ratio,
        result.final_stats.inliers,
        result.final_stats.sampled,
        result.final_stats.radius
    );
    println!("time:          {seconds:.3} s");
    if let Some(outputs) = outputs {
        let dir = outputs.dir();
        let report = RegisterReport {
            source: &args.source,
            target: &args.target,
            source_stats: source.stats,
            target_stats: target.stats,
            params,
            t_source_to_target: se3::to_rows(&result.t_source_to_target),
            status: result.status.to_string(),
            converged: result.status.is_converged(),
            iterations: result.iteration_count(),
            rmse_m: result.final_stats.rmse,
            outlier_ratio: result.final_stats.outlier_ratio,
            per_iteration: &result.iterations,
            seconds,
        };
        let json =
            serde_json::to_vec_pretty(&report).map_err(|e| Error::encode("result.json", e))?;
        write_atomic(&dir.join("result.json"), &json)?;
        write_ply_xyz(
            &dir.join("aligned.ply"),
            &transform_points(&result.t_source_to_target, &source.points),
        )?;
        let target = outputs.target().to_path_buf();
        outputs.commit()?;
        println!("wrote {}/result.json and aligned.ply", target.display());
    }
    Ok(result)
}

/// `odometry SCANS_DIR`: register consecutive scans (scan i+1 onto scan i) and chain them.
/// SCANS_DIR is an AirSim folder (`lidar/<vehicle>/*.bin`, `poses/<vehicle>/*.txt`) or a
/// folder of cloud files sorted by name.
#[derive(clap::Args, Debug, Clone)]
pub struct OdometryArgs {
    /// Folder of scans (AirSim layout or plain cloud files).
    pub scans_dir: PathBuf,
    /// Ground truth: a TUM file (stamps = numeric file stems) or a folder of AirSim pose
    /// files. AirSim folders use their own `poses/` when this is not given.
    #[arg(long)]
    pub gt: Option<PathBuf>,
    #[command(flatten)]
    pub icp: IcpArgs,
    /// Output directory for trajectory.tum and pairs.tsv (and errors.json with ground truth).
    #[arg(long)]
    pub out: Option<PathBuf>,
}

/// Runs `odometry`: prints one line per pair and, with ground truth, the error summary;
/// with `--out` writes `trajectory.tum`, `pairs.tsv` and (with ground truth) `errors.json`.
pub fn run_odometry(args: &OdometryArgs) -> Result<(ScanSequence, Odometry)> {
    let outputs = args
        .out
        .as_deref()
        .map(|d| OutputSet::begin(d, &ODOMETRY_OUTPUTS))
        .transpose()?;
    let mut seq = odometry::discover(&args.scans_dir)?;
    if let Some(gt) = &args.gt {
        seq.gt_scan_to_world = Some(odometry::read_ground_truth(gt, &seq)?);
    }
    let params = args.icp.params();
    let start = std::time::Instant::now();
    let odo = odometry::run_odometry(&seq, &params, args.icp.z_range())?;
    let seconds = start.elapsed().as_secs_f64();
    let tsv = odometry::format_pairs_tsv(&seq, &odo);
    print!("{tsv}");
    let summary = odometry::summarize(&seq, &odo);
    if let Some(s) = &summary {
        println!("{s}");
    }
    let failed = odo.not_converged();
    println!(
        "{} scans, {} pairs ({} not converged) in {:.2} s",
        seq.scans.len(),
        odo.pairs.len(),
        failed,
        seconds
    );
    if let Some(outputs) = outputs {
        let dir = outputs.dir();
        let poses: Vec<(f64, DMat4)> = (odo.t_scan_to_world.iter().enumerate())
            .map(|(i, t)| (seq.stamp(i), *t))
            .collect();
        crate::io::trajectory::write_tum_of(&dir.join("trajectory.tum"), "scan to world", &poses)?;
        write_atomic(&dir.join("pairs.tsv"), tsv.as_bytes())?;
        if let Some(s) = &summary {
            let json = serde_json::to_vec_pretty(s).map_err(|e| Error::encode("errors.json", e))?;
            write_atomic(&dir.join("errors.json"), &json)?;
        }
        let target = outputs.target().to_path_buf();
        outputs.commit()?;
        println!("wrote {}/trajectory.tum and pairs.tsv", target.display());
    }
    Ok((seq, odo))
}

/// Folder of the bundled LiDAR pair used by `bench-scan` by default.
const BUNDLED_SCAN_PAIR: &str = "assets/lidar/fast_gicp_pair/data";

/// The bundled pair `(source, target)`: scan 251371071 registered onto 251370668. Found
/// through the crate directory, else relative to the working directory.
pub fn bundled_scan_pair() -> (PathBuf, PathBuf) {
    let from_crate = Path::new(env!("CARGO_MANIFEST_DIR")).join(BUNDLED_SCAN_PAIR);
    let dir = if from_crate.is_dir() {
        from_crate
    } else {
        PathBuf::from(BUNDLED_SCAN_PAIR)
    };
    (dir.join("251371071.pcd"), dir.join("251370668.pcd"))
}

/// `bench-scan [SOURCE TARGET]`: time scan registration and nearest-neighbour queries on
/// the CPU (KD-tree) and the GPU (hashed grid, brute force) in one run.
#[derive(clap::Args, Debug, Clone)]
pub struct BenchScanArgs {
    /// Source cloud (default: the bundled fast_gicp pair's 251371071.pcd).
    #[arg(requires = "target")]
    pub source: Option<PathBuf>,
    /// Target cloud (default: the bundled 251370668.pcd).
    pub target: Option<PathBuf>,
    /// Maximum timed runs per row (median and minimum are printed); a row stops repeating
    /// once its runs took 2 s in total; all-points and gpu-brute registrations run once.
    #[arg(long, default_value_t = 5)]
    pub repeats: usize,
    /// Nearest-neighbour-only timings at these query counts (comma-separated).
    #[arg(long, value_delimiter = ',', default_value = "1000,10000,100000")]
    pub queries: Vec<usize>,
    /// Iteration cap of the all-points rows (the GPU grid takes ~20 s per iteration with
    /// all 70k points on lavapipe; compare seconds per iteration there).
    #[arg(long, default_value_t = 2)]
    pub all_points_max_iters: usize,
    /// Time the CPU only (no GPU context is opened).
    #[arg(long)]
    pub cpu_only: bool,
    /// Also write the report as JSON to this file.
    #[arg(long)]
    pub json: Option<PathBuf>,
}

/// Runs `bench-scan`: times registration (KD-tree or GPU target build included; GPU
/// context and pipeline creation and the first-dispatch shader compile excluded) and
/// nearest-neighbour queries, prints a table and returns the report (written with
/// `--json`). Without a GPU adapter the CPU rows are printed and the reason is reported.
pub fn run_bench_scan(args: &BenchScanArgs) -> Result<BenchScanReport> {
    let (source_path, target_path) = match (&args.source, &args.target) {
        (Some(s), Some(t)) => (s.clone(), t.clone()),
        (None, None) => bundled_scan_pair(),
        _ => {
            return Err(Error::Argument(
                "bench-scan takes both SOURCE and TARGET or neither".into(),
            ))
        }
    };
    if args.repeats == 0 {
        return Err(Error::Argument("--repeats must be at least 1".into()));
    }
    if args.all_points_max_iters == 0 {
        return Err(Error::Argument(
            "--all-points-max-iters must be at least 1".into(),
        ));
    }
    if args.queries.contains(&0) {
        return Err(Error::Argument("--queries counts must be positive".into()));
    }
    let source = read_cloud(&source_path)?.points;
    let target = read_cloud(&target_path)?.points;
    if source.is_empty() || target.is_empty() {
        return Err(Error::Argument("bench-scan needs non-empty clouds".into()));
    }
    let options = BenchScanOptions {
        repeats: args.repeats,
        queries: args.queries.clone(),
        all_points_max_iters: args.all_points_max_iters,
        cpu_only: args.cpu_only,
    };
    let (sampled, all) = bench_scan_params(&options);
    println!(
        "bench-scan: source {} ({} points) -> target {} ({} points)",
        source_path.display(),
        source.len(),
        target_path.display(),
        target.len()
    );
    println!(
        "ICP: radius {} m -> final {} m, threshold {:e}, seed {}, max {} iterations with {} samples; all-points rows capped at {} iterations (--all-points-max-iters) and run once, to keep the run to ~2 minutes on lavapipe",
        sampled.radius,
        sampled.final_radius.unwrap_or(sampled.radius),
        sampled.threshold,
        sampled.seed,
        sampled.max_iterations,
        BENCH_SAMPLES,
        all.max_iterations
    );
    println!(
        "other rows: up to {} runs each (--repeats), fewer once a row's runs took {BENCH_ROW_BUDGET_S} s",
        args.repeats
    );
    let (report, moved) = bench_scan(source_path, target_path, &source, &target, &options)?;
    print_bench_scan(&report, &moved);
    if let Some(path) = &args.json {
        let json =
            serde_json::to_vec_pretty(&report).map_err(|e| Error::encode("the bench report", e))?;
        write_atomic(path, &json)?;
        println!("wrote {}", path.display());
    }
    Ok(report)
}

fn print_bench_scan(report: &BenchScanReport, moved: &[[f32; 3]]) {
    match (&report.gpu_adapter, &report.gpu_skipped) {
        (Some(name), _) => println!("GPU: {name}"),
        (None, Some(why)) => println!("GPU skipped (CPU rows only): {why}"),
        (None, None) => {}
    }
    println!();
    println!("registration (time includes the KD-tree / GPU target build; GPU context, pipelines and shader compile excluded)");
    println!(
        "{:<8} {:<10} {:>4} {:>5} {:>10} {:>10} {:>10} {:>9} {:>10}  status",
        "samples", "backend", "runs", "iters", "median s", "min s", "s/iter", "GPU/CPU", "per iter"
    );
    for r in &report.registrations {
        let ratio = |x: Option<f64>| x.map_or("-".to_string(), |v| format!("{v:.2}x"));
        println!(
            "{:<8} {:<10} {:>4} {:>5} {:>10.4} {:>10.4} {:>10.5} {:>9} {:>10}  {}",
            r.samples.map_or("all".to_string(), |n| n.to_string()),
            r.backend,
            r.timing.seconds.len(),
            r.timing.iterations,
            r.timing.median_seconds,
            r.timing.min_seconds,
            r.timing.seconds_per_iteration(),
            ratio(r.gpu_over_cpu),
            ratio(r.gpu_over_cpu_per_iteration),
            r.status
        );
    }
    if report.gpu_adapter.is_some() {
        println!("gpu-brute: {BENCH_SAMPLES} samples only, capped at {BENCH_BRUTE_MAX_ITERS} iterations and run once (all points would take minutes per iteration on lavapipe); compare its s/iter");
    }
    println!();
    println!(
        "nearest neighbour only, against the full target ({} points); queries: the source ({} points) moved by the {BENCH_SAMPLES}-sample CPU estimate, spread evenly and cycled past its size; GPU queries are radius-limited ({} m), brute only up to {BENCH_BRUTE_MAX_QUERIES} queries",
        report.target_points,
        moved.len(),
        report.params.radius
    );
    println!(
        "{:>8} {:<10} {:>4} {:>10} {:>10} {:>12} {:>9}",
        "queries", "backend", "runs", "median s", "min s", "us/query", "GPU/CPU"
    );
    for n in &report.nearest {
        println!(
            "{:>8} {:<10} {:>4} {:>10.4} {:>10.4} {:>12.3} {:>9}",
            n.timing.queries,
            n.backend,
            n.timing.seconds.len(),
            n.timing.median_seconds,
            n.timing.min_seconds,
            n.timing.median_seconds * 1e6 / n.timing.queries as f64,
            n.gpu_over_cpu
                .map_or("-".to_string(), |v| format!("{v:.2}x"))
        );
    }
}
