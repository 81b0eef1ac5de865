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

/// Opens the chosen backend, the GPU's on a device of its own.
pub fn open(choice: BackendChoice) -> Result<AnyBackend> {
    open_on(choice, GpuContext::new)
}

/// Opens the chosen backend, the GPU's on the process's shared device: every backend
/// opened so shares one device and queue ([`GpuContext::share`]: their device waits are
/// shared, and the pipelines are compiled once for all of them), as issue 48 asks of
/// several trackers in one process (Python's `wgslam.Slam`s and `wgslam.run`s). The device
/// is made at the first call and kept for the process's life; a lost one is replaced at the
/// next call. In a browser (wasm32) each backend has a device of its own.
pub fn open_shared(choice: BackendChoice) -> Result<AnyBackend> {
    open_on(choice, shared_gpu_context)
}

/// The process's shared device (see [`open_shared`]).
#[cfg(not(target_arch = "wasm32"))]
static SHARED_DEVICE: std::sync::Mutex<Option<GpuContext>> = std::sync::Mutex::new(None);

/// A context on the process's shared device, made at the first call (or after the last one
/// was lost).
#[cfg(not(target_arch = "wasm32"))]
fn shared_gpu_context() -> Result<GpuContext> {
    let mut shared = SHARED_DEVICE.lock().unwrap_or_else(|p| p.into_inner());
    if let Some(ctx) = shared.as_ref().filter(|c| c.check_device().is_ok()) {
        return Ok(ctx.share());
    }
    let ctx = GpuContext::new()?;
    let this_one = ctx.share();
    *shared = Some(ctx);
    Ok(this_one)
}

/// In a browser (one thread, and wgpu's device there cannot be sent between threads) a
/// device of its own.
#[cfg(target_arch = "wasm32")]
fn shared_gpu_context() -> Result<GpuContext> {
    GpuContext::new()
}

/// Opens the chosen backend with `gpu` giving the GPU's context.
fn open_on(choice: BackendChoice, gpu: fn() -> Result<GpuContext>) -> Result<AnyBackend> {
    match choice {
        BackendChoice::Cpu => Ok(Box::new(cpu_backend(1)?)),
        BackendChoice::Gpu => Ok(Box::new(GpuBackend::new(gpu()?)?)),
        BackendChoice::Auto => match gpu().and_then(GpuBackend::new) {
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
