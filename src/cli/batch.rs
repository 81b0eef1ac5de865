//! `wgslam batch`: argument parsing and printing for the batch layer ([`crate::batch`]).

use std::path::{Path, PathBuf};
use std::sync::{Mutex, OnceLock};

use clap::{Args, Parser, Subcommand};
use indicatif::{MultiProgress, ProgressBar, ProgressStyle};

use crate::batch::in_process::{self, Embedded, InProcessRun, RunHooks};
use crate::batch::job::{Outcome, Runner};
use crate::batch::manifest::Manifest;
use crate::batch::select::{self, Selection};
use crate::batch::summary::{self, Summary};
use crate::batch::{folder, interrupt, report};
use crate::cli::pipeline_args::ParamOverrides;
use crate::gpu::backend::GpuBackend;
use crate::gpu::context::GpuContext;
use crate::slam::any_backend::{self, AnyBackend, BackendChoice};
use crate::slam::params::PoseSource;
use crate::{Error, Result};

/// `wgslam batch MANIFEST` runs a manifest's jobs; `list`, `collect` and `diff` inspect
/// manifests and batch folders.
#[derive(Debug, Args)]
#[command(args_conflicts_with_subcommands = true, subcommand_negates_reqs = true)]
pub struct BatchArgs {
    #[command(subcommand)]
    pub action: Option<BatchAction>,
    #[command(flatten)]
    pub run: BatchRunArgs,
}

#[derive(Debug, Subcommand)]
pub enum BatchAction {
    /// Print the manifest's jobs: index and id, the parameter file each writes, and the
    /// `wgslam run` commands.
    List { manifest: PathBuf },
    /// Write DIR/summary.csv, DIR/summary.json and DIR/report.html from the jobs that have
    /// finished (the others listed as pending).
    Collect { dir: PathBuf },
    /// Compare two batches' numbers job by job (status, frames, map size, lost frames, ATE,
    /// RPE, GPU-vs-CPU differences; not times or memory); exits non-zero if any differ.
    /// A and B: batch folders or summary.json files.
    Diff { a: PathBuf, b: PathBuf },
}

#[derive(Debug, Args)]
pub struct BatchRunArgs {
    /// The manifest (TOML): jobs and grids of sequence, frames, downsample, profile,
    /// backend (cpu, gpu, both) and parameter overrides, the keys of a `--params` file
    /// (docs/batch-and-clusters.md; docs/params-file.md).
    #[arg(required = true)]
    pub manifest: Option<PathBuf>,
    /// Batch folder (default: the manifest's `output`, relative to the manifest).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Run only the jobs whose index is I modulo N ("I/N", 0-based).
    #[arg(long, value_name = "I/N")]
    pub shard: Option<String>,
    /// Run only job I (as a scheduler array task would; default from SLURM_ARRAY_TASK_ID or
    /// JOB_COMPLETION_INDEX, with SLURM_ARRAY_TASK_COUNT or WGSLAM_SHARD_COUNT as the
    /// number of shards when set).
    #[arg(long, value_name = "I")]
    pub index: Option<usize>,
    /// Print the jobs this invocation would run (and skip), and run nothing.
    #[arg(long)]
    pub dry_run: bool,
    /// Run up to N jobs at once, in this process on one shared GPU device (default: the
    /// manifest's `concurrent`, else 1: one job at a time, each run in a child process).
    #[arg(long, value_name = "N")]
    pub concurrent: Option<usize>,
}

/// Runs `wgslam batch ...`.
pub fn execute(a: BatchArgs) -> Result<()> {
    match a.action {
        Some(BatchAction::List { manifest }) => list(&manifest),
        Some(BatchAction::Collect { dir }) => collect(&dir).map(|_| ()),
        Some(BatchAction::Diff { a, b }) => diff(&a, &b),
        None => run(a.run),
    }
}

