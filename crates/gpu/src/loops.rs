//! The GPU side of loop closure's map deformation (`wgslam::slam::loops`):
//! `deform_surfels`' kernel and node table, made at the first closure so a run without one
//! pays nothing. The step itself, and the two copies a loop's verification needs, are in
//! `super::single_steps`.

use super::buffers::{GpuArray, ParamBuffer};
use super::context::GpuContext;
use super::kernel::Kernel;
use crate::layout::{DeformNode, DeformParams};
use crate::Result;

/// `deform_surfels`' kernel, parameters and node table.
pub(super) struct DeformBuffers {
    pub kernel: Kernel,
    pub params: ParamBuffer<DeformParams>,
    pub nodes: GpuArray<DeformNode>,
}

impl DeformBuffers {
    /// The kernel, and a node table for at least `nodes` nodes (the next power of two).
    pub fn new(ctx: &GpuContext, params: &DeformParams, nodes: usize) -> Result<Self> {
        Ok(DeformBuffers {
            kernel: Kernel::new(ctx, "deform_surfels")?,
            params: ParamBuffer::new(ctx, "DeformParams", params),
            nodes: GpuArray::new(ctx, "deformation nodes", nodes.next_power_of_two())?,
        })
    }
}
