//! Command-line interface: argument parsing and printing only; no algorithm code here.

pub mod batch;
pub mod render;
pub mod scan;

use std::path::{Path, PathBuf};

use clap::{Args, Parser, Subcommand, ValueEnum};

use crate::dataset::{self, SequenceOptions};
use crate::geometry::camera::Intrinsics;
use crate::slam::any_backend::{self, BackendChoice};
use crate::slam::params::{
    Association, BilateralSettings, PoseSource, Profile, PyramidSettings, SlamParams,
    UnstableRemoval, MAX_ICP_LEVELS,
};
use crate::{eval, io, tools::bench, tools::compare, tools::run, tools::two_frame, Error, Result};

/// The bundled sequence used when no dataset is given (relative to the crate root).
pub const BUNDLED_DATASET: &str = "assets/icl_living_room_kt2";

/// Dense RGB-D SLAM (point-based fusion) and point-to-point ICP on wgpu, with a CPU reference.
#[derive(Debug, Parser)]
#[command(name = "wgslam", version, about)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Debug, Subcommand)]
pub enum Command {
    /// Run dense SLAM over a sequence; write trajectory.tum, map.ply, metrics.json.
    Run(RunArgs),
    /// Two-frame ICP: align frame --target to frame --source, print every iteration.
    Icp(IcpArgs),
    /// ATE and RPE of an estimated TUM trajectory against a ground-truth TUM trajectory.
    Eval(EvalArgs),
    /// Run the CPU reference and the GPU on the same frames and report their differences
    /// per stage and frame; exits non-zero beyond the documented tolerances.
    Compare(CompareArgs),
    /// Time both backends on the same frames: per stage, per frame, memory, readbacks.
    Bench(BenchArgs),
    /// (internal) Benchmark one backend and print its result as JSON; used by `bench`.
    #[command(hide = true)]
    BenchOne(BenchArgs),
    /// Point-to-point ICP between two point clouds (PCD, PLY, xyz text, KITTI .bin).
    Register(crate::cli::scan::RegisterArgs),
    /// Scan odometry: register each consecutive pair of a folder of scans and chain them.
    Odometry(crate::cli::scan::OdometryArgs),
    /// Time scan registration and nearest neighbours: CPU KD-tree vs GPU grid / brute force.
    BenchScan(crate::cli::scan::BenchScanArgs),
    /// Render a map PLY headlessly to a PNG (colour, normals, weight or depth view).
    Render(crate::cli::render::RenderArgs),
    /// Run a TOML manifest of jobs (sequences x settings x backends), resumable and
    /// shardable (`--shard I/N`, Slurm / Kubernetes array indices); `batch collect DIR`
    /// writes summary.csv, summary.json and report.html; `batch diff A B` compares two.
    Batch(crate::cli::batch::BatchArgs),
}

/// Pose source for `run`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum PosesChoice {
    /// Frame-to-model ICP tracking.
    Track,
    /// Ground-truth poses, no tracking (fusion only).
    Gt,
}

/// Options shared by every command that reads an RGB-D sequence.
#[derive(Debug, Args)]
pub struct DatasetArgs {
    /// Sequence directory (TUM RGB-D or ICL-NUIM layout); default: the bundled frames.
    pub dataset: Option<PathBuf>,
    /// Ground-truth file (TUM format) instead of the layout's default.
    #[arg(long)]
    pub gt: Option<PathBuf>,
    /// Intrinsics preset: icl, fr1, fr2, fr3 (overrides camera.json).
    #[arg(long)]
    pub camera: Option<String>,
    /// Intrinsics override "fx,fy,cx,cy" in pixels (image size from the frames' preset/json).
    #[arg(long)]
    pub intrinsics: Option<String>,
    /// Raw depth units per metre (default: camera.json or 5000).
    #[arg(long)]
    pub depth_scale: Option<f32>,
    /// Largest timestamp difference for association, seconds.
    #[arg(long, default_value_t = dataset::DEFAULT_MAX_TIME_DIFF)]
    pub max_time_diff: f64,
}

/// The bilateral depth filter: off unless `--bilateral` (shared by `run`, `icp`, `compare`
/// and `bench`); the other three flags take effect only with it.
#[derive(Debug, Args)]
pub struct BilateralArgs {
    /// Smooth the depth with an edge-preserving bilateral filter before the normals, ICP
    /// and fusion (KinectFusion's; for noisy sensors). Off by default.
    #[arg(long)]
    pub bilateral: bool,
    /// Bilateral filter window half-width, pixels of the (downsampled) maps.
    #[arg(long, default_value_t = BilateralSettings::default().radius_px)]
    pub bilateral_radius: u32,
    /// Bilateral filter spatial sigma, pixels of the (downsampled) maps.
    #[arg(long, default_value_t = BilateralSettings::default().sigma_space_px)]
    pub bilateral_sigma_space: f32,
    /// Bilateral filter depth sigma, metres (at depth 0, see --bilateral-sigma-depth-z2).
    #[arg(long, default_value_t = BilateralSettings::default().sigma_depth_m)]
    pub bilateral_sigma_depth: f32,
    /// Bilateral filter depth sigma's growth with depth squared, 1/m: sigma_depth + this x z².
    #[arg(long, default_value_t = BilateralSettings::default().sigma_depth_per_m2)]
    pub bilateral_sigma_depth_z2: f32,
}

/// Largest `--bilateral-radius`: a 33x33 window is already far past any useful one.
const MAX_BILATERAL_RADIUS: u32 = 16;

