//! Running the `wgslam` executable from an integration test: its output, and stdout and
//! stderr as one text for assertion messages.

use std::ffi::OsStr;
use std::process::{Command, Output};

/// Runs `wgslam ARGS` to completion (`&str`s, `String`s or paths).
pub fn wgslam<S: AsRef<OsStr>>(args: &[S]) -> Output {
    wgslam_env(args, &[])
}

/// `o`, asserted to be a run that succeeded (what it said when not).
pub fn ok(o: Output) -> Output {
    assert!(o.status.success(), "{}", text(&o));
    o
}

/// Runs `wgslam ARGS` with `env` set. The job-index variables of the schedulers (which
/// `wgslam batch` reads) are removed unless `env` sets them, so a test run inside a Slurm
/// or Kubernetes task still runs every job.
pub fn wgslam_env<S: AsRef<OsStr>>(args: &[S], env: &[(&str, &str)]) -> Output {
    let mut c = Command::new(env!("CARGO_BIN_EXE_wgslam"));
    c.args(args);
    for k in [
        "SLURM_ARRAY_TASK_ID",
        "SLURM_ARRAY_TASK_COUNT",
        "JOB_COMPLETION_INDEX",
        "WGSLAM_SHARD_COUNT",
    ] {
        c.env_remove(k);
    }
    for (k, v) in env {
        c.env(k, v);
    }
    c.output().expect("run wgslam")
}

/// stdout then stderr, lossily decoded.
pub fn text(o: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}
