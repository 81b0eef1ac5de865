//! The GPU backend: wgpu context, embedded WGSL kernels, typed buffers and timing.
//!
//! Every kernel in `shaders/<kernel>.wgsl` has a CPU twin in `src/cpu/<kernel>.rs`; this
//! module only knows how to run them on a device. Nothing here reads files.

pub mod backend;
pub mod buffers;
pub mod context;
pub mod kernel;
pub mod shaders;
pub mod test_support;
pub mod timing;

pub use backend::GpuBackend;
pub use buffers::{GpuArray, Readback, StatsSnapshot, Uniform};
pub use context::GpuContext;
pub use kernel::{Binding, BindingKind, Kernel};
pub use timing::{StageTime, StageTimer};
