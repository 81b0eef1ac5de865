//! One batch job: its parameters into `params.toml` in its folder, then `wgslam run
//! --params params.toml` once per backend, each in a child process of this executable (so
//! each run's peak memory is its own, and a crash or a lost GPU device fails one job, not
//! the batch) or, with `--concurrent N` above 1, on this thread through
//! [`Runner::in_process`] (see [`super::in_process`]), then the GPU-vs-CPU comparison, then
//! `job.json`.
//!
//! `job.json` is written last, atomically: a job is complete exactly when it holds status
//! `ok` for the same [`JobSpec`]. Starting a job first removes its folder (only the files a
//! job writes; see [`super::folder`]), so what an earlier, interrupted or failed attempt
//! left cannot pass for this one's outputs. The job's lock is held meanwhile.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use serde::{Deserialize, Serialize};

use super::folder::{self, COMPARISON, PARAMS, RECORD};
use super::gpu_vs_cpu::{self, GpuVsCpu};
use super::in_process::{InProcessRun, RunHooks};
use super::interrupt;
use super::manifest::JobSpec;
use crate::tools::run::{read_numbers, RunNumbers};
use crate::{Error, Result};

/// The run outputs a backend's folder must hold for the job to count as complete.
pub const RUN_OUTPUTS: [&str; 4] = ["trajectory.tum", "map.ply", "metrics.json", "frames.json"];
/// The hidden `wgslam run` flag that makes it print `progress DONE TOTAL` lines on stdout.
pub const PROGRESS_FLAG: &str = "--progress-lines";
/// How often the job loop looks at the child and the interrupt flag.
const POLL: Duration = Duration::from_millis(50);
/// Lines of a failed run's log quoted in its error.
const LOG_TAIL_LINES: usize = 6;

/// Whether the job ran to the end.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum JobStatus {
    Ok,
    Failed,
}

/// What `job.json` holds.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct JobRecord {
    /// The job's number in the manifest.
    pub index: usize,
    pub spec: JobSpec,
    pub status: JobStatus,
    /// Why the job failed (the first failing step, with the end of its log).
    pub error: Option<String>,
    /// Per backend that finished.
    pub runs: BTreeMap<String, RunNumbers>,
    /// With both backends finished.
    pub gpu_vs_cpu: Option<GpuVsCpu>,
    /// Wall time of the whole job, seconds.
    pub wall_s: f64,
}

/// What became of a job this time.
#[derive(Debug)]
pub enum Outcome {
    /// Its outputs were complete already; nothing ran.
    Skipped,
    /// It ran (successfully or not): the record written.
    Ran(Box<JobRecord>),
    /// Ctrl-C or SIGTERM: the run in flight was stopped; no record written.
    Interrupted,
}

/// Where a batch's jobs live and how their runs are started.
pub struct Runner {
    /// This executable (`wgslam`), started as `wgslam run ...` per backend.
    pub exe: PathBuf,
    /// The batch folder.
    pub out: PathBuf,
    /// `None`: each backend's run is a child process of [`Runner::exe`]. `Some`: it runs in
    /// this process, on the calling thread, given the `wgslam run` arguments.
    pub in_process: Option<Box<InProcessRun>>,
}

impl Runner {
    /// The folder of job `id`.
    pub fn job_dir(&self, id: &str) -> PathBuf {
        self.out.join("jobs").join(id)
    }

    /// The parameter file of job `id` ([`JobSpec::params_toml`], [`PARAMS`]).
    pub fn params_path(&self, id: &str) -> PathBuf {
        self.job_dir(id).join(PARAMS)
    }

    /// The `wgslam run` arguments of one backend of `spec`, writing into `out`: the
    /// sequence, the job's parameter file, the frames and the backend (every parameter is
    /// in the file).
    pub fn run_args(&self, spec: &JobSpec, backend: &str, out: &Path) -> Vec<String> {
        let mut a = vec![
            "run".to_string(),
            spec.sequence.display().to_string(),
            "--params".into(),
            self.params_path(&spec.id).display().to_string(),
        ];
        if let Some(f) = &spec.frames {
            a.extend(["--frames".into(), f.clone()]);
        }
        a.extend([
            "--backend".into(),
            backend.into(),
            "--out".into(),
            out.display().to_string(),
        ]);
        a
    }

    /// The job's record when its outputs are complete for `spec`; otherwise why not.
    pub fn completed(&self, spec: &JobSpec) -> std::result::Result<JobRecord, String> {
        let dir = self.job_dir(&spec.id);
        let path = dir.join(RECORD);
        let text = crate::io::input::read_kind_string(&path, crate::io::input::InputKind::List)
            .map_err(|_| "not run yet".to_string())?;
        let rec: JobRecord = serde_json::from_str(&text)
            .map_err(|e| format!("{} unreadable ({e})", path.display()))?;
        if rec.spec != *spec {
            return Err("the manifest changed this job".into());
        }
        if rec.status != JobStatus::Ok {
            return Err("failed last time".into());
        }
        for b in &spec.backends {
            for f in RUN_OUTPUTS {
                if !dir.join(b).join(f).is_file() {
                    return Err(format!("{b}/{f} is missing"));
                }
            }
        }
        if spec.backends.len() == 2 && !dir.join(COMPARISON).is_file() {
            return Err(format!("{COMPARISON} is missing"));
        }
        Ok(rec)
    }

