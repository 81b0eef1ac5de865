//! Command-line front ends of scan registration: `register` and `odometry` (clap argument
//! structs and run functions the main CLI dispatches to). Parsing and printing only; the
//! algorithms live in [`crate::scan`].

use std::path::{Path, PathBuf};

use glam::DMat4;

use crate::scan::odometry::{self, Odometry, ScanSequence};
use crate::scan::write::{format_matrix4, transform_points, write_atomic, write_ply_xyz};
use crate::scan::{read_cloud, read_matrix4, IcpParams, IcpResult, Samples};
use crate::{Error, Result};

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

fn rows(t: &DMat4) -> [[f64; 4]; 4] {
    let r = |i| t.row(i).to_array();
    [r(0), r(1), r(2), r(3)]
}

fn create_dir(dir: &Path) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))
}

/// Runs `register`: prints the transform, iterations, inlier RMSE and outlier ratio, and
/// with `--out` writes `result.json` and `aligned.ply`. A registration that does not
/// converge is printed with its status and returned, not turned into an error.
pub fn run_register(args: &RegisterArgs) -> Result<IcpResult> {
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
    if let Some(dir) = &args.out {
        create_dir(dir)?;
        let report = RegisterReport {
            source: &args.source,
            target: &args.target,
            source_stats: source.stats,
            target_stats: target.stats,
            params,
            t_source_to_target: rows(&result.t_source_to_target),
            status: result.status.to_string(),
            converged: result.status.is_converged(),
            iterations: result.iteration_count(),
            rmse_m: result.final_stats.rmse,
            outlier_ratio: result.final_stats.outlier_ratio,
            per_iteration: &result.iterations,
            seconds,
        };
        let json = serde_json::to_vec_pretty(&report)
            .map_err(|e| Error::Argument(format!("cannot encode result.json: {e}")))?;
        write_atomic(&dir.join("result.json"), &json)?;
        write_ply_xyz(
            &dir.join("aligned.ply"),
            &transform_points(&result.t_source_to_target, &source.points),
        )?;
        println!("wrote {}/result.json and aligned.ply", dir.display());
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
        println!(
            "relative pose error over {} pairs: rotation mean {:.3} max {:.3} deg, translation mean {:.3} max {:.3} m; end position error {:.3} m over {:.2} m of path",
            s.pairs,
            s.mean_rotation_deg,
            s.max_rotation_deg,
            s.mean_translation_m,
            s.max_translation_m,
            s.end_position_error_m,
            s.gt_path_length_m
        );
    }
    let failed = odo
        .pairs
        .iter()
        .filter(|p| !p.icp.status.is_converged())
        .count();
    println!(
        "{} scans, {} pairs ({} not converged) in {:.2} s",
        seq.scans.len(),
        odo.pairs.len(),
        failed,
        seconds
    );
    if let Some(dir) = &args.out {
        create_dir(dir)?;
        write_atomic(
            &dir.join("trajectory.tum"),
            odometry::format_tum(&seq, &odo.t_scan_to_world).as_bytes(),
        )?;
        write_atomic(&dir.join("pairs.tsv"), tsv.as_bytes())?;
        if let Some(s) = &summary {
            let json = serde_json::to_vec_pretty(s)
                .map_err(|e| Error::Argument(format!("cannot encode errors.json: {e}")))?;
            write_atomic(&dir.join("errors.json"), &json)?;
        }
        println!("wrote {}/trajectory.tum and pairs.tsv", dir.display());
    }
    Ok((seq, odo))
}
