//! Backend selection for the command line: the CPU reference or the GPU, behind one type.
//!
//! `auto` opens the GPU when an adapter exists and otherwise falls back to the CPU
//! reference, saying so on stderr; `gpu` fails with the adapter error instead.

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
        BackendChoice::Cpu => Ok(Box::new(CpuBackend::new())),
        BackendChoice::Gpu => Ok(Box::new(GpuBackend::new(GpuContext::new()?)?)),
        BackendChoice::Auto => match GpuContext::new().and_then(GpuBackend::new) {
            Ok(g) => Ok(Box::new(g)),
            Err(e @ (Error::NoAdapter(_) | Error::Gpu(_))) => {
                eprintln!("note: no usable GPU ({e}); running the CPU reference instead");
                Ok(Box::new(CpuBackend::new()))
            }
            Err(e) => Err(e),
        },
    }
}