impl BilateralArgs {
    /// The filter's settings, or `None` without `--bilateral`.
    pub fn settings(&self) -> Result<Option<BilateralSettings>> {
        if !self.bilateral {
            return Ok(None);
        }
        if self.bilateral_radius > MAX_BILATERAL_RADIUS {
            return Err(Error::Argument(format!(
                "--bilateral-radius {} must be at most {MAX_BILATERAL_RADIUS}",
                self.bilateral_radius
            )));
        }
        let space = self.bilateral_sigma_space;
        if !(space > 0.0 && space.is_finite()) {
            return Err(Error::Argument(format!(
                "--bilateral-sigma-space {space} must be a positive number"
            )));
        }
        let (depth, z2) = (self.bilateral_sigma_depth, self.bilateral_sigma_depth_z2);
        if !(depth >= 0.0 && z2 >= 0.0 && depth + z2 > 0.0 && (depth + z2).is_finite()) {
            return Err(Error::Argument(format!(
                "--bilateral-sigma-depth {depth} and --bilateral-sigma-depth-z2 {z2} must be \
                 non-negative numbers, not both zero"
            )));
        }
        Ok(Some(BilateralSettings {
            radius_px: self.bilateral_radius,
            sigma_space_px: self.bilateral_sigma_space,
            sigma_depth_m: self.bilateral_sigma_depth,
            sigma_depth_per_m2: self.bilateral_sigma_depth_z2,
        }))
    }

    /// The flags that reproduce these settings (for `bench`'s child processes).
    fn args(&self) -> Vec<String> {
        if !self.bilateral {
            return Vec::new();
        }
        vec![
            "--bilateral".into(),
            "--bilateral-radius".into(),
            self.bilateral_radius.to_string(),
            "--bilateral-sigma-space".into(),
            self.bilateral_sigma_space.to_string(),
            "--bilateral-sigma-depth".into(),
            self.bilateral_sigma_depth.to_string(),
            "--bilateral-sigma-depth-z2".into(),
            self.bilateral_sigma_depth_z2.to_string(),
        ]
    }
}

/// The coarse-to-fine ICP schedule (shared by `run`, `icp`, `compare` and `bench`); the
/// profile's without the flag.
#[derive(Debug, Args)]
pub struct IcpLevelArgs {
    /// ICP iterations per pyramid level, coarse to fine: "10,5,4" is three levels (each
    /// half the size of the next finer one), at most 10 iterations at the coarsest and 4 at
    /// the full maps; one number is single-level ICP (assignment 10, robust 10,5,4).
    #[arg(long, value_delimiter = ',', value_name = "N,...")]
    pub icp_level_iters: Option<Vec<usize>>,
}

impl IcpLevelArgs {
    /// The schedule, or `None` without the flag (the profile's then).
    pub fn schedule(&self) -> Result<Option<Vec<usize>>> {
        let Some(s) = &self.icp_level_iters else {
            return Ok(None);
        };
        if s.is_empty() || s.len() > MAX_ICP_LEVELS || s.contains(&0) {
            return Err(Error::Argument(format!(
                "--icp-level-iters {s:?}: want 1 to {MAX_ICP_LEVELS} iteration counts, coarse \
                 to fine, each at least 1 (e.g. 10,5,4)"
            )));
        }
        Ok(Some(s.clone()))
    }

    /// The flags that reproduce this schedule (for `bench`'s child processes).
    fn args(&self) -> Vec<String> {
        match &self.icp_level_iters {
            Some(s) => vec![
                "--icp-level-iters".into(),
                s.iter()
                    .map(|n| n.to_string())
                    .collect::<Vec<_>>()
                    .join(","),
            ],
            None => Vec::new(),
        }
    }
}

/// Pipeline tunables shared by `run` and `icp`: a profile, then any of its values
/// overridden one by one (the flags' defaults are the profile's).
#[derive(Debug, Args)]
pub struct PipelineArgs {
    /// Parameter set to start from: the robust tracker and fusion for real (noisy) depth,
    /// the default, or the course assignment's exact algorithm.
    #[arg(long, value_enum, default_value_t = Profile::Robust)]
    pub profile: Profile,
    /// Keep every N-th pixel in each direction.
    #[arg(long, default_value_t = 2)]
    pub downsample: u32,
    /// ICP correspondence distance threshold, metres (assignment 0.07, robust 0.10).
    #[arg(long)]
    pub icp_dist: Option<f32>,
    /// ICP normal-angle threshold, degrees; 180 turns it off (assignment 180, robust 20).
    #[arg(long)]
    pub icp_angle: Option<f32>,
    /// Huber threshold on ICP residuals, metres; 0 turns it off (assignment 0, robust 0.02).
    #[arg(long)]
    pub icp_huber: Option<f32>,
    #[command(flatten)]
    pub icp_levels: IcpLevelArgs,
    /// Fusion distance threshold, metres (assignment 0.03, robust 0.05).
    #[arg(long)]
    pub fuse_dist: Option<f32>,
    /// Fusion normal-angle threshold, degrees (assignment 5, robust 60).
    #[arg(long)]
    pub fuse_angle: Option<f32>,
    /// How fusion pairs pixels with surfels (assignment projective, robust best-candidate).
    #[arg(long, value_enum)]
    pub fuse_association: Option<Association>,
    /// Confidence of a measurement over its distance from the image centre: the Gaussian's
    /// sigma (normalised, 1 at the corners); 0 weighs every measurement 1 (assignment 0,
    /// robust 0.6).
    #[arg(long)]
    pub confidence_sigma: Option<f32>,
    /// Best-candidate fusion's duplicate pruning: a surfel that was not refreshed retires
    /// when the surfel its pixel merged into lies within this many times the larger radius
    /// (and faces the same way, and is at least as confident); 0 turns it off (assignment
    /// 0, robust 0.5). It runs on the frames the unstable-surfel removal runs after
    /// (--removal-every), or every frame without the removal.
    #[arg(long)]
    pub prune_scale: Option<f32>,
    /// Implementation: auto, cpu or gpu.
    #[arg(long, value_enum, default_value_t = BackendChoice::Auto)]
    pub backend: BackendChoice,
    #[command(flatten)]
    pub bilateral: BilateralArgs,
    /// Removal of unstable surfels: surfels with fewer observations than this whose last
    /// one is more than --unstable-max-age frames old are removed after each fusion; 0
    /// turns the removal off (assignment off, robust 20).
    #[arg(long)]
    pub stable_weight: Option<f32>,
    /// Removal of unstable surfels: frames an unstable surfel may go unobserved (assignment
    /// off, robust 20; with the assignment profile, either flag turns the removal on).
    #[arg(long)]
    pub unstable_max_age: Option<u32>,
    /// Removal of unstable surfels: run it after every N-th frame (robust 10).
    #[arg(long)]
    pub removal_every: Option<u32>,
    /// Valid depth range, metres: nearer pixels are invalid (both profiles 0.1).
    #[arg(long)]
    pub min_depth: Option<f32>,
    /// Valid depth range, metres: farther pixels are invalid (both profiles 10).
    #[arg(long)]
    pub max_depth: Option<f32>,
    /// Normals across a depth jump larger than this, metres, are invalid (both 0.1).
    #[arg(long)]
    pub max_depth_jump: Option<f32>,
    /// Weigh each ICP row by the depth-noise model (assignment false, robust true).
    #[arg(long)]
    pub icp_noise_weight: Option<bool>,
    /// ICP stops when the increment's rotation (rad) and translation (m) are both below
    /// this (assignment 1e-6, robust 1e-5).
    #[arg(long)]
    pub icp_min_increment: Option<f64>,
    /// Coarser ICP pyramid levels: half-width of the averaging window, pixels of the finer
    /// level (1).
    #[arg(long)]
    pub pyramid_radius: Option<u32>,
    /// Coarser ICP pyramid levels: neighbours whose depth differs from the sampled pixel's
    /// by more than this times its depth squared (1/m) are left out of the average (0.03).
    #[arg(long)]
    pub pyramid_depth_gate_z2: Option<f32>,
}

