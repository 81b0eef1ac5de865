//! The GPU backend: wgpu context, embedded WGSL kernels, typed buffers, timing, and
//! [`GpuBackend`], which runs `slam::backend::Backend`'s steps as those kernels.
//!
//! Every kernel in `shaders/<kernel>.wgsl` has a CPU twin in `src/cpu/<kernel>.rs`; this
//! module only knows how to run them on a device. Nothing here reads files.
//!
//! - [`context`]: adapter (Vulkan / Metal / DX12, never GL), device, limits, error scopes.
//! - [`shaders`]: `common.wgsl` + kernel sources, shared by the runtime and the naga test.
//! - [`kernel`]: pipeline + explicit bind-group layout + workgroup size; dispatch.
//! - [`buffers`]: typed storage arrays, uniforms, read-back, byte accounting.
//! - [`images`]: per-pixel maps as 2D textures (fast loads on lavapipe), read-back.
//! - [`map_buffers`]: the surfel map as chunks of storage buffers (structure of arrays).
//! - [`timing`]: per-pass timestamps (or wall time).
//! - [`backend`]: the dense-SLAM steps on the GPU.
//! - [`test_support`]: skip-or-require logic shared by every GPU test.

pub mod backend;
pub mod buffers;
pub mod context;
pub mod images;
pub mod kernel;
pub mod map_buffers;
pub mod shaders;
pub mod test_support;
pub mod timing;

pub use backend::GpuBackend;
pub use buffers::{GpuArray, ParamBuffer, Readback, StatsSnapshot};
pub use context::GpuContext;
pub use kernel::{layout_entries, layout_mismatches, Binding, BindingKind, Kernel, TexelFormat};
pub use timing::{StageTime, StageTimer};

/// The binding table of every kernel in [`shaders::KERNELS`], as `(kernel name, table)`:
/// the tables the dense backend, the scan registration and the renderer build their
/// layouts from. `tests/it/bindings.rs` checks each against naga's reflection of the kernel's
/// WGSL, without a GPU.
pub fn kernel_binding_tables() -> Vec<(&'static str, &'static [Binding])> {
    use crate::render::gpu::{RENDER_RESOLVE, RENDER_SPLAT};
    use crate::scan::gpu::{CROSS_COVARIANCE, NN_BRUTE, NN_GRID};
    use backend::bindings as b;
    vec![
        ("depth_to_vertex", &b::DEPTH_TO_VERTEX),
        ("bilateral_filter", &b::BILATERAL_FILTER),
        ("vertex_to_normal", &b::VERTEX_TO_NORMAL),
        ("pyramid_depth", &b::PYRAMID_DEPTH),
        ("pyramid_model", &b::PYRAMID_MODEL),
        ("block_bounds", &b::BLOCK_BOUNDS),
        ("project_model", &b::PROJECT_MODEL),
        ("predict_model", &b::PREDICT_MODEL),
        ("icp_reduce", &b::ICP_REDUCE),
        ("icp_reduce_final", &b::ICP_REDUCE_FINAL),
        ("fuse_select", &b::FUSE_SELECT),
        ("fuse_merge", &b::FUSE_MERGE),
        ("fuse_merge_chosen", &b::FUSE_MERGE_CHOSEN),
        ("fuse_prune", &b::FUSE_PRUNE),
        ("fuse_flags", &b::FUSE_FLAGS),
        ("fuse_add", &b::FUSE_ADD),
        ("compact_flags", &b::COMPACT_FLAGS),
        ("prefix_sum", &b::PREFIX_SUM),
        ("compact_scatter", &b::COMPACT_SCATTER),
        ("nn_brute", &NN_BRUTE),
        ("nn_grid", &NN_GRID),
        ("cross_covariance", &CROSS_COVARIANCE),
        ("render_splat", &RENDER_SPLAT),
        ("render_resolve", &RENDER_RESOLVE),
    ]
}
