//! The workgroups of a GPU step's passes ([`StepGrid`]), worked out before the step's bind
//! groups are lent out, and the checks and look-ups the steps share. Not the steps
//! themselves (see `super::steps`).

use super::bind_groups::{BindGroups, SURFEL_ARRAYS};
use super::context::GpuContext;
use super::kernel::{image_grid, Kernel};
use super::pipelines::Kernels;
use super::recording::Pass;
use crate::layout::{scan_blocks, ICP_SYSTEM_LEN};
use crate::{Error, Result};
use wgslam_core::backend::PyramidLevel;
use wgslam_core::plan::Call;
use wgslam_core::registry::Shape;

/// The workgroups of one step's passes, worked out before its bind groups are lent out:
/// the sizes of the frame and its pyramid levels (a per-pixel kernel's grid follows from
/// them and the kernel's workgroup size), the map chunks' workgroups and the stale block
/// boxes.
pub(super) struct StepGrid {
    /// The stale block boxes' passes, `(chunk, workgroups)` (a `PerStaleBlock` row's;
    /// see `stale_bounds_passes`).
    pub bounds: Vec<(usize, u32)>,
    /// Per map chunk, the block-walking kernels' workgroups (see `chunk_blocks`).
    pub chunks: Vec<u32>,
    /// Per map chunk, its live surfels (a `PerSurfel` or `PerChunkPair` row's passes; see
    /// `chunk_live`).
    pub live: Vec<usize>,
    /// The items a `PerItem` row's pass gives one thread each (ferns, keypoints), or a
    /// `PerCount` row's one workgroup each (its counts).
    pub items: usize,
    /// The flags a scan's rows cover (`PerScanBlock`: one workgroup per block of them).
    pub flags: usize,
    /// The frame's `[width, height]` in pixels.
    frame: [u32; 2],
    /// Per coarser pyramid level (1, 2, ...), its `[width, height]` in pixels.
    levels: Vec<[u32; 2]>,
    /// [`GpuContext::grid_workgroups_cap`] and [`GpuContext::is_cpu_adapter`] (see
    /// [`image_grid`]).
    cap: u32,
    cpu_adapter: bool,
    /// [`GpuContext::reduction_workgroups`]: a reduction's workgroups, one partial system
    /// each.
    reduction: u32,
}