#[derive(Debug, Args)]
pub struct RunArgs {
    #[command(flatten)]
    pub data: DatasetArgs,
    #[command(flatten)]
    pub pipeline: PipelineArgs,
    /// Inclusive frame range "A..B" by position in the sequence (default: all frames from
    /// the first with ground truth).
    #[arg(long)]
    pub frames: Option<String>,
    /// Poses from tracking or from ground truth.
    #[arg(long, value_enum, default_value_t = PosesChoice::Track)]
    pub poses: PosesChoice,
    /// Play the frame range forwards, backwards, forwards ... for this many frames (a long
    /// sequence that revisits the same scene; stamps become positions 0, 1, ...).
    #[arg(long, value_name = "FRAMES")]
    pub revisit: Option<usize>,
    /// Output directory.
    #[arg(long, default_value = "out")]
    pub out: PathBuf,
    /// (for `wgslam batch`) Print `progress DONE TOTAL` on stdout after every frame.
    #[arg(long, hide = true)]
    pub progress_lines: bool,
    /// Also write a Rerun recording of the run here (camera path, ground truth, colour and
    /// depth images, the map every few frames; open it with `rerun FILE.rrd`). Needs a
    /// binary built with `--features rerun`; without it this flag fails with a message.
    #[arg(long, value_name = "FILE.rrd")]
    pub rerun: Option<PathBuf>,
    /// With --rerun: log the map (at most 100k of its surfels) after every N-th frame, and
    /// after the last.
    #[arg(long, value_name = "N", default_value_t = 10)]
    pub rerun_map_every: usize,
}

#[derive(Debug, Args)]
pub struct IcpArgs {
    #[command(flatten)]
    pub data: DatasetArgs,
    #[command(flatten)]
    pub pipeline: PipelineArgs,
    /// Source frame (its points are the model).
    #[arg(long, default_value_t = 10)]
    pub source: usize,
    /// Target frame (aligned to the source); default 50, or the last frame of a shorter
    /// sequence (the bundled one has 24).
    #[arg(long)]
    pub target: Option<usize>,
    /// Write result.json and before/after overlay pictures (icp_before.png, icp_after.png)
    /// here.
    #[arg(long)]
    pub out: Option<PathBuf>,
}

#[derive(Debug, Args)]
pub struct CompareArgs {
    #[command(flatten)]
    pub data: DatasetArgs,
    /// Inclusive frame range "A..B" (default: 20 frames from the first with ground truth).
    #[arg(long)]
    pub frames: Option<String>,
    /// Keep every N-th pixel in each direction.
    #[arg(long, default_value_t = 2)]
    pub downsample: u32,
    /// Parameter set (see `run --help`).
    #[arg(long, value_enum, default_value_t = Profile::Robust)]
    pub profile: Profile,
    #[command(flatten)]
    pub bilateral: BilateralArgs,
    #[command(flatten)]
    pub icp_levels: IcpLevelArgs,
    /// Let each backend track on its own state (end to end, as two separate runs) instead
    /// of the default lockstep, where the GPU starts every frame from the CPU's map and pose.
    #[arg(long)]
    pub free: bool,
    /// Lockstep: compare the maps after every K-th frame (and after the last).
    #[arg(long, value_name = "K", default_value_t = 1)]
    pub map_every: usize,
    /// Write the full comparison as JSON here.
    #[arg(long)]
    pub json: Option<PathBuf>,
}