fn runner(out: PathBuf) -> Result<Runner> {
    Ok(Runner {
        exe: std::env::current_exe().map_err(|e| Error::io("the wgslam executable", e))?,
        out,
        in_process: None,
    })
}

/// `wgslam run`'s arguments on their own, as a batch job's run is given them.
#[derive(Debug, Parser)]
#[command(name = "wgslam run")]
struct RunOnly {
    #[command(flatten)]
    run: super::run::RunArgs,
}

/// Runs a job's backend in this process: `args` parsed as `wgslam run`'s, the CPU backend
/// or a GPU backend on its own share of one device, opened at the first GPU run and shared
/// by all ([`GpuContext::share`]; each pipeline built once: `GpuContext::kernels_cached`).
/// The `concurrent` jobs share the cores for decoding: each decodes ahead on its share (at
/// least one thread) unless its own `--decode-threads` says otherwise; a CPU job's twins
/// run on its share of the `--threads` budget.
fn in_process_runs(concurrent: usize) -> Box<InProcessRun> {
    let device: OnceLock<std::result::Result<GpuContext, String>> = OnceLock::new();
    Box::new(move |args: &[String], hooks: &RunHooks| {
        let mut a = RunOnly::try_parse_from(
            std::iter::once("wgslam run").chain(args.iter().skip(1).map(String::as_str)),
        )
        .map_err(|e| Error::Argument(e.to_string()))?
        .run;
        // A job's own --decode-threads wins over its share.
        let cores = crate::tools::run::Decode::ahead_on_every_core().threads();
        a.decode
            .decode_threads
            .get_or_insert((cores / concurrent).max(1));
        let gpu = || -> Result<AnyBackend> {
            let shared = device
                .get_or_init(|| GpuContext::new().map_err(|e| e.to_string()))
                .as_ref()
                .map_err(|e| Error::Gpu(format!("opening the batch's GPU: {e}")))?;
            Ok(Box::new(GpuBackend::new(shared.share())?))
        };
        let backend: AnyBackend = match a.backend {
            BackendChoice::Cpu => Box::new(any_backend::cpu_backend(concurrent)?),
            BackendChoice::Gpu | BackendChoice::Auto => gpu()?,
        };
        let hooks = RunHooks {
            say: hooks.say,
            progress: hooks.progress,
            stop: hooks.stop,
        };
        super::run::execute_in(a, Some(Embedded { backend, hooks }))
    })
}

/// Reads a manifest and checks every job's parameter file parses and its parameters are
/// in range (so a typo in an override fails before the first job, naming the job).
fn read_checked(path: &Path) -> Result<Manifest> {
    let m = Manifest::read(path)?;
    let all: Vec<usize> = (0..m.jobs.len()).collect();
    if let Some(e) = check_jobs(path, &m, &all).into_iter().next() {
        return Err(e);
    }
    Ok(m)
}

/// Checks the parameter files of jobs `picked` of `m` (an array task checks its own jobs
/// only: `batch list`, which sizes the array, and a run of all jobs check them all); the
/// error of each job whose parameters are wrong, naming it.
fn check_jobs(path: &Path, m: &Manifest, picked: &[usize]) -> Vec<Error> {
    let mut bad_jobs = Vec::new();
    for job in picked.iter().map(|&i| &m.jobs[i]) {
        let bad = |why: String| {
            Error::format(
                path,
                format!("job {:?}: its `wgslam run` parameters: {why}", job.id),
            )
        };
        let checked = ParamOverrides::from_toml(&job.params_toml())
            .map_err(bad)
            .and_then(|set| {
                set.slam_params(PoseSource::Track)
                    .and_then(|params| set.sequence_options(&params))
                    .map_err(|e| bad(e.to_string()))
            });
        bad_jobs.extend(checked.err());
    }
    bad_jobs
}