impl StepGrid {
    /// The grids of a step over a `frame` of `[width, height]` pixels and its coarser
    /// pyramid `levels` (1, 2, ...), with no map chunks and no stale boxes.
    pub fn new(ctx: &GpuContext, frame: [u32; 2], levels: Vec<[u32; 2]>) -> StepGrid {
        StepGrid {
            bounds: Vec::new(),
            chunks: Vec::new(),
            live: Vec::new(),
            items: 0,
            flags: 0,
            frame,
            levels,
            cap: ctx.grid_workgroups_cap(),
            cpu_adapter: ctx.is_cpu_adapter(),
            reduction: ctx.reduction_workgroups(),
        }
    }
    /// A per-pixel `kernel`'s workgroups over the frame.
    pub fn image(&self, kernel: &Kernel) -> [u32; 2] {
        self.over(kernel, self.frame)
    }
    /// A per-pixel `kernel`'s workgroups over pyramid level `level` (0: the frame).
    pub fn level(&self, level: usize, kernel: &Kernel) -> [u32; 2] {
        match level {
            0 => self.image(kernel),
            l => self.over(kernel, self.levels[l - 1]),
        }
    }
    fn over(&self, kernel: &Kernel, [width, height]: [u32; 2]) -> [u32; 2] {
        image_grid(
            kernel.workgroups_for_image(width, height),
            self.cap,
            self.cpu_adapter,
        )
    }
    /// One pass of `kernel` per map chunk (bind group) with the chunk's `workgroups`: a
    /// block-walking kernel's ([`StepGrid::chunks`]), or a grid-stride kernel's over the
    /// chunk's live surfels ([`StepGrid::live`], one thread each, at most the grid cap: the
    /// loop covers the rest). A chunk of none records an empty pass.
    fn per_chunk<'a>(
        kernel: &'a Kernel,
        groups: &'a [wgpu::BindGroup],
        workgroups: impl Iterator<Item = u32>,
    ) -> Vec<Pass<'a>> {
        groups
            .iter()
            .zip(workgroups)
            .map(|(g, wg)| (kernel, g, [wg, 1]))
            .collect()
    }

    /// The passes of the `generic` kernel of the registry that `call` runs (see
    /// `wgslam_core::registry::Shape`), over its bind groups at the call's
    /// [`At`](wgslam_core::registry::At):
    /// - per bind group a pass over the frame's pixels (a pyramid level's);
    /// - per map chunk one workgroup per block, or per chunk with stale boxes one per stale
    ///   block ([`StepGrid::bounds`]);
    /// - per chunk with live surfels a grid-stride pass over them ([`StepGrid::live`]), and
    ///   per pair of chunks and surfel array one over the first chunk's;
    /// - one thread per item, or one workgroup per count ([`StepGrid::items`]);
    /// - a reduction's pass of the reduction workgroups, a system's sum of one workgroup per
    ///   entry;
    /// - a scan's pass of one workgroup per block of [`StepGrid::flags`], or of one
    ///   workgroup;
    /// - a key kernel's passes in turn, each over every bind group (its first alone where
    ///   the call says so: `Call::every_key_pass`).
    ///
    /// Panics on a call whose kernel has no `generic` row, or no bind group where it runs
    /// (internal contracts: every planned kernel has a row, and
    /// [`At::choices`](wgslam_core::registry::At::choices) lists every place a plan gives).
    pub fn generic<'a>(
        &self,
        k: &'a Kernels,
        bg: &'a BindGroups,
        call: impl Call,
    ) -> Vec<Pass<'a>> {
        let Some((kernel, (passes, shape))) = call
            .kernel()
            .and_then(|id| Some((id, k.generic_kernel(id)?)))
        else {
            panic!(
                "`{}` has neither a `generic` registry row nor an arm in its step",
                call.name()
            )
        };
        let at = shape.bound_at(call.at());
        let groups = bg
            .generic
            .get(&(kernel, at))
            .unwrap_or_else(|| panic!("`{}` has no bind group at {at:?}", call.name()));
        let wg = match shape {
            Shape::Reduce => [self.reduction, 1],
            Shape::PerSystem => [ICP_SYSTEM_LEN as u32, 1],
            Shape::PerScanBlock => [scan_blocks(self.flags) as u32, 1],
            Shape::OneWorkgroup => [1, 1],
            // One workgroup per count.
            Shape::PerCount => [self.items as u32, 1],
            // Bound by their callers (`row_kernels`): no row of the dense pipeline.
            Shape::PerPoint | Shape::PerPartial => {
                panic!("`{}` is bound by its caller", call.name())
            }
            // One thread per item, at most the reduction workgroups.
            Shape::PerItem => [
                passes[0]
                    .workgroups_for(self.items)
                    .min(self.reduction.max(1)),
                1,
            ],
            Shape::OverFrame
            | Shape::PerChunk
            | Shape::PerBlock
            | Shape::PerStaleBlock
            | Shape::PerSurfel
            | Shape::PerChunkPair
            | Shape::PerLevel => self.level(at.level, &passes[0]),
        };
        let passes = match call.every_key_pass() {
            true => passes,
            false => &passes[..1],
        };
        passes
            .iter()
            .flat_map(|pass| match shape {
                Shape::PerBlock => Self::per_chunk(pass, groups, self.chunks.iter().copied()),
                Shape::PerSurfel => {
                    let live = self.live.iter();
                    let wg = live.map(|&n| pass.workgroups_for(n).min(self.cap));
                    Self::per_chunk(pass, groups, wg)
                }
                // Chunk s's workgroups for each of its s + 1 pairs' SURFEL_ARRAYS groups.
                Shape::PerChunkPair => {
                    let live = self.live.iter().enumerate();
                    let wg = live.flat_map(|(s, &n)| {
                        let wg = pass.workgroups_for(n).min(self.cap);
                        std::iter::repeat_n(wg, (s + 1) * SURFEL_ARRAYS)
                    });
                    Self::per_chunk(pass, groups, wg)
                }
                Shape::PerStaleBlock => self
                    .bounds
                    .iter()
                    .map(|&(c, wg)| (pass, &groups[c], [wg, 1]))
                    .collect(),
                Shape::OverFrame
                | Shape::PerChunk
                | Shape::PerLevel
                | Shape::PerItem
                | Shape::Reduce
                | Shape::PerSystem
                | Shape::PerScanBlock
                | Shape::OneWorkgroup
                | Shape::PerCount
                | Shape::PerPoint
                | Shape::PerPartial => groups.iter().map(|g| (pass, g, wg)).collect(),
            })
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