#[derive(Debug, Args)]
pub struct BenchArgs {
    #[command(flatten)]
    pub data: DatasetArgs,
    /// Inclusive frame range "A..B" (default: all frames from the first with ground truth).
    #[arg(long)]
    pub frames: Option<String>,
    /// Keep every N-th pixel in each direction.
    #[arg(long, default_value_t = 2)]
    pub downsample: u32,
    /// Parameter set (see `run --help`).
    #[arg(long, value_enum, default_value_t = Profile::Robust)]
    pub profile: Profile,
    #[command(flatten)]
    pub bilateral: BilateralArgs,
    #[command(flatten)]
    pub icp_levels: IcpLevelArgs,
    /// Backends to run (bench-one runs the first only).
    #[arg(long, value_enum, value_delimiter = ',', default_values_t = [BackendChoice::Cpu, BackendChoice::Gpu])]
    pub backends: Vec<BackendChoice>,
    /// Also time every GPU kernel (one more pass over the frames, GPU timestamps).
    #[arg(long)]
    pub kernels: bool,
    /// Rounds of whole-frame timing. Round 1 also times every stage; each later round runs
    /// the backends once more without it, in the reverse order of the round before (CPU,
    /// GPU, GPU, CPU, ...), so a machine whose speed drifts favours neither. The ratio is
    /// reported per round and as the median over rounds.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..))]
    pub rounds: u32,
    /// Also run the CPU reference and the GPU in one process, alternating frame by frame,
    /// and report the per-frame GPU/CPU ratio: robust to other jobs changing the machine's
    /// speed between runs (runs both backends whatever --backends lists; needs a GPU).
    #[arg(long)]
    pub interleaved: bool,
    /// The long-sequence benchmark instead: each backend runs (`wgslam run --revisit N`, in
    /// a child process) over the frame range played forwards, backwards, ... for N frames;
    /// prints time per frame over the first and last 100 frames, the map after each pass,
    /// peak memory and ATE.
    #[arg(long, value_name = "N")]
    pub revisit: Option<usize>,
    /// Write the results as JSON here.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// bench-one only: time whole frames only (no per-stage pass, no kernels).
    #[arg(long, hide = true)]
    pub frames_only: bool,
}

#[derive(Debug, Args)]
pub struct EvalArgs {
    /// Estimated trajectory, TUM format.
    pub estimate: PathBuf,
    /// Ground truth trajectory, TUM format (ICL-NUIM's *.gt.freiburg works).
    pub ground_truth: PathBuf,
    /// RPE frame distance.
    #[arg(long, default_value_t = 1)]
    pub delta: usize,
    /// Write a trajectory plot (estimate vs ground truth from above, and the error over
    /// frames) to this PNG.
    #[arg(long)]
    pub plot: Option<PathBuf>,
}

impl DatasetArgs {
    /// Opens the sequence with the overrides applied.
    pub fn open(&self) -> Result<dataset::Sequence> {
        let root = self.dataset.clone().unwrap_or_else(bundled_dataset);
        let mut intrinsics = match &self.camera {
            Some(name) => Some(Intrinsics::preset(name).ok_or_else(|| {
                Error::Argument(format!(
                    "unknown camera preset {name:?} (icl, fr1, fr2, fr3)"
                ))
            })?),
            None => None,
        };
        if let Some(s) = &self.intrinsics {
            let v: Vec<f32> = s
                .split(',')
                .map(|x| x.trim().parse::<f32>())
                .collect::<std::result::Result<_, _>>()
                .map_err(|_| Error::Argument(format!("--intrinsics {s:?}: want fx,fy,cx,cy")))?;
            if v.len() != 4 || v[0] == 0.0 || v[1] == 0.0 {
                return Err(Error::Argument(format!(
                    "--intrinsics {s:?}: want four numbers fx,fy,cx,cy with fx, fy non-zero"
                )));
            }
            let base = intrinsics.unwrap_or(Intrinsics::ICL_NUIM);
            intrinsics = Some(Intrinsics {
                fx: v[0],
                fy: v[1],
                cx: v[2],
                cy: v[3],
                ..base
            });
        }
        let opts = SequenceOptions {
            gt_path: self.gt.clone(),
            intrinsics,
            depth_scale: self.depth_scale,
            max_time_diff: self.max_time_diff,
        };
        dataset::open(&root, &opts)
    }
}