/// A batch whose every job has wrong parameters (a typo in the defaults or a grid axis)
/// fails before the first job; when only some do, the others run and those fail on their
/// own (their run refuses the same parameters, recorded in their `job.json`): one job's
/// input never stops the rest.
fn refuse_or_note(path: &Path, m: &Manifest, picked: &[usize]) -> Result<()> {
    let bad = check_jobs(path, m, picked);
    if !picked.is_empty() && bad.len() == picked.len() {
        return Err(bad.into_iter().next().expect("one error per picked job"));
    }
    for e in bad {
        eprintln!("note: {e}; this job will fail, the others run");
    }
    Ok(())
}

fn list(path: &Path) -> Result<()> {
    let m = read_checked(path)?;
    let r = runner(m.output.clone().unwrap_or_else(|| PathBuf::from("OUT")))?;
    for (i, job) in m.jobs.iter().enumerate() {
        // A folder, or a recording file (ROS bag, MCAP).
        let missing = if job.sequence.exists() {
            ""
        } else {
            "  (sequence not found here)"
        };
        println!("{i:4}  {}{missing}", job.id);
        let params: Vec<String> = job
            .params_toml()
            .lines()
            .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
            .map(String::from)
            .collect();
        println!(
            "        {}: {}",
            r.params_path(&job.id).display(),
            params.join(", ")
        );
        for b in &job.backends {
            let args = r.run_args(job, b, &r.job_dir(&job.id).join(b));
            println!("        wgslam {}", args.join(" "));
        }
    }
    println!(
        "{} jobs (array indices 0..={}; Slurm: --array=0-{})",
        m.jobs.len(),
        m.jobs.len() - 1,
        m.jobs.len() - 1
    );
    Ok(())
}

fn run(a: BatchRunArgs) -> Result<()> {
    let path = a
        .manifest
        .as_deref()
        .ok_or_else(|| Error::Argument("no manifest given".into()))?;
    let m = Manifest::read(path)?;
    let out = a.out.clone().or_else(|| m.output.clone()).ok_or_else(|| {
        Error::Argument("no batch folder: set `output` in the manifest or pass --out DIR".into())
    })?;
    let chosen = select::choose(a.shard.as_deref(), a.index, m.jobs.len(), |v| {
        std::env::var(v).ok()
    })?;
    chosen.selection.check(m.jobs.len())?;
    let picked: Vec<usize> = (0..m.jobs.len())
        .filter(|&i| chosen.selection.picks(i))
        .collect();
    refuse_or_note(path, &m, &picked)?;
    let concurrent = a.concurrent.or(m.concurrent).unwrap_or(1);
    if concurrent == 0 {
        return Err(Error::Argument(
            "--concurrent (or the manifest's `concurrent`) must be at least 1".into(),
        ));
    }
    eprintln!(
        "batch {}: {} of {} jobs ({}) into {}{}",
        path.display(),
        picked.len(),
        m.jobs.len(),
        match chosen.selection {
            Selection::All => "all".to_string(),
            Selection::Shard { index, count } =>
                format!("index {index} of {count}, from {}", chosen.source),
        },
        out.display(),
        match concurrent {
            1 => String::new(),
            n => format!(", up to {n} at once in this process"),
        }
    );
    let mut r = runner(out.clone())?;
    folder::claim(&out, path, !a.dry_run)?;
    if a.dry_run {
        for &i in &picked {
            let job = &m.jobs[i];
            let state = match r.completed(job) {
                Ok(_) => "complete, would skip".to_string(),
                Err(why) => format!("would run ({why})"),
            };
            println!("{i:4}  {}: {state}", job.id);
        }
        return Ok(());
    }
    if concurrent > 1 {
        r.in_process = Some(in_process_runs(concurrent));
    }
    summary::write_plan(&out, &m)?;
    interrupt::install();
    let ended = run_jobs(&r, &m, &picked, concurrent);
    let Ended {
        mut failed,
        interrupted,
        error,
    } = ended;
    // In manifest order, whatever order concurrent jobs ended in.
    failed.sort_by_key(|id| m.jobs.iter().position(|j| &j.id == id));
    if let Some(e) = error {
        return Err(e);
    }
    if !interrupted.is_empty() {
        return Err(Error::Interrupted(format!(
            "job {} was stopped and left unfinished (no job.json); finished jobs keep their \
             records; run the same command again to resume",
            interrupted.join(", ")
        )));
    }
    summarise(
        &out,
        chosen.selection == Selection::All,
        &failed,
        picked.len(),
    )
}

