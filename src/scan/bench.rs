//! Timing of scan registration and of nearest-neighbour queries, for the CLI's
//! `bench-scan`. Not a statistics framework: it reports the median and minimum of a few
//! repeats, and it knows nothing about which backend it times (callers pass closures or a
//! [`NearestNeighbours`]).

use web_time::Instant;

use glam::DMat4;

use super::icp::{register, IcpParams, IcpResult};
use super::nn::NearestNeighbours;
use crate::{Error, Result};

/// Timings of [`bench_register`] / [`bench_register_with`], seconds.
#[derive(Debug, Clone, serde::Serialize)]
pub struct RegisterTiming {
    /// Every repeat, in run order (seconds).
    pub seconds: Vec<f64>,
    pub median_seconds: f64,
    pub min_seconds: f64,
    /// Iterations of the last repeat (all repeats are identical: same seed).
    pub iterations: usize,
}

impl RegisterTiming {
    /// Median seconds per ICP iteration (the comparable figure when iterations differ).
    pub fn seconds_per_iteration(&self) -> f64 {
        self.median_seconds / self.iterations.max(1) as f64
    }
}

/// Timings of [`bench_nearest`], seconds.
#[derive(Debug, Clone, serde::Serialize)]
pub struct NearestTiming {
    /// Queries per run.
    pub queries: usize,
    /// Every repeat, in run order (seconds).
    pub seconds: Vec<f64>,
    pub median_seconds: f64,
    pub min_seconds: f64,
}

/// Runs `f` at least once and at most `max_runs` times, stopping early once the runs so
/// far took `budget_seconds` in total (pass `f64::INFINITY` for exactly `max_runs`).
/// Returns each run's wall time (seconds) and the last run's output.
fn timed_runs<T>(
    max_runs: usize,
    budget_seconds: f64,
    mut f: impl FnMut() -> Result<T>,
) -> Result<(Vec<f64>, T)> {
    if max_runs == 0 {
        return Err(Error::Argument("bench needs at least one repeat".into()));
    }
    let mut seconds = Vec::with_capacity(max_runs);
    let mut last = None;
    while seconds.len() < max_runs
        && (last.is_none() || seconds.iter().sum::<f64>() < budget_seconds)
    {
        let start = Instant::now();
        let r = f()?;
        seconds.push(start.elapsed().as_secs_f64());
        last = Some(r);
    }
    Ok((seconds, last.expect("at least one run")))
}

/// `(median, min)` of a non-empty list of seconds (the one median: [`crate::stats::median`]).
fn median_min(seconds: &[f64]) -> (f64, f64) {
    let min = seconds.iter().copied().fold(f64::INFINITY, f64::min);
    (crate::stats::median(seconds), min)
}

/// Registers `source` onto `target` (metres) on the CPU `repeats` times (>= 1) from
/// `init_source_to_target` and times each run, KD-tree build included. Returns the timings
/// and the last result.
pub fn bench_register(
    source: &[[f32; 3]],
    target: &[[f32; 3]],
    init_source_to_target: DMat4,
    params: &IcpParams,
    repeats: usize,
) -> Result<(RegisterTiming, IcpResult)> {
    bench_register_with(repeats, f64::INFINITY, || {
        register(source, target, init_source_to_target, params)
    })
}

/// Times `run` (one whole registration, target set-up included if the caller puts it in
/// the closure) up to `max_repeats` times (>= 1), stopping repeating once the runs took
/// `budget_seconds` in total. Returns the timings and the last result.
pub fn bench_register_with(
    max_repeats: usize,
    budget_seconds: f64,
    run: impl FnMut() -> Result<IcpResult>,
) -> Result<(RegisterTiming, IcpResult)> {
    let (seconds, last) = timed_runs(max_repeats, budget_seconds, run)?;
    let (median_seconds, min_seconds) = median_min(&seconds);
    Ok((
        RegisterTiming {
            median_seconds,
            min_seconds,
            iterations: last.iteration_count(),
            seconds,
        },
        last,
    ))
}

/// Times `nn.nearest` over `queries` (target frame, metres) up to `max_repeats` times
/// (>= 1), stopping repeating once the runs took `budget_seconds` in total.
pub fn bench_nearest(
    nn: &dyn NearestNeighbours,
    queries: &[[f32; 3]],
    max_repeats: usize,
    budget_seconds: f64,
) -> Result<NearestTiming> {
    let mut out = vec![(0u32, 0f32); queries.len()];
    let (seconds, ()) = timed_runs(max_repeats, budget_seconds, || {
        nn.nearest(queries, &mut out)
    })?;
    let (median_seconds, min_seconds) = median_min(&seconds);
    Ok(NearestTiming {
        queries: queries.len(),
        seconds,
        median_seconds,
        min_seconds,
    })
}