impl PipelineArgs {
    /// Pipeline parameters from the flags.
    pub fn params(&self, poses: PoseSource) -> Result<SlamParams> {
        // The profile at --downsample with the bilateral and ICP schedule flags, then the
        // overrides.
        let base = profile_params(
            self.profile,
            self.downsample,
            &self.bilateral,
            &self.icp_levels,
        )?;
        let p = SlamParams {
            icp_dist_m: self.icp_dist.unwrap_or(base.icp_dist_m),
            icp_normal_deg: self.icp_angle.unwrap_or(base.icp_normal_deg),
            icp_huber_m: self.icp_huber.unwrap_or(base.icp_huber_m),
            fuse_dist_m: self.fuse_dist.unwrap_or(base.fuse_dist_m),
            fuse_normal_deg: self.fuse_angle.unwrap_or(base.fuse_normal_deg),
            fuse_association: self.fuse_association.unwrap_or(base.fuse_association),
            fuse_confidence_sigma: self.confidence_sigma.unwrap_or(base.fuse_confidence_sigma),
            fuse_prune_scale: self.prune_scale.unwrap_or(base.fuse_prune_scale),
            min_depth_m: self.min_depth.unwrap_or(base.min_depth_m),
            max_depth_m: self.max_depth.unwrap_or(base.max_depth_m),
            max_depth_jump_m: self.max_depth_jump.unwrap_or(base.max_depth_jump_m),
            icp_noise_weight: self.icp_noise_weight.unwrap_or(base.icp_noise_weight),
            icp_min_increment: self.icp_min_increment.unwrap_or(base.icp_min_increment),
            pyramid: PyramidSettings {
                radius_px: self.pyramid_radius.unwrap_or(base.pyramid.radius_px),
                max_depth_diff_per_m2: self
                    .pyramid_depth_gate_z2
                    .unwrap_or(base.pyramid.max_depth_diff_per_m2),
                ..base.pyramid
            },
            poses,
            ..base
        };
        if !(p.min_depth_m.is_finite()
            && p.min_depth_m >= 0.0
            && p.max_depth_m.is_finite()
            && p.max_depth_m > p.min_depth_m)
        {
            return Err(Error::Argument(format!(
                "--min-depth {} and --max-depth {} must be a range 0 <= min < max",
                p.min_depth_m, p.max_depth_m
            )));
        }
        for (flag, v) in [
            ("--max-depth-jump", p.max_depth_jump_m as f64),
            ("--icp-min-increment", p.icp_min_increment),
            (
                "--pyramid-depth-gate-z2",
                p.pyramid.max_depth_diff_per_m2 as f64,
            ),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(Error::Argument(format!("{flag} {v} must be positive")));
            }
        }
        for (flag, v) in [
            ("--icp-dist", p.icp_dist_m),
            ("--icp-angle", p.icp_normal_deg),
            ("--fuse-dist", p.fuse_dist_m),
            ("--fuse-angle", p.fuse_normal_deg),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(Error::Argument(format!("{flag} {v} must be positive")));
            }
        }
        if !(p.fuse_confidence_sigma.is_finite() && p.fuse_confidence_sigma >= 0.0) {
            return Err(Error::Argument(format!(
                "--confidence-sigma {} must be 0 (off) or positive",
                p.fuse_confidence_sigma
            )));
        }
        if !(p.fuse_prune_scale.is_finite() && p.fuse_prune_scale >= 0.0) {
            return Err(Error::Argument(format!(
                "--prune-scale {} must be 0 (off) or positive",
                p.fuse_prune_scale
            )));
        }
        if !(p.icp_huber_m.is_finite() && p.icp_huber_m >= 0.0) {
            return Err(Error::Argument(format!(
                "--icp-huber {} must be 0 (off) or positive",
                p.icp_huber_m
            )));
        }
        if let Some(w) = self.stable_weight {
            if !(w.is_finite() && w >= 0.0) {
                return Err(Error::Argument(format!(
                    "--stable-weight {w} must be 0 (off) or positive"
                )));
            }
        }
        // --stable-weight 0 turns the removal off; either flag otherwise overrides the
        // profile's rule (or the robust one's, when the profile has none).
        if self.removal_every == Some(0) {
            return Err(Error::Argument("--removal-every must be at least 1".into()));
        }
        let unstable_removal = match (
            self.stable_weight,
            self.unstable_max_age,
            self.removal_every,
        ) {
            (Some(0.0), _, _) => None,
            (None, None, None) => p.unstable_removal,
            (w, age, every) => {
                let base = p.unstable_removal.unwrap_or_default();
                Some(UnstableRemoval {
                    stable_weight: w.unwrap_or(base.stable_weight),
                    max_age_frames: age.unwrap_or(base.max_age_frames),
                    every_frames: every.unwrap_or(base.every_frames),
                })
            }
        };
        Ok(SlamParams {
            unstable_removal,
            ..p
        })
    }
}

/// The bundled sequence: next to the executable's crate when run through cargo, else
/// relative to the working directory.
pub fn bundled_dataset() -> PathBuf {
    let from_crate = Path::new(env!("CARGO_MANIFEST_DIR")).join(BUNDLED_DATASET);
    if from_crate.is_dir() {
        from_crate
    } else {
        PathBuf::from(BUNDLED_DATASET)
    }
}

/// A progress bar on stderr, hidden when stderr is not a terminal.
fn progress_bar(len: usize) -> indicatif::ProgressBar {
    let bar = indicatif::ProgressBar::new(len as u64);
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{elapsed_precise} [{bar:30}] {pos}/{len} frames {msg}",
        )
        .expect("static template")
        .progress_chars("=> "),
    );
    bar
}

/// Runs the parsed command.
pub fn execute(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Run(a) => cmd_run(a),
        Command::Icp(a) => cmd_icp(a),
        Command::Eval(a) => cmd_eval(a),
        Command::Compare(a) => cmd_compare(a),
        Command::Bench(a) => cmd_bench(a),
        Command::BenchOne(a) => cmd_bench_one(a),
        Command::Register(a) => crate::cli::scan::run_register(&a).map(|_| ()),
        Command::Odometry(a) => crate::cli::scan::run_odometry(&a).map(|_| ()),
        Command::Render(a) => cmd_render(a),
        Command::BenchScan(a) => crate::cli::scan::run_bench_scan(&a).map(|_| ()),
        Command::Batch(a) => crate::cli::batch::execute(a),
    }
}

fn cmd_run(a: RunArgs) -> Result<()> {
    let seq = a.data.open()?;
    let (first, last) = match &a.frames {
        Some(r) => dataset::parse_range(r)?,
        None => (default_first_frame(&seq), seq.len() - 1),
    };
    let mut range = seq.select(first, last)?;
    let seq = match a.revisit {
        Some(total) => {
            let long = seq.revisiting(first, last, total)?;
            range = 0..=total - 1;
            long
        }
        None => seq,
    };
    let poses = match a.poses {
        PosesChoice::Track => PoseSource::Track,
        PosesChoice::Gt => PoseSource::GroundTruth,
    };
    let params = a.pipeline.params(poses)?;
    let bar = progress_bar(range.clone().count());
    let total = range.clone().count();
    let on_frame = |f: &run::FrameOutcome| {
        bar.set_message(format!("{} surfels", f.report.surfels));
        bar.inc(1);
        if a.progress_lines {
            use std::io::Write;
            println!("progress {} {total}", bar.position());
            let _ = std::io::stdout().flush();
        }
        if let crate::slam::pipeline::TrackStatus::Lost(why) = &f.report.status {
            bar.println(format!(
                "frame {}: tracking lost ({why}); not fused",
                f.index
            ));
        }
        if f.report.status == crate::slam::pipeline::TrackStatus::EmptyDepth {
            bar.println(format!("frame {}: no valid depth; skipped", f.index));
        }
    };
    let mut recording = open_recording(&a, &seq, &range)?;
    let backend = any_backend::open(a.pipeline.backend)?;
    let result = run::run_observed(
        backend,
        &seq,
        range,
        params,
        run::Decode::Overlapped,
        on_frame,
        recording.as_mut().map(|r| r as &mut dyn run::FrameObserver),
    )?;
    bar.finish_and_clear();
    run::write_outputs(&a.out, &result)?;
    let pictures = run::write_pictures(&a.out, &result, &seq)?;
    let recorded = recording.map(|r| r.finish(&result.map)).transpose()?;
    print_summary(&result.metrics, &a.out);
    for p in pictures.iter().chain(&recorded) {
        println!("wrote {}", p.display());
    }
    Ok(())
}