/// After the jobs of this invocation (`picked` of them, `failed` by id): the summary and
/// report when `all` jobs were this process's, notes on lost and unfinished jobs, and the
/// error naming the failed ones.
fn summarise(out: &Path, all: bool, failed: &[String], picked: usize) -> Result<()> {
    // One array task of many writes no summary: the others are still running, and a
    // thousand tasks each rewriting the report is waste; `batch collect` merges them.
    let (pending, lost) = if all {
        let s = collect(out)?;
        (s.pending, s.lost)
    } else {
        eprintln!(
            "this task's jobs are done; when all tasks are, `wgslam batch collect {}` writes \
             the summary and the report",
            out.display()
        );
        (0, 0)
    };
    if lost > 0 {
        eprintln!(
            "note: {lost} job(s) ran to the end but their tracking ended lost (status `lost`; \
             their health in summary.csv says why)"
        );
    }
    if !failed.is_empty() {
        return Err(Error::Batch(format!(
            "{} of {} jobs failed: {} (their errors are in summary.csv and their job.json)",
            failed.len(),
            picked,
            failed.join(", ")
        )));
    }
    if pending > 0 {
        eprintln!("note: {pending} jobs of the manifest are not finished yet");
    }
    Ok(())
}

/// How the jobs of one `batch` invocation ended, beyond their records.
#[derive(Default)]
struct Ended {
    /// Ids of the jobs that failed.
    failed: Vec<String>,
    /// Ids of the jobs an interrupt stopped.
    interrupted: Vec<String>,
    /// An error of the batch itself (a lock, a folder): the first one; it stops the queue.
    error: Option<Error>,
}

/// Runs jobs `picked` of `m`, up to `concurrent` at once ([`in_process::run_queue`]), with
/// a bar for the batch and one per job in flight on a terminal, and a line per job end
/// (prefixed with its number and id) either way.
fn run_jobs(r: &Runner, m: &Manifest, picked: &[usize], concurrent: usize) -> Ended {
    let multi = MultiProgress::new();
    let tty = std::io::IsTerminal::is_terminal(&std::io::stderr());
    let batch_bar = multi.add(ProgressBar::new(picked.len() as u64));
    batch_bar.set_style(
        ProgressStyle::with_template("{elapsed_precise} [{bar:30}] {pos}/{len} jobs {msg}")
            .expect("static template")
            .progress_chars("=> "),
    );
    let job_bars: Vec<ProgressBar> = (0..concurrent.clamp(1, picked.len().max(1)))
        .map(|_| {
            let bar = multi.add(ProgressBar::new(0));
            bar.set_style(
                ProgressStyle::with_template("  {msg} [{bar:30}] {pos}/{len} frames")
                    .expect("static template")
                    .progress_chars("=> "),
            );
            bar
        })
        .collect();
    let say = |line: String| {
        if tty {
            let _ = multi.println(line);
        } else {
            eprintln!("{line}");
        }
    };
    let ended = Mutex::new(Ended::default());
    in_process::run_queue(picked, concurrent, |slot, k, &i| {
        let job = &m.jobs[i];
        let job_bar = &job_bars[slot];
        if concurrent == 1 {
            batch_bar.set_message(job.id.clone());
        }
        job_bar.reset();
        job_bar.set_length(0);
        job_bar.set_message(job.id.clone());
        let progress = |backend: &str, done: u64, total: u64| {
            job_bar.set_message(format!("{} {backend}", job.id));
            job_bar.set_length(total);
            job_bar.set_position(done);
        };
        let tag = format!("[{}/{}] job {i} {}", k + 1, picked.len(), job.id);
        if !tty {
            eprintln!("{tag}: starting");
        }
        let outcome = r.run(i, job, &progress);
        let mut ended = ended.lock().unwrap_or_else(|p| p.into_inner());
        match outcome {
            Ok(Outcome::Skipped) => say(format!("{tag}: outputs complete, skipped")),
            Ok(Outcome::Ran(rec)) => match &rec.error {
                None => say(format!("{tag}: ok in {:.1} s", rec.wall_s)),
                Some(e) => {
                    say(format!("{tag}: FAILED: {e}"));
                    ended.failed.push(job.id.clone());
                }
            },
            Ok(Outcome::Interrupted) => {
                ended.interrupted.push(job.id.clone());
                return false;
            }
            Err(e) => {
                ended.error.get_or_insert(e);
                return false;
            }
        }
        batch_bar.inc(1);
        true
    });
    for bar in &job_bars {
        bar.finish_and_clear();
    }
    batch_bar.finish_and_clear();
    ended.into_inner().unwrap_or_else(|p| p.into_inner())
}

