//! Backend selection for the command line: the CPU reference or the GPU, behind one type.
//!
//! `auto` opens the GPU when an adapter exists and otherwise falls back to the CPU
//! reference, saying so on stderr; `gpu` fails with the adapter error instead.

use crate::cpu_backend::CpuBackend;
use crate::gpu::backend::GpuBackend;
use crate::gpu::context::GpuContext;
use crate::layout::{
    FuseParams, IcpParams, NormalParams, PreprocessParams, ProjectParams, ICP_SYSTEM_LEN,
};
use crate::map::SurfelMap;
use crate::pipeline::{Backend, BackendCounters, FrameMaps};
use crate::{Error, Result};

/// Which implementation to run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum BackendChoice {
    /// The GPU when an adapter exists, otherwise the CPU reference (saying so).
    Auto,
    /// The CPU reference (the twins in src/cpu).
    Cpu,
    /// WGSL compute kernels on wgpu (Vulkan, Metal or DX12).
    Gpu,
}

/// The CPU or the GPU backend.
pub enum AnyBackend {
    Cpu(Box<CpuBackend>),
    Gpu(Box<GpuBackend>),
}

impl AnyBackend {
    /// Opens the chosen backend.
    pub fn open(choice: BackendChoice) -> Result<AnyBackend> {
        match choice {
            BackendChoice::Cpu => Ok(AnyBackend::Cpu(Box::default())),
            BackendChoice::Gpu => Ok(AnyBackend::Gpu(Box::new(GpuBackend::new(
                GpuContext::new()?,
            )?))),
            BackendChoice::Auto => match GpuContext::new().and_then(GpuBackend::new) {
                Ok(g) => Ok(AnyBackend::Gpu(Box::new(g))),
                Err(e @ (Error::NoAdapter(_) | Error::Gpu(_))) => {
                    eprintln!("note: no usable GPU ({e}); running the CPU reference instead");
                    Ok(AnyBackend::Cpu(Box::default()))
                }
                Err(e) => Err(e),
            },
        }
    }

    fn inner(&mut self) -> &mut dyn Backend {
        match self {
            AnyBackend::Cpu(b) => b.as_mut(),
            AnyBackend::Gpu(b) => b.as_mut(),
        }
    }

    fn inner_ref(&self) -> &dyn Backend {
        match self {
            AnyBackend::Cpu(b) => b.as_ref(),
            AnyBackend::Gpu(b) => b.as_ref(),
        }
    }
}

impl Backend for AnyBackend {
    fn name(&self) -> &'static str {
        self.inner_ref().name()
    }
    fn preprocess(
        &mut self,
        p: &PreprocessParams,
        n: &NormalParams,
        d: &[u16],
        c: &[u32],
    ) -> Result<()> {
        self.inner().preprocess(p, n, d, c)
    }
    fn predict(&mut self, p: &ProjectParams) -> Result<()> {
        self.inner().predict(p)
    }
    fn icp_system(&mut self, p: &IcpParams) -> Result<[f64; ICP_SYSTEM_LEN]> {
        self.inner().icp_system(p)
    }
    fn fuse(&mut self, p: &FuseParams) -> Result<usize> {
        self.inner().fuse(p)
    }
    fn surfel_count(&self) -> usize {
        self.inner_ref().surfel_count()
    }
    fn download_map(&mut self) -> Result<SurfelMap> {
        self.inner().download_map()
    }
    fn download_frame(&mut self) -> Result<FrameMaps> {
        self.inner().download_frame()
    }
    fn download_prediction(&mut self) -> Result<crate::pipeline::Prediction> {
        self.inner().download_prediction()
    }
    fn counters(&self) -> BackendCounters {
        self.inner_ref().counters()
    }
    fn finish(&mut self) -> Result<()> {
        self.inner().finish()
    }
}