/// `run --rerun FILE`'s recording.
#[cfg(feature = "rerun")]
use crate::tools::rerun_log::RerunLog as Recording;

/// Without the `rerun` feature there is never a recording (`--rerun` fails up front), so
/// the type has no values and its methods cannot be called.
#[cfg(not(feature = "rerun"))]
enum Recording {}

#[cfg(not(feature = "rerun"))]
impl Recording {
    fn finish(self, _map: &crate::slam::map::SurfelMap) -> Result<PathBuf> {
        match self {}
    }
}

#[cfg(not(feature = "rerun"))]
impl run::FrameObserver for Recording {
    fn wants_map(&mut self, _index: usize) -> bool {
        match *self {}
    }
    fn frame(
        &mut self,
        _raw: &dataset::RawFrame,
        _outcome: &run::FrameOutcome,
        _map: Option<&crate::slam::map::SurfelMap>,
    ) -> Result<()> {
        match *self {}
    }
}

/// The recording `--rerun` asks for, started over the run's frames.
#[cfg(feature = "rerun")]
fn open_recording(
    a: &RunArgs,
    seq: &dataset::Sequence,
    range: &std::ops::RangeInclusive<usize>,
) -> Result<Option<Recording>> {
    a.rerun
        .as_deref()
        .map(|path| Recording::create(path, seq, *range.start(), *range.end(), a.rerun_map_every))
        .transpose()
}

/// Without the `rerun` feature: an error naming the feature when `--rerun` is given.
#[cfg(not(feature = "rerun"))]
fn open_recording(
    a: &RunArgs,
    _seq: &dataset::Sequence,
    _range: &std::ops::RangeInclusive<usize>,
) -> Result<Option<Recording>> {
    match &a.rerun {
        Some(_) => Err(Error::Argument(
            "--rerun needs a wgslam built with the `rerun` feature \
             (cargo build --release --features rerun); this binary was built without it"
                .into(),
        )),
        None => Ok(None),
    }
}

/// Without `--frames`, a run starts at the first frame with ground truth (ICL-NUIM's frame 0
/// has none), so the map and trajectory share the ground truth's world frame.
fn default_first_frame(seq: &dataset::Sequence) -> usize {
    match seq.frames.iter().position(|f| f.gt_cam_to_world.is_some()) {
        Some(i) if i > 0 => {
            eprintln!(
                "note: starting at frame {i}, the first with ground truth (use --frames to change)"
            );
            i
        }
        _ => 0,
    }
}

fn print_summary(m: &run::Metrics, out: &Path) {
    println!(
        "{} frames {}..{} on {} ({}x{}): {:.1} ms/frame median, {:.2} s total",
        m.frames,
        m.first_frame,
        m.last_frame,
        m.backend,
        m.width,
        m.height,
        m.time_per_frame_median_s * 1e3,
        m.time_total_s
    );
    println!(
        "map: {} points, compression ratio {:.4}",
        m.map_points, m.compression_ratio
    );
    let t = &m.tracking;
    println!(
        "tracking: {} given, {} converged, {} at max iterations, {} stopped early, {} lost, {} empty",
        t.given, t.converged, t.max_iterations, t.stopped, t.lost, t.empty_depth
    );
    if let Some(acc) = &m.accuracy {
        println!(
            "ATE RMSE {:.3} mm aligned, {:.3} mm unaligned; RPE {:.3} mm, {:.4} deg ({} poses)",
            acc.ate_rmse_aligned_m * 1e3,
            acc.ate_rmse_unaligned_m * 1e3,
            acc.rpe_trans_rmse_m * 1e3,
            acc.rpe_rot_rmse_deg,
            acc.pairs
        );
    }
    if let Some(mem) = m.peak_memory_mib {
        println!("peak memory {mem:.0} MiB");
    }
    println!(
        "wrote {}/{{trajectory.tum, map.ply, metrics.json, frames.json}}",
        out.display()
    );
}

fn cmd_icp(a: IcpArgs) -> Result<()> {
    let seq = a.data.open()?;
    let target = a.target.unwrap_or(50.min(seq.len() - 1));
    seq.select(a.source.min(target), a.source.max(target))?;
    let params = a.pipeline.params(PoseSource::Track)?;
    let r = two_frame::align_frames(
        any_backend::open(a.pipeline.backend)?,
        &seq,
        a.source,
        target,
        params,
    )?;
    println!("frames {} -> {target}", a.source);
    println!("iter  level  inliers  mean squared residual (m^2)");
    for (i, it) in r.iterations.iter().enumerate() {
        println!(
            "{i:4}  {:5}  {:7}  {:.6e}",
            it.level, it.inliers, it.mean_sq_residual
        );
    }
    println!("status: {:?}", r.status);
    let t = glam::DMat4::from_cols_array_2d(&r.t_source_to_target);
    println!("T_source_to_target (row-major):");
    for row in 0..4 {
        let rv = t.row(row);
        println!("  {:10.6} {:10.6} {:10.6} {:10.6}", rv.x, rv.y, rv.z, rv.w);
    }
    if let (Some(re), Some(te), Some((gr, gt))) =
        (r.rotation_error_deg, r.translation_error_m, r.gt_motion)
    {
        println!(
            "against ground truth: rotation error {re:.4} deg, translation error {:.2} mm \
             (true motion {gr:.2} deg, {:.1} mm)",
            te * 1e3,
            gt * 1e3
        );
    }
    if let Some(out) = &a.out {
        let [result, before, after] = two_frame::write_outputs(out, &r, &seq)?;
        println!(
            "wrote {}, {} and {} (source orange, target blue)",
            result.display(),
            before.display(),
            after.display()
        );
    }
    Ok(())
}

