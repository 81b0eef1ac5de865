//! `wgslam bench`: both backends timed on the same frames, each in a child process of this
//! executable (`bench-one`, or `run --revisit` for `--revisit`) that reads this
//! invocation's parameters from a temporary parameter file.

use std::path::PathBuf;

use clap::Args;

use super::pipeline_args::{frame_range, PipelineArgs, Setup};
use crate::slam::any_backend::{self, BackendChoice};
use crate::slam::params::{PoseSource, ValidParams};
use crate::tools::{bench, long_run, run, streams, thread_scaling};
use crate::{Error, Result};

#[derive(Debug, Args)]
pub struct BenchArgs {
    /// Inclusive frame range "A..B" (default: all frames from the first with ground truth).
    #[arg(long)]
    pub frames: Option<String>,
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
    /// The GPU streams benchmark instead: the frames as one stream, then as N streams at
    /// once in this process on one device and queue (as `batch --concurrent N` runs jobs);
    /// prints waits, submissions and the device's `queue.submit` calls (fewer where the
    /// streams combine theirs) per stream-frame, ICP iterations per frame and wall time
    /// against N runs one at a time (needs a GPU; ignores --backends).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..))]
    pub streams: Option<u32>,
    /// The CPU reference's thread scaling instead: the frames on one thread and on every
    /// core (or `--threads N`), alternating frame by frame in one process; prints the
    /// per-frame speed-up and whether both give the same bits (ignores --backends).
    #[arg(long)]
    pub thread_scaling: bool,
    /// Write the results as JSON here.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// bench-one only: time whole frames only (no per-stage pass, no kernels).
    #[arg(long, hide = true)]
    pub frames_only: bool,
    #[command(flatten)]
    pub decode: super::run::DecodeArgs,
    // The sequence, a parameter file and the parameters (last, so their help heading
    // follows this command's own options).
    #[command(flatten)]
    pub pipeline: PipelineArgs,
}

/// Runs `wgslam bench`.
pub fn execute(a: BenchArgs) -> Result<()> {
    let setup = with_backends_downsample(a.pipeline.resolve()?, &a);
    // Bad parameters fail here, before any child starts (each child validates its own).
    let params = setup.slam_params(PoseSource::Track)?;
    setup.set.sequence_options(&params)?;
    if let Some(total) = a.revisit {
        return bench_revisit(&a, &setup, &params, total);
    }
    if let Some(streams) = a.streams {
        let seq = setup.open_sequence(&params)?;
        let (first, last) = frame_range(&seq, &a.frames, usize::MAX)?;
        let ctx = crate::gpu::GpuContext::new()?;
        eprintln!("{first}..{last} as 1 GPU stream, then as {streams} at once ...");
        let r = streams::bench_streams(&ctx, &seq, (first, last), &params, streams as usize)?;
        streams::print_streams(&r);
        if let Some(path) = &a.json {
            run::write_json(path, &serde_json::json!({ "streams": r }))?;
        }
        return Ok(());
    }
    if a.thread_scaling {
        let seq = setup.open_sequence(&params)?;
        let range = frame_range(&seq, &a.frames, usize::MAX)?;
        let many = any_backend::cpu_threads(1)?;
        let n = many.count();
        eprintln!(
            "{}..{} on 1 and {n} CPU threads, frame by frame ...",
            range.0, range.1
        );
        let r = thread_scaling::bench_thread_scaling(many, &seq, range, &params)?;
        println!("{}", r.text());
        if let Some(path) = &a.json {
            run::write_json(path, &serde_json::json!({ "thread_scaling": r }))?;
        }
        return Ok(());
    }
    let params_file = setup.child_params("bench")?;
    let mut bench_one_args = with_frames(setup.handoff_args(&params_file), &a.frames);
    bench_one_args.extend(a.decode.child_args());
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
                &bench_one_args,
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
        let seq = setup.open_sequence(&params)?;
        let (first, last) = frame_range(&seq, &a.frames, usize::MAX)?;
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

/// `setup` with the downsampling its backends run when it sets none (one for all of
/// them, handed to every child: `crate::slam::params::resolution`): the full frames when
/// only the GPU is timed (`--backends gpu`, `--streams`), every second pixel when the CPU
/// reference is (the default `--backends cpu,gpu`, `--interleaved`).
fn with_backends_downsample(mut setup: Setup, a: &BenchArgs) -> Setup {
    if setup.set.sets_downsample() {
        return setup;
    }
    let names: Vec<&str> = match (a.interleaved, a.streams.is_some()) {
        _ if a.thread_scaling => vec!["cpu"],
        (true, _) => vec!["cpu", "gpu"],
        (false, true) => vec!["gpu"],
        (false, false) => a
            .backends
            .iter()
            .map(|b| match b {
                BackendChoice::Cpu => "cpu",
                BackendChoice::Gpu | BackendChoice::Auto => "gpu",
            })
            .collect(),
    };
    let (downsample, from) = crate::slam::params::resolution::default_downsample(&names);
    if let Some(why) = from.describe() {
        eprintln!("bench: --downsample {downsample} ({why})");
    }
    setup.set.downsample = Some(downsample);
    setup
}

/// A child's arguments with `--frames` when this invocation has it; without it the
/// child's default range is the one this process resolves.
fn with_frames(mut args: Vec<String>, frames: &Option<String>) -> Vec<String> {
    if let Some(f) = frames {
        args.extend(["--frames".into(), f.clone()]);
    }
    args
}

/// `bench --revisit N`: each backend's long run in a child `wgslam run`, then the table.
fn bench_revisit(a: &BenchArgs, setup: &Setup, params: &ValidParams, total: usize) -> Result<()> {
    let seq = setup.open_sequence(params)?;
    let (first, last) = frame_range(&seq, &a.frames, usize::MAX)?;
    let gt = seq.revisiting(first, last, total)?.ground_truth();
    let params_file = setup.child_params("bench")?;
    let mut runs = Vec::new();
    for b in &a.backends {
        let name = format!("{b:?}").to_lowercase();
        eprintln!("{name}: {total} frames over {first}..{last} forwards and backwards ...");
        let mut args = vec!["run".to_string()];
        args.extend(with_frames(setup.handoff_args(&params_file), &a.frames));
        args.extend(a.decode.child_args());
        args.extend([
            "--revisit".into(),
            total.to_string(),
            "--backend".into(),
            name.clone(),
        ]);
        runs.push(long_run::run_in_child(&args, &name, last - first, &gt)?);
    }
    long_run::print(&runs);
    if let Some(path) = &a.json {
        run::write_json(path, &serde_json::json!({ "revisit": runs }))?;
    }
    Ok(())
}

/// Runs `wgslam bench-one` (a child of `bench`): one backend, its result as JSON on stdout.
pub fn execute_one(a: BenchArgs) -> Result<()> {
    let setup = a.pipeline.resolve()?;
    let params = setup.slam_params(PoseSource::Track)?;
    let seq = setup.open_sequence(&params)?;
    let (first, last) = frame_range(&seq, &a.frames, usize::MAX)?;
    let choice = *a.backends.first().unwrap_or(&BackendChoice::Cpu);
    let make = || any_backend::open(choice);
    let mut r = if a.frames_only {
        bench::bench_frames(make, &seq, (first, last), &params, a.decode.decode())?
    } else {
        bench::bench_backend(make, &seq, first, last, &params, a.decode.decode())?
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
