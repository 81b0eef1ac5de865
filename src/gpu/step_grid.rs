//! The workgroups of a GPU step's passes ([`StepGrid`]), worked out before the step's bind
//! groups are lent out, and the checks and look-ups the steps share. Not the steps
//! themselves (see `super::steps`).

use std::collections::BTreeMap;

use super::bind_groups::BindGroups;
use super::context::GpuContext;
use super::kernel::{Kernel, KeyKernel};
use super::kernels::{Kernels, Shape};
use super::recording::Pass;
use crate::layout::{FuseParams, ASSOCIATION_BEST_CANDIDATE};
use crate::slam::backend::PyramidLevel;
use crate::{Error, Result};

/// The workgroups of one step's passes, worked out before its bind groups are lent out.
#[derive(Default)]
pub(super) struct StepGrid {
    /// The stale block boxes' `block_bounds` passes, `(chunk, workgroups)`.
    pub bounds: Vec<(usize, u32)>,
    /// Per map chunk, block-walking and grid-stride workgroups (see `chunk_workgroups`).
    pub chunks: Vec<(u32, u32)>,
    /// Per-pixel kernels at the frame's size, by kernel name.
    pub image: BTreeMap<&'static str, [u32; 2]>,
    /// Per coarser pyramid level, the grids of the level's kernels, by kernel name.
    pub levels: Vec<BTreeMap<&'static str, [u32; 2]>>,
}

impl StepGrid {
    pub fn image(&self, kernel: &str) -> [u32; 2] {
        self.image[kernel]
    }
    pub fn level(&self, level: usize, kernel: &str) -> [u32; 2] {
        self.levels[level - 1][kernel]
    }
    /// One pass of `kernel` per map chunk with the chunk's block-walking workgroups.
    pub fn per_block<'a>(
        &self,
        kernel: &'a Kernel,
        groups: &'a [wgpu::BindGroup],
    ) -> Vec<Pass<'a>> {
        groups
            .iter()
            .zip(&self.chunks)
            .map(|(g, &(blocks, _))| (kernel, g, [blocks, 1]))
            .collect()
    }
    /// [`StepGrid::per_block`] for each pass of a key kernel in turn: every chunk of a
    /// pass before the next pass (the portable kernels' second pass reads the first's
    /// result over the whole map).
    pub fn per_block_keys<'a>(
        &self,
        kernel: &'a KeyKernel,
        groups: &'a [wgpu::BindGroup],
    ) -> Vec<Pass<'a>> {
        kernel
            .passes
            .iter()
            .flat_map(|pass| self.per_block(pass, groups))
            .collect()
    }
    /// The passes of a `generic` kernel of the registry (see `super::kernels::Shape`):
    /// per bind group a pass over the frame's pixels, or per map chunk one workgroup per
    /// block. Panics on a kernel with neither a `generic` row nor an arm of its own in its
    /// step (an internal contract: every planned kernel has one or the other).
    pub fn generic<'a>(&self, k: &'a Kernels, bg: &'a BindGroups, kernel: &str) -> Vec<Pass<'a>> {
        let (pipeline, shape) = k.generic_kernel(kernel).unwrap_or_else(|| {
            panic!("`{kernel}` has neither a `generic` row in gpu::kernels nor an arm in its step")
        });
        let groups = &bg.generic[kernel];
        match shape {
            Shape::PerBlock => self.per_block(pipeline, groups),
            Shape::OverFrame | Shape::PerChunk => groups
                .iter()
                .map(|g| (pipeline, g, self.image(kernel)))
                .collect(),
        }
    }
    /// The `block_bounds` passes over the stale boxes.
    pub fn bounds<'a>(&self, k: &'a Kernels, bg: &'a BindGroups) -> Vec<Pass<'a>> {
        self.bounds
            .iter()
            .map(|&(c, wg)| (&k.block_bounds, &bg.block_bounds[c], [wg, 1]))
            .collect()
    }
}

/// [`Error::Argument`] unless each pyramid level halves the one before (rounded up), the
/// first level 0's `width` x `height`: the kernels read finer pixel `(2u, 2v)` for coarse
/// pixel `(u, v)` without a bounds check of their own.
pub(super) fn check_pyramid(width: u32, height: u32, pyramid: &[PyramidLevel]) -> Result<()> {
    let mut fine = (width, height);
    for (l, p) in pyramid.iter().enumerate() {
        let d = &p.down;
        let coarse = (fine.0.div_ceil(2), fine.1.div_ceil(2));
        if (d.fine_width, d.fine_height) != fine
            || (d.camera.width, d.camera.height) != coarse
            || (p.normal.width, p.normal.height) != coarse
        {
            return Err(Error::Argument(format!(
                "pyramid level {}: a {}x{} level (normals {}x{}) made from {}x{} does not halve \
                 the {}x{} level before it",
                l + 1,
                d.camera.width,
                d.camera.height,
                p.normal.width,
                p.normal.height,
                d.fine_width,
                d.fine_height,
                fine.0,
                fine.1
            )));
        }
        fine = coarse;
    }
    Ok(())
}

/// The image grids of per-pixel `kernels` and of the registry's `generic` kernels over the
/// frame's `width x height` maps, by kernel name.
pub(super) fn frame_grids(
    ctx: &GpuContext,
    k: &Kernels,
    kernels: &[&Kernel],
    width: u32,
    height: u32,
) -> BTreeMap<&'static str, [u32; 2]> {
    let generic = k.generic_kernels();
    let all: Vec<&Kernel> = kernels.iter().copied().chain(generic).collect();
    image_grids(ctx, &all, width, height)
}

/// The image grids of per-pixel `kernels` over a `width x height` map, by kernel name.
pub(super) fn image_grids(
    ctx: &GpuContext,
    kernels: &[&Kernel],
    width: u32,
    height: u32,
) -> BTreeMap<&'static str, [u32; 2]> {
    kernels
        .iter()
        .map(|k| {
            (
                kernel_name(k),
                k.grid_workgroups_for_image(ctx, width, height),
            )
        })
        .collect()
}

/// How many of `fuse_add`'s passes a fuse step runs: all with best-candidate association;
/// without it only the first (the portable kernel's second pass only sets the index words
/// of the index map, which projective association does not build).
pub(super) fn key_passes_of_fuse_add(params: &FuseParams, fuse_add: &KeyKernel) -> usize {
    if params.association == ASSOCIATION_BEST_CANDIDATE {
        fuse_add.passes.len()
    } else {
        1
    }
}

/// A kernel's name as the `'static` key of a [`StepGrid`] map.
pub(super) fn kernel_name(kernel: &Kernel) -> &'static str {
    crate::gpu::shaders::KERNELS
        .iter()
        .map(|(name, _)| *name)
        .find(|name| *name == kernel.name)
        .expect("every kernel is in shaders::KERNELS")
}