/// Frames from `--frames`, or from the first frame with ground truth to at most `count`
/// frames later (`usize::MAX` for all).
fn frame_range(
    seq: &dataset::Sequence,
    frames: &Option<String>,
    count: usize,
) -> Result<(usize, usize)> {
    let (first, last) = match frames {
        Some(r) => dataset::parse_range(r)?,
        None => {
            let first = default_first_frame(seq);
            (first, (seq.len() - 1).min(first.saturating_add(count - 1)))
        }
    };
    let r = seq.select(first, last)?;
    Ok((*r.start(), *r.end()))
}

/// The profile's parameters at `downsample`, with the bilateral filter on when the flags
/// say so (`--bilateral` turns it on with its flags' settings; without it the profile
/// decides) and the ICP schedule of `--icp-level-iters` (the profile's without it).
/// `run`/`icp` override further values on top (`PipelineArgs::params`).
fn profile_params(
    profile: Profile,
    downsample: u32,
    bilateral: &BilateralArgs,
    icp_levels: &IcpLevelArgs,
) -> Result<SlamParams> {
    if downsample == 0 || downsample > 16 {
        return Err(Error::Argument(format!(
            "--downsample {downsample} must be between 1 and 16"
        )));
    }
    let base = SlamParams::profile(profile);
    Ok(SlamParams {
        downsample,
        bilateral: bilateral.settings()?.or(base.bilateral),
        icp_level_iters: icp_levels
            .schedule()?
            .unwrap_or_else(|| base.icp_level_iters.clone()),
        ..base
    })
}

fn cmd_compare(a: CompareArgs) -> Result<()> {
    let seq = a.data.open()?;
    let (first, last) = frame_range(&seq, &a.frames, 20)?;
    let params = profile_params(a.profile, a.downsample, &a.bilateral, &a.icp_levels)?;
    let mode = if a.free {
        compare::Mode::Free
    } else {
        compare::Mode::Lockstep {
            map_every: a.map_every.max(1),
        }
    };
    let gpu = any_backend::open(BackendChoice::Gpu)?;
    let cpu = any_backend::open(BackendChoice::Cpu)?;
    println!(
        "mode: {}",
        match mode {
            compare::Mode::Lockstep { map_every } => format!(
                "lockstep (the GPU starts every frame from the CPU's map and pose; maps \
                 compared every {map_every} frame(s) and after the last)"
            ),
            compare::Mode::Free => "free (each backend tracks on its own state)".into(),
        }
    );
    let c = compare::compare(cpu, gpu, &seq, first, last, params, mode)?;
    println!(
        "frame  vertex(m)  normal(deg)  valid-mismatch  system-rel   pose(mm)  pose(deg)  \
         fused cpu/gpu    surfels cpu/gpu  map-unmatched"
    );
    for f in &c.frames {
        let opt = |x: Option<String>| x.unwrap_or_else(|| "-".into());
        println!(
            "{:5}  {:9.2e}  {:11.5}  {:13.5}%  {:>10}  {:9.5}  {:9.6}  {:>15}  {:>15}  {:>13}",
            f.index,
            f.maps.vertex_max_abs_m,
            f.maps.normal_max_deg,
            f.maps.validity_mismatch_fraction * 100.0,
            opt(f.system_rel_diff.map(|r| format!("{r:.2e}"))),
            f.pose_diff_mm,
            f.pose_diff_deg,
            opt(f.fused_surfels.map(|(a, b)| format!("{a}/{b}"))),
            format!("{}/{}", f.surfels.0, f.surfels.1),
            opt(f
                .map
                .as_ref()
                .map(|m| format!("{:.4}%", m.unmatched_fraction() * 100.0))),
        );
    }
    println!(
        "map after the last frame: {} vs {} surfels; unmatched within {} mm: {:.4}% cpu, \
         {:.4}% gpu; match distance mean {:.2e} m, max {:.2e} m",
        c.map.surfels.0,
        c.map.surfels.1,
        c.map.match_radius_m * 1e3,
        c.map.unmatched_a_fraction * 100.0,
        c.map.unmatched_b_fraction * 100.0,
        c.map.mean_match_m,
        c.map.max_match_m
    );
    let w = &c.worst;
    println!(
        "worst ({} mode, {} frames): vertex {:.2e} m, normal {:.5} deg, validity {:.5}%, \
         system {:.2e}, pose {:.5} mm / {:.6} deg, surfel counts {:.2e} fused / {:.2e} after \
         the frame, map unmatched {:.4}% (max match {:.2e} m)",
        c.mode.name(),
        c.frames.len(),
        w.vertex_max_abs_m,
        w.normal_max_deg,
        w.validity_mismatch_fraction * 100.0,
        w.system_rel_diff,
        w.pose_diff_mm,
        w.pose_diff_deg,
        w.fused_surfels_rel_diff,
        w.surfels_rel_diff,
        w.map_unmatched_fraction * 100.0,
        w.map_max_match_m
    );
    if let Some(path) = &a.json {
        run::write_json(path, &c)?;
    }
    if c.violations.is_empty() {
        println!(
            "backends agree within the documented {} tolerances (src/tools/compare.rs)",
            c.mode.name()
        );
        Ok(())
    } else {
        for v in &c.violations {
            println!("beyond tolerance: {v}");
        }
        Err(Error::Numerical(format!(
            "{} comparisons beyond the {} tolerances",
            c.violations.len(),
            c.mode.name()
        )))
    }
}

