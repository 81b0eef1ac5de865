//! Command-line interface: argument parsing and printing only; no algorithm code here.
//!
//! | module | what |
//! |---|---|
//! | `pipeline_args` | the options `run`, `icp`, `compare` and `bench` share: the sequence, `--params FILE.toml`, every parameter override (the key table of parameter files and manifests) |
//! | `params_file` | reading and writing parameter files: the one parser of `--params` files and manifest overrides |
//! | `run`, `icp`, `compare`, `bench` | the dense pipeline's commands |
//! | `eval` | ATE / RPE of two trajectories |
//! | [`render`] | `render`: a map PLY to a PNG |
//! | [`mesh`] | `mesh`: a map PLY to a triangle mesh (PLY or OBJ) |
//! | [`scan`] | point-cloud registration, odometry and its benchmark |
//! | `batch` | `batch`: manifests of many runs |
//! | [`embed`] | the entry point `main` from argument strings, and what the Python package resolves as `run` does |

pub(crate) mod batch;
pub(crate) mod bench;
pub(crate) mod compare;
pub mod embed;
pub(crate) mod eval;
pub(crate) mod icp;
pub mod mesh;
pub(crate) mod params_file;
pub(crate) mod pipeline_args;
pub mod render;
pub(crate) mod run;
pub mod scan;

use std::path::{Path, PathBuf};

use clap::{Parser, Subcommand};

use crate::gpu::context::{
    GpuFeatures, GpuLimits, GpuSubmissions, FEATURES_ENV, LIMITS_ENV, SUBMISSIONS_ENV,
};
use crate::slam::any_backend::THREADS_ENV;
use crate::Result;

/// The bundled sequence used when no dataset is given (relative to the crate root).
pub const BUNDLED_DATASET: &str = "assets/icl_living_room_kt2";

/// Dense RGB-D SLAM (point-based fusion) and point-to-point ICP on wgpu, with a CPU reference.
#[derive(Debug, Parser)]
#[command(name = "wgslam", version, about)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
    /// GPU kernels: `auto` takes the 64-bit key kernels where the adapter has 64-bit
    /// atomics, `portable` the two-pass 32-bit kernels everywhere (same results). Sets
    /// WGSLAM_GPU_FEATURES for this command and the processes it starts.
    #[arg(long, global = true, value_enum, value_name = "auto|portable")]
    pub gpu_features: Option<GpuFeatures>,
    /// GPU limits: `adapter` asks for the adapter's own limits, `webgpu` for exactly
    /// WebGPU's defaults and no optional feature (as in a browser tab). Sets
    /// WGSLAM_GPU_LIMITS for this command and the processes it starts.
    #[arg(long, global = true, value_enum, value_name = "adapter|webgpu")]
    pub gpu_limits: Option<GpuLimits>,
    /// How GPU streams sharing one device (`batch --concurrent`, `bench --streams`) submit:
    /// `own` gives each step's work to the device at once, `combined` holds a stream's
    /// work while the device is busy and gives every stream's held work to the device in
    /// one submission (same results). Sets WGSLAM_GPU_SUBMISSIONS for this command and the
    /// processes it starts.
    #[arg(long, global = true, value_enum, value_name = "own|combined")]
    pub gpu_submissions: Option<GpuSubmissions>,
    /// Threads of the CPU reference (--backend cpu, compare, bench), default one per core;
    /// a batch running jobs at once shares them between its jobs. Outputs are the same for
    /// any number. Sets WGSLAM_THREADS for this command and the processes it starts.
    #[arg(long, global = true, value_name = "N")]
    pub threads: Option<std::num::NonZeroUsize>,
}