/// Collects, writes the summaries and the report, and prints the table.
fn collect(dir: &Path) -> Result<Summary> {
    let s = summary::collect(dir)?;
    summary::write(dir, &s)?;
    report::write(dir, &s)?;
    let w = s.rows.iter().map(|r| r.id.len()).max().unwrap_or(0).max(3);
    // An ATE is over the frames with a pose: each is followed by how many had none.
    println!(
        "{:>4}  {:<w$} {:>8} {:>20} {:>20} {:>9} {:>9}",
        "#",
        "job",
        "status",
        "cpu ATE mm (no pose)",
        "gpu ATE mm (no pose)",
        "cpu ms/f",
        "gpu ms/f"
    );
    for r in &s.rows {
        let n = |b: &str| r.record.as_ref().and_then(|rec| rec.runs.get(b));
        let f =
            |x: Option<f64>, d: usize| x.map(|v| format!("{v:.d$}")).unwrap_or_else(|| "-".into());
        let ate = |b: &str| match n(b).map(|n| (n.ate_rmse_mm, n.frames_without_pose)) {
            Some((Some(ate), Some(without))) => format!("{ate:.3} ({without})"),
            Some((Some(ate), None)) => format!("{ate:.3} (?)"),
            _ => "-".into(),
        };
        println!(
            "{:>4}  {:<w$} {:>8} {:>20} {:>20} {:>9} {:>9}",
            r.index,
            r.id,
            r.status,
            ate("cpu"),
            ate("gpu"),
            f(n("cpu").map(|n| n.time_per_frame_median_ms), 1),
            f(n("gpu").map(|n| n.time_per_frame_median_ms), 1),
        );
    }
    println!(
        "{} jobs: {} ok, {} lost, {} failed, {} pending; wrote {}/{{summary.csv, summary.json, \
         report.html}}",
        s.jobs,
        s.ok,
        s.lost,
        s.failed,
        s.pending,
        dir.display()
    );
    Ok(s)
}

fn diff(a: &Path, b: &Path) -> Result<()> {
    let (sa, sb) = (summary::load(a)?, summary::load(b)?);
    let d = summary::diff(&sa, &sb);
    if d.is_empty() {
        println!(
            "equal: {} jobs, the same status and numbers in {} and {}",
            sa.rows.len(),
            a.display(),
            b.display()
        );
        return Ok(());
    }
    for line in &d {
        println!("differs: {line}");
    }
    Err(Error::Batch(format!(
        "{} jobs differ between {} and {}",
        d.len(),
        a.display(),
        b.display()
    )))
}