fn cmd_bench(a: BenchArgs) -> Result<()> {
    if let Some(total) = a.revisit {
        return bench_revisit(&a, total);
    }
    let mut rounds = Vec::new();
    for round in 0..a.rounds {
        let mut order = a.backends.clone();
        if round % 2 == 1 {
            order.reverse();
        }
        let mut results = Vec::new();
        for b in &order {
            let name = format!("{b:?}").to_lowercase();
            let frames_only = round > 0;
            let kernels = a.kernels && !frames_only;
            results.push(bench::bench_in_child(
                &a.child_args(),
                &name,
                frames_only,
                kernels,
            )?);
        }
        if round == 0 {
            bench::print_table(&results);
        } else {
            bench::print_round(round as usize + 1, &results);
        }
        rounds.push(results);
    }
    if a.rounds > 1 {
        bench::print_ratio_over_rounds(&rounds);
    }
    let interleaved = if a.interleaved {
        eprintln!("benchmarking both backends frame by frame in one process ...");
        let seq = a.data.open()?;
        let (first, last) = frame_range(&seq, &a.frames, usize::MAX)?;
        let params = profile_params(a.profile, a.downsample, &a.bilateral, &a.icp_levels)?;
        let gpu = crate::gpu::GpuBackend::open()?;
        let r = bench::bench_interleaved(gpu, &seq, first, last, &params)?;
        bench::print_interleaved(&r);
        Some(r)
    } else {
        None
    };
    if let Some(path) = &a.json {
        run::write_json(
            path,
            &serde_json::json!({ "rounds": rounds, "interleaved": interleaved }),
        )?;
    }
    Ok(())
}

/// `bench --revisit N`: each backend's long run in a child `wgslam run`, then the table.
fn bench_revisit(a: &BenchArgs, total: usize) -> Result<()> {
    let seq = a.data.open()?;
    let (first, last) = frame_range(&seq, &a.frames, usize::MAX)?;
    seq.revisiting(first, last, total)?;
    let mut runs = Vec::new();
    for b in &a.backends {
        let name = format!("{b:?}").to_lowercase();
        eprintln!("{name}: {total} frames over {first}..{last} forwards and backwards ...");
        // `child_args` carries --frames when given; without it the child's default range
        // is the one resolved here (from the first frame with ground truth).
        let mut args = vec!["run".to_string()];
        args.extend(a.child_args());
        args.extend([
            "--revisit".into(),
            total.to_string(),
            "--backend".into(),
            name.clone(),
        ]);
        runs.push(crate::tools::long_run::run_in_child(
            &args,
            &name,
            last - first,
        )?);
    }
    crate::tools::long_run::print(&runs);
    if let Some(path) = &a.json {
        run::write_json(path, &serde_json::json!({ "revisit": runs }))?;
    }
    Ok(())
}

impl BenchArgs {
    /// The `bench-one` arguments that reproduce this invocation's dataset, frames and
    /// resolution in a child process (every dataset option, so the child opens the
    /// sequence exactly as this process does).
    fn child_args(&self) -> Vec<String> {
        let d = &self.data;
        let mut args = Vec::new();
        if let Some(dir) = &d.dataset {
            args.push(dir.display().to_string());
        }
        for (flag, v) in [
            ("--gt", d.gt.as_ref().map(|p| p.display().to_string())),
            ("--camera", d.camera.clone()),
            ("--intrinsics", d.intrinsics.clone()),
            ("--depth-scale", d.depth_scale.map(|x| x.to_string())),
            ("--max-time-diff", Some(d.max_time_diff.to_string())),
            ("--frames", self.frames.clone()),
            ("--downsample", Some(self.downsample.to_string())),
            (
                "--profile",
                clap::ValueEnum::to_possible_value(&self.profile).map(|v| v.get_name().to_string()),
            ),
        ] {
            if let Some(v) = v {
                args.extend([flag.to_string(), v]);
            }
        }
        args.extend(self.bilateral.args());
        args.extend(self.icp_levels.args());
        args
    }
}

fn cmd_bench_one(a: BenchArgs) -> Result<()> {
    let seq = a.data.open()?;
    let (first, last) = frame_range(&seq, &a.frames, usize::MAX)?;
    let params = profile_params(a.profile, a.downsample, &a.bilateral, &a.icp_levels)?;
    let choice = *a.backends.first().unwrap_or(&BackendChoice::Cpu);
    let make = || any_backend::open(choice);
    let mut r = if a.frames_only {
        bench::bench_frames(make, &seq, first, last, &params)?
    } else {
        bench::bench_backend(make, &seq, first, last, &params)?
    };
    if a.kernels && !a.frames_only && r.backend == "gpu" {
        r.kernels = bench::gpu_kernel_times(&seq, first, last, &params)?;
    }
    println!(
        "{}",
        serde_json::to_string(&r).map_err(|e| Error::encode("the bench result", e))?
    );
    Ok(())
}

fn cmd_eval(a: EvalArgs) -> Result<()> {
    let est = io::trajectory::read_tum(&a.estimate)?;
    let gt = io::trajectory::read_tum(&a.ground_truth)?;
    let aligned = eval::ate(&est, &gt, true)?;
    let unaligned = eval::ate(&est, &gt, false)?;
    let rpe = eval::rpe(&est, &gt, a.delta)?;
    println!(
        "ATE RMSE {:.3} mm aligned, {:.3} mm unaligned ({} poses)",
        aligned.rmse_m * 1e3,
        unaligned.rmse_m * 1e3,
        aligned.pairs
    );
    println!(
        "RPE (delta {}): translation RMSE {:.3} mm, rotation RMSE {:.4} deg ({} pairs)",
        a.delta,
        rpe.trans_rmse_m * 1e3,
        rpe.rot_rmse_deg,
        rpe.pairs
    );
    if let Some(path) = &a.plot {
        crate::render::plot::write_trajectory_plot(path, &est, &gt)?;
        println!("wrote {}", path.display());
    }
    Ok(())
}

fn cmd_render(a: crate::cli::render::RenderArgs) -> Result<()> {
    let r = crate::cli::render::run_render(&a)?;
    for w in &r.warnings {
        eprintln!("warning: {w}");
    }
    println!(
        "rendered {} points ({:?} view, {}x{}, {})",
        r.points, r.view, r.size.0, r.size.1, r.backend
    );
    Ok(())
}