    /// Runs job `index` unless complete; `progress(done, total)` follows the frames of the
    /// run in flight.
    pub fn run(
        &self,
        index: usize,
        spec: &JobSpec,
        progress: &dyn Fn(&str, u64, u64),
    ) -> Result<Outcome> {
        let _lock = folder::lock_job(&self.out, &spec.id)?;
        if self.completed(spec).is_ok() {
            return Ok(Outcome::Skipped);
        }
        let dir = self.job_dir(&spec.id);
        folder::remove_job_dir(&dir)?;
        let jobs = self.out.join(folder::JOBS);
        std::fs::create_dir_all(&jobs).map_err(|e| Error::write(&jobs, e))?;
        std::fs::create_dir(&dir).map_err(|e| Error::write(&dir, e))?;
        let params = spec.params_toml();
        crate::io::atomic::write_atomic(&self.params_path(&spec.id), |w| {
            w.write_all(params.as_bytes())
                .map_err(|e| Error::write(self.params_path(&spec.id), e))
        })?;
        let start = Instant::now();
        let mut rec = JobRecord {
            index,
            spec: spec.clone(),
            status: JobStatus::Ok,
            error: None,
            runs: BTreeMap::new(),
            gpu_vs_cpu: None,
            wall_s: 0.0,
        };
        for backend in &spec.backends {
            let out = dir.join(backend);
            let log = dir.join(format!("{backend}.log"));
            let args = self.run_args(spec, backend, &out);
            let progress = |done, total| progress(backend, done, total);
            let end = match create_log(&args, &log)? {
                Err(failed) => failed,
                Ok(file) => match &self.in_process {
                    None => self.run_child(&args, (file, &log), &progress)?,
                    Some(launch) => run_here(launch.as_ref(), &args, file, &progress)?,
                },
            };
            match end {
                ChildEnd::Interrupted => return Ok(Outcome::Interrupted),
                ChildEnd::Failed(why) => {
                    rec.fail(with_log_tail(format!("{backend} run failed: {why}"), &log));
                    break;
                }
                ChildEnd::Exited(status) if status.success() => {
                    match read_numbers(&out.join("metrics.json")) {
                        Ok(n) => {
                            rec.runs.insert(backend.clone(), n);
                        }
                        Err(e) => {
                            rec.fail(format!("{backend} run: {e}"));
                            break;
                        }
                    }
                }
                ChildEnd::Exited(status) => {
                    rec.fail(with_log_tail(
                        format!("{backend} run exited with {status}"),
                        &log,
                    ));
                    break;
                }
            }
        }
        if rec.status == JobStatus::Ok && spec.backends.len() == 2 {
            match gpu_vs_cpu::compare_outputs(&dir.join("cpu"), &dir.join("gpu")) {
                Ok(c) => {
                    crate::tools::run::write_json(&dir.join(COMPARISON), &c)?;
                    rec.gpu_vs_cpu = Some(c);
                }
                Err(e) => rec.fail(format!("GPU-vs-CPU comparison: {e}")),
            }
        }
        if interrupt::requested() {
            return Ok(Outcome::Interrupted);
        }
        rec.wall_s = start.elapsed().as_secs_f64();
        crate::tools::run::write_json(&dir.join(RECORD), &rec)?;
        Ok(Outcome::Ran(Box::new(rec)))
    }

    /// Starts `wgslam ARGS`, stdout and stderr into the log `file` at `log` (progress
    /// lines to `progress`), and waits for it, killing it on an interrupt.
    fn run_child(
        &self,
        args: &[String],
        (file, log): (File, &Path),
        progress: &dyn Fn(u64, u64),
    ) -> Result<ChildEnd> {
        let err_file = file.try_clone().map_err(|e| Error::write(log, e))?;
        let mut cmd = Command::new(&self.exe);
        cmd.args(args)
            .arg(PROGRESS_FLAG)
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(err_file);
        let mut child = match cmd.spawn() {
            Ok(child) => child,
            // This job's run could not start (its arguments, a full process table): its
            // failure, not the batch's.
            Err(e) => {
                return Ok(ChildEnd::Failed(format!(
                    "could not start {}: {e}",
                    self.exe.display()
                )))
            }
        };
        let (tx, rx) = mpsc::channel();
        let stdout = child.stdout.take().expect("stdout was piped");
        let reader = std::thread::spawn(move || copy_output(stdout, file, tx));
        let end = loop {
            for (done, total) in rx.try_iter() {
                progress(done, total);
            }
            if interrupt::requested() {
                stop(&mut child);
                break ChildEnd::Interrupted;
            }
            match child.try_wait() {
                Ok(Some(status)) => break self.classify(status),
                Ok(None) => std::thread::sleep(POLL),
                Err(e) => {
                    stop(&mut child);
                    return Err(Error::io(&self.exe, e));
                }
            }
        };
        let _ = reader.join();
        Ok(end)
    }

