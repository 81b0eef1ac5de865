//! The dense-SLAM kernels, one [`Kernel`] each, built once per backend. Each is
//! `shaders/<name>.wgsl` with its layout reflected from the WGSL (see [`Kernel::new`]) and
//! its CPU twin in `src/cpu/<name>.rs`; the field is named after the kernel. The three
//! key kernels are [`KeyKernel`]s: 64-bit, or their portable twins on a device without
//! 64-bit atomics.

use super::context::GpuContext;
use super::kernel::{Kernel, KeyKernel};
use crate::Result;

/// Every kernel of the dense pipeline.
pub(super) struct Kernels {
    pub depth_to_vertex: Kernel,
    pub bilateral_filter: Kernel,
    pub vertex_to_normal: Kernel,
    pub pyramid_depth: Kernel,
    pub block_bounds: Kernel,
    pub project_model: KeyKernel,
    pub predict_model: Kernel,
    pub pyramid_model: Kernel,
    pub icp_reduce: Kernel,
    pub icp_reduce_final: Kernel,
    pub fern_encode: Kernel,
    pub icp_candidates: Kernel,
    pub keypoint_detect: Kernel,
    pub keypoint_describe: Kernel,
    pub fuse_select: KeyKernel,
    pub fuse_merge: Kernel,
    pub fuse_merge_chosen: Kernel,
    pub fuse_prune: Kernel,
    pub fuse_flags: Kernel,
    pub fuse_add: KeyKernel,
    pub compact_flags: Kernel,
    /// The scan's three kernels: block sums, their scan, each block's scan.
    pub prefix_sum_reduce: Kernel,
    pub prefix_sum_blocks: Kernel,
    pub prefix_sum: Kernel,
    pub compact_scatter: Kernel,
}

impl Kernels {
    /// Builds every kernel (pipeline creation costs 60-130 ms each on lavapipe).
    pub fn new(ctx: &GpuContext) -> Result<Kernels> {
        let k = |name: &str| Kernel::new(ctx, name);
        Ok(Kernels {
            depth_to_vertex: k("depth_to_vertex")?,
            bilateral_filter: k("bilateral_filter")?,
            vertex_to_normal: k("vertex_to_normal")?,
            pyramid_depth: k("pyramid_depth")?,
            block_bounds: k("block_bounds")?,
            project_model: KeyKernel::new(ctx, "project_model")?,
            predict_model: k("predict_model")?,
            pyramid_model: k("pyramid_model")?,
            icp_reduce: k("icp_reduce")?,
            icp_reduce_final: k("icp_reduce_final")?,
            fern_encode: k("fern_encode")?,
            icp_candidates: k("icp_candidates")?,
            keypoint_detect: k("keypoint_detect")?,
            keypoint_describe: k("keypoint_describe")?,
            fuse_select: KeyKernel::new(ctx, "fuse_select")?,
            fuse_merge: k("fuse_merge")?,
            fuse_merge_chosen: k("fuse_merge_chosen")?,
            fuse_prune: k("fuse_prune")?,
            fuse_flags: k("fuse_flags")?,
            fuse_add: KeyKernel::new(ctx, "fuse_add")?,
            compact_flags: k("compact_flags")?,
            prefix_sum_reduce: k("prefix_sum_reduce")?,
            prefix_sum_blocks: k("prefix_sum_blocks")?,
            prefix_sum: k("prefix_sum")?,
            compact_scatter: k("compact_scatter")?,
        })
    }
}
