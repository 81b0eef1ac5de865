//! The GPU backend: wgpu context, embedded WGSL kernels, typed buffers, timing, and
//! [`GpuBackend`], which runs `pipeline::Backend`'s steps as those kernels.
//!
//! Every kernel in `shaders/<kernel>.wgsl` has a CPU twin in `src/cpu/<kernel>.rs`; this
//! module only knows how to run them on a device. Nothing here reads files.
//!
//! - [`context`]: adapter (Vulkan / Metal / DX12, never GL), device, limits, error scopes.
//! - [`shaders`]: `common.wgsl` + kernel sources, shared by the runtime and the naga test.
//! - [`kernel`]: pipeline + explicit bind-group layout + workgroup size; dispatch.
//! - [`buffers`]: typed storage arrays, uniforms, read-back, byte accounting.
//! - [`images`]: per-pixel maps as 2D textures (fast loads on lavapipe), read-back.
//! - [`map_textures`]: the surfel map as five textures that grow by GPU copy.
//! - [`timing`]: per-pass timestamps (or wall time).
//! - [`backend`]: the dense-SLAM steps on the GPU.
//! - [`test_support`]: skip-or-require logic shared by every GPU test.

pub mod backend;
pub mod buffers;
pub mod context;
pub mod images;
pub mod kernel;
pub mod map_textures;
pub mod shaders;
pub mod test_support;
pub mod timing;

pub use backend::GpuBackend;
pub use buffers::{GpuArray, Readback, StatsSnapshot, Uniform};
pub use context::GpuContext;
pub use kernel::{Binding, BindingKind, Kernel, TexelFormat};
pub use timing::{StageTime, StageTimer};