    /// A child that died of SIGINT or SIGTERM was interrupted with the batch (a terminal's
    /// Ctrl-C reaches the whole process group), even if the flag is not set yet.
    fn classify(&self, status: ExitStatus) -> ChildEnd {
        #[cfg(unix)]
        {
            use std::os::unix::process::ExitStatusExt;
            const SIGINT: i32 = 2;
            const SIGTERM: i32 = 15;
            if matches!(status.signal(), Some(SIGINT | SIGTERM)) {
                return ChildEnd::Interrupted;
            }
        }
        // The handler may run a moment after the child died of the same Ctrl-C.
        if !status.success() {
            std::thread::sleep(POLL * 2);
            if interrupt::requested() {
                return ChildEnd::Interrupted;
            }
        }
        ChildEnd::Exited(status)
    }
}

impl JobRecord {
    fn fail(&mut self, why: String) {
        self.status = JobStatus::Failed;
        self.error = Some(why);
    }
}

enum ChildEnd {
    Exited(ExitStatus),
    /// An in-process run's error or panic.
    Failed(String),
    Interrupted,
}

/// The run's log, created at `log`; or, when one of `args` holds a NUL byte (no process
/// can be given one, and no path holds one), the run's failure: the job's own input, its
/// sequence path say, so the job fails and the batch goes on. The reason is written into
/// the log too.
fn create_log(args: &[String], log: &Path) -> Result<std::result::Result<File, ChildEnd>> {
    let mut file = File::create(log).map_err(|e| Error::write(log, e))?;
    let Some(a) = args.iter().find(|a| a.contains('\0')) else {
        return Ok(Ok(file));
    };
    let why = format!(
        "its `wgslam run` argument {a:?} holds a NUL byte, which no path or argument can \
         hold; fix the job's `sequence` (or `frames`) in the manifest"
    );
    let _ = writeln!(file, "error: {why}");
    Ok(Err(ChildEnd::Failed(why)))
}

/// Runs `wgslam ARGS` through `launch` on this thread, every line it prints into the log
/// `file` (its error last, as `wgslam` prints it), stopping at the next frame on an
/// interrupt. A panic in the run fails this run only.
fn run_here(
    launch: &InProcessRun,
    args: &[String],
    file: File,
    progress: &dyn Fn(u64, u64),
) -> Result<ChildEnd> {
    let file = std::sync::Mutex::new(file);
    let say = |line: &str| {
        let mut f = file.lock().unwrap_or_else(|p| p.into_inner());
        let _ = writeln!(f, "{line}");
    };
    let stop = interrupt::requested;
    let hooks = RunHooks {
        say: &say,
        progress,
        stop: &stop,
    };
    let ran = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| launch(args, &hooks)));
    let why = match ran {
        // `ExitStatus::default()` is a successful exit.
        Ok(Ok(())) => return Ok(ChildEnd::Exited(ExitStatus::default())),
        Ok(Err(e)) => e.to_string(),
        Err(panic) => format!(
            "panicked: {}",
            panic
                .downcast_ref::<String>()
                .map(String::as_str)
                .or_else(|| panic.downcast_ref::<&str>().copied())
                .unwrap_or("(no message)")
        ),
    };
    if interrupt::requested() {
        return Ok(ChildEnd::Interrupted);
    }
    say(&format!("error: {why}"));
    Ok(ChildEnd::Failed(why))
}

fn stop(child: &mut Child) {
    let _ = child.kill();
    let _ = child.wait();
}

/// Copies the child's stdout into its log, sending `progress DONE TOTAL` lines to `tx`
/// instead.
fn copy_output(stdout: std::process::ChildStdout, mut log: File, tx: mpsc::Sender<(u64, u64)>) {
    for line in BufReader::new(stdout).lines() {
        let Ok(line) = line else { break };
        let mut words = line.split_whitespace();
        if words.next() == Some("progress") {
            if let (Some(Ok(d)), Some(Ok(t))) =
                (words.next().map(str::parse), words.next().map(str::parse))
            {
                let _ = tx.send((d, t));
                continue;
            }
        }
        let _ = writeln!(log, "{line}");
    }
}

/// The last lines of a log, for an error message; for a run that panicked, the panic's
/// place and message instead (a backtrace after it would push them out of the tail).
/// `what`, followed by where the log is and its last lines.
fn with_log_tail(what: String, log: &Path) -> String {
    format!("{what}; end of {}:\n{}", log.display(), log_tail(log))
}

fn log_tail(log: &Path) -> String {
    let text = crate::io::input::read_kind_string(log, crate::io::input::InputKind::Cloud)
        .unwrap_or_default();
    let lines: Vec<&str> = text.lines().filter(|l| !l.trim().is_empty()).collect();
    if let Some(at) = lines.iter().rposition(|l| l.contains("panicked at")) {
        return lines[at..]
            .iter()
            .take_while(|l| !l.starts_with("stack backtrace:"))
            .take(LOG_TAIL_LINES)
            .copied()
            .collect::<Vec<_>>()
            .join("\n");
    }
    let from = lines.len().saturating_sub(LOG_TAIL_LINES);
    lines[from..].join("\n")
}
