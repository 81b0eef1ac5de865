//! wgslam's GPU engine, the second floor of its workspace: wgpu context, embedded WGSL
//! kernels, typed buffers, timing, and [`GpuBackend`], which runs
//! [`wgslam_core::backend::Backend`]'s steps as those kernels.
//!
//! Every kernel in `shaders/<kernel>.wgsl` has a CPU twin in
//! `crates/core/src/cpu/<kernel>.rs`; this crate only knows how to run them on a device.
//! Nothing here reads files but the pipeline cache's own ([`pipeline_cache`]), and nothing
//! here can import the pipeline, the datasets or the tools above it (the `wgslam` package
//! re-exports this crate as `wgslam::gpu`).
//!
//! - [`context`]: adapter (Vulkan / Metal / DX12, never GL), device, limits, error scopes.
//! - [`shaders`]: `common.wgsl` + kernel sources, shared by the runtime and the naga test.
//! - [`kernel`]: pipeline + bind-group layout reflected from the WGSL + workgroup size;
//!   bind groups by binding name; dispatch.
//! - [`buffers`]: typed storage arrays, uniforms, read-back, byte accounting.
//! - [`images`]: per-pixel maps as 2D textures (fast loads on lavapipe), read-back.
//! - [`map_buffers`]: the surfel map as chunks of storage buffers (structure of arrays).
//! - [`timing`]: per-pass timestamps (or wall time).
//! - [`backend`]: the dense-SLAM steps on the GPU, each recorded from its plan
//!   (`wgslam_core::plan`); beside it, private: `pipelines` (the pipelines, built from the
//!   kernel registry's rows, `wgslam_core::registry`), `resources` (parameter
//!   and frame buffers), `bind_groups`, `compaction`, `recording` (passes and per-kernel
//!   timing), `steps` (the steps' passes), `single_steps` (the steps of one kernel each)
//!   with their buffers in `ferns`, `keypoints` and `candidates`, `inspect`
//!   (downloads and uploads). The helper modules never import `backend`: the one-way
//!   imports are `steps`/`single_steps` -> `backend` -> helpers.
//! - [`row_kernels`]: the kernels outside the dense pipeline (the renderer's, scan
//!   registration's), each plan call bound over its caller's pool by the kernel's row.
//! - [`pipeline_cache`]: the pipelines' cache across processes, in the user's cache folder.
//! - [`test_support`]: skip-or-require logic shared by every GPU test.
//! - [`wait`]: waiting for wgpu's futures and callbacks, natively and in a browser (JSPI or asyncify).

// The floor below, under the paths the modules use (`crate::layout`).
pub(crate) use wgslam_core::{layout, Error, Result};

#[macro_use]
pub mod backend;
mod bind_groups;
pub mod buffers;
mod candidates;
mod compaction;
pub mod context;
mod ferns;
pub mod images;
mod inspect;
pub mod kernel;
mod keypoints;
pub mod map_buffers;
pub mod pipeline_cache;
mod pipelines;
mod recording;
mod resources;
pub mod row_kernels;
pub mod shaders;
mod shared_wait;
mod single_steps;
pub mod stats;
mod step_grid;
mod steps;
pub mod test_support;
pub mod timing;
pub mod wait;

pub use backend::GpuBackend;
pub use buffers::{GpuArray, ParamBuffer, Readback};
pub use context::GpuContext;
pub use kernel::{reflect, Kernel, ReflectedBinding};
pub use row_kernels::RowKernels;
pub use stats::StatsSnapshot;
pub use timing::{StageTime, StageTimer};