#[derive(Debug, Subcommand)]
pub enum Command {
    /// Run dense SLAM over a sequence; write trajectory.tum, map.ply, metrics.json.
    Run(run::RunArgs),
    /// Two-frame ICP: align frame --target to frame --source, print every iteration.
    Icp(icp::IcpArgs),
    /// ATE and RPE of an estimated TUM trajectory against a ground-truth TUM trajectory.
    Eval(eval::EvalArgs),
    /// Run the CPU reference and the GPU on the same frames and report their differences
    /// per stage and frame; exits non-zero beyond the documented tolerances.
    Compare(compare::CompareArgs),
    /// Time both backends on the same frames: per stage, per frame, memory, readbacks.
    Bench(bench::BenchArgs),
    /// (internal) Benchmark one backend and print its result as JSON; used by `bench`.
    #[command(hide = true)]
    BenchOne(bench::BenchArgs),
    /// Point-to-point ICP between two point clouds (PCD, PLY, xyz text, KITTI .bin).
    Register(scan::RegisterArgs),
    /// Scan odometry: register each consecutive pair of a folder of scans and chain them.
    Odometry(scan::OdometryArgs),
    /// Time scan registration and nearest neighbours: CPU KD-tree vs GPU grid / brute force.
    BenchScan(scan::BenchScanArgs),
    /// Render a map PLY headlessly to a PNG (colour, normals, weight or depth view).
    Render(render::RenderArgs),
    /// Mesh a map PLY: a TSDF of its surfels and surface nets, written as PLY with vertex
    /// colours (or OBJ), with its distance to the map's points.
    Mesh(mesh::MeshArgs),
    /// Run a TOML manifest of jobs (sequences x settings x backends), resumable and
    /// shardable (`--shard I/N`, Slurm / Kubernetes array indices); `batch collect DIR`
    /// writes summary.csv, summary.json and report.html; `batch diff A B` compares two.
    Batch(batch::BatchArgs),
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

/// Sets `var` to the option's command-line name when it was given.
fn set_env<T: clap::ValueEnum>(var: &str, value: Option<T>) {
    if let Some(name) = value.as_ref().and_then(|v| v.to_possible_value()) {
        // Before any thread of this process starts (execute is called first thing).
        std::env::set_var(var, name.get_name());
    }
}

/// Runs the parsed command.
pub fn execute(cli: Cli) -> Result<()> {
    // Through the environment, so that child processes (bench-one, batch jobs) and every
    // GPU context of this one (GpuContext::new reads it) make the same device.
    set_env(FEATURES_ENV, cli.gpu_features);
    set_env(LIMITS_ENV, cli.gpu_limits);
    set_env(SUBMISSIONS_ENV, cli.gpu_submissions);
    if let Some(n) = cli.threads {
        // Before any thread of this process starts, as above.
        std::env::set_var(THREADS_ENV, n.to_string());
    }
    match cli.command {
        Command::Run(a) => run::execute(a),
        Command::Icp(a) => icp::execute(a),
        Command::Eval(a) => eval::execute(a),
        Command::Compare(a) => compare::execute(a),
        Command::Bench(a) => bench::execute(a),
        Command::BenchOne(a) => bench::execute_one(a),
        Command::Register(a) => scan::run_register(&a).map(|_| ()),
        Command::Odometry(a) => scan::run_odometry(&a).map(|_| ()),
        Command::Render(a) => render::execute(a),
        Command::Mesh(a) => mesh::execute(a),
        Command::BenchScan(a) => scan::run_bench_scan(&a).map(|_| ()),
        Command::Batch(a) => batch::execute(a),
    }
}

#[cfg(test)]
mod help_tests {
    use clap::CommandFactory;

    use super::Cli;

    /// Every command's and subcommand's `--help` (long form, possible values included) is
    /// plain text: rustdoc's intra-doc links (`` [`Name`] ``) mean nothing on a terminal,
    /// so doc comments that clap shows must state things in words.
    #[test]
    fn no_help_text_shows_a_rustdoc_link() {
        fn walk(cmd: &mut clap::Command, path: &str, found: &mut Vec<String>) {
            let help = cmd.render_long_help().to_string();
            for line in help.lines().filter(|l| l.contains("[`")) {
                found.push(format!("{path}: {}", line.trim()));
            }
            for sub in cmd.get_subcommands_mut() {
                let name = format!("{path} {}", sub.get_name());
                walk(sub, &name, found);
            }
        }
        let mut cmd = Cli::command();
        cmd.build();
        let mut found = Vec::new();
        walk(&mut cmd, "wgslam", &mut found);
        assert!(
            found.is_empty(),
            "rustdoc links in --help:\n{}",
            found.join("\n")
        );
    }
}
