//! Backend selection for the command line: the CPU reference or the GPU, behind one type.
//!
//! `auto` opens the GPU when an adapter exists and otherwise falls back to the CPU
//! reference, saying so on stderr; `gpu` fails with the adapter error instead. The CPU
//! reference runs on the threads [`cpu_threads`] gives it (`--threads N`, [`THREADS_ENV`]).

use std::num::NonZeroUsize;

use wgslam_core::cpu::invocations::Threads;

use crate::gpu::backend::GpuBackend;
use crate::gpu::context::GpuContext;
use crate::slam::backend::SlamBackend;
use crate::slam::cpu_backend::CpuBackend;
use crate::{Error, Result};

/// Which implementation to run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum BackendChoice {
    /// The GPU when an adapter exists, otherwise the CPU reference (saying so).
    Auto,
    /// The CPU reference (the twins in crates/core/src/cpu).
    Cpu,
    /// WGSL compute kernels on wgpu (Vulkan, Metal or DX12).
    Gpu,
}

/// The CPU or the GPU backend, chosen at run time. `Box<dyn SlamBackend>` is itself a
/// [`crate::slam::backend::Backend`] and [`crate::slam::backend::Inspect`] (the forwarding
/// impls next to the traits in `backend.rs`).
pub type AnyBackend = Box<dyn SlamBackend>;

/// Opens the chosen backend.
pub fn open(choice: BackendChoice) -> Result<AnyBackend> {
    match choice {
        BackendChoice::Cpu => Ok(Box::new(cpu_backend(1)?)),
        BackendChoice::Gpu => Ok(Box::new(GpuBackend::new(GpuContext::new()?)?)),
        BackendChoice::Auto => match GpuContext::new().and_then(GpuBackend::new) {
            Ok(g) => Ok(Box::new(g)),
            Err(e @ (Error::NoAdapter(_) | Error::Gpu(_))) => {
                eprintln!("note: no usable GPU ({e}); running the CPU reference instead");
                Ok(Box::new(cpu_backend(1)?))
            }
            Err(e) => Err(e),
        },
    }
}

/// The environment variable `--threads N` sets for this command and the processes it
/// starts (bench's children, a batch's jobs): the most threads the CPU reference's twins
/// use; unset, one per core.
pub const THREADS_ENV: &str = "WGSLAM_THREADS";

/// The CPU reference's threads for one of `jobs` runs at once in this process: the
/// `--threads` budget ([`THREADS_ENV`]; unset, every core) shared evenly, at least one
/// each. One job with no budget runs on rayon's global pool.
pub fn cpu_threads(jobs: usize) -> Result<Threads> {
    let budget = match std::env::var(THREADS_ENV) {
        Ok(v) => Some(v.parse::<NonZeroUsize>().map_err(|_| {
            Error::Argument(format!(
                "{THREADS_ENV}={v:?}: expected a whole number of threads, at least 1"
            ))
        })?),
        Err(_) => None,
    };
    if budget.is_none() && jobs <= 1 {
        return Ok(Threads::default());
    }
    let total = budget
        .or_else(|| std::thread::available_parallelism().ok())
        .map_or(1, NonZeroUsize::get);
    Threads::bounded(NonZeroUsize::new(total / jobs.max(1)).unwrap_or(NonZeroUsize::MIN))
}

/// The CPU reference on [`cpu_threads`]`(jobs)`.
pub fn cpu_backend(jobs: usize) -> Result<CpuBackend> {
    Ok(CpuBackend::with_threads(cpu_threads(jobs)?))
}
