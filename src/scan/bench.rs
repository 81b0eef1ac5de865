//! Timing of one CPU registration (KD-tree build + ICP), for the CLI's `bench`.
//! Not a statistics framework: it reports the median and minimum of a few repeats.

use std::time::Instant;

use glam::DMat4;

use super::icp::{register, IcpParams, IcpResult};
use crate::{Error, Result};

/// Timings of [`bench_register`], seconds.
#[derive(Debug, Clone, serde::Serialize)]
pub struct RegisterTiming {
    /// Every repeat, in run order (seconds).
    pub seconds: Vec<f64>,
    pub median_seconds: f64,
    pub min_seconds: f64,
    /// Iterations of the last repeat (all repeats are identical: same seed).
    pub iterations: usize,
}

/// Registers `source` onto `target` `repeats` times (>= 1) from `init_source_to_target`
/// and times each run, KD-tree build included. Returns the timings and the last result.
pub fn bench_register(
    source: &[[f32; 3]],
    target: &[[f32; 3]],
    init_source_to_target: DMat4,
    params: &IcpParams,
    repeats: usize,
) -> Result<(RegisterTiming, IcpResult)> {
    if repeats == 0 {
        return Err(Error::Argument("bench needs at least one repeat".into()));
    }
    let mut seconds = Vec::with_capacity(repeats);
    let mut last = None;
    for _ in 0..repeats {
        let start = Instant::now();
        let r = register(source, target, init_source_to_target, params)?;
        seconds.push(start.elapsed().as_secs_f64());
        last = Some(r);
    }
    let last = last.expect("repeats >= 1");
    let mut sorted = seconds.clone();
    sorted.sort_by(f64::total_cmp);
    Ok((
        RegisterTiming {
            median_seconds: sorted[sorted.len() / 2],
            min_seconds: sorted[0],
            iterations: last.iteration_count(),
            seconds,
        },
        last,
    ))
}
