//! The GPU backend: runs the dense-SLAM steps of [`crate::slam::backend::Backend`] as the
//! WGSL kernels in `shaders/`, each the twin of a CPU function in `src/cpu/`, in the order
//! of each step's plan ([`crate::slam::plan`], shared with the CPU backend): one compute
//! pass per planned kernel (one per map chunk for the kernels that walk the map), one
//! submission per step.
//!
//! Per-pixel maps (raw inputs, vertex / filtered-vertex / normal / colour maps, the
//! prediction, the pyramid's coarser levels) are 2D textures (`GpuImage`, in
//! `FrameBuffers`): kernels read them with `textureLoad` and write them as storage
//! textures, which lavapipe loads 3-5x faster than storage-buffer elements
//! (`examples/lavapipe_loads.rs`). The frame's normal map carries the vertex's depth in w
//! (`normal_depth`), so the kernels that associate with the frame fetch one texel and
//! rebuild the vertex (see vertex_to_normal.wgsl), as does the twin.
//! The surfel map is chunks of three storage buffers each ([`MapBuffers`]); the index map,
//! the association buffers, the counter and the ICP partials are storage buffers too
//! (atomics). Each block of [`BLOCK_SURFELS`] map slots has a world-frame box in
//! `block_bounds`: the culling kernels skip the blocks the camera cannot see, `fuse_merge`
//! grows a box a merge moved a surfel out of, and `block_bounds` recomputes the boxes of the
//! blocks fusion appended to (all of them after a compaction or an upload) at the start of
//! the next culling step.
//! Every pipeline, uniform and small buffer is created once in [`GpuBackend::new`]; the
//! frame's buffers at the first `preprocess` (again only if the frame size changes); the
//! surfel map lives on the GPU for the whole run and grows before a fusion could overflow
//! it (its last chunk x1.5 by a GPU-side copy, then new chunks). Per frame the host reads
//! back only the ICP system (per iteration, `icp_reduce`'s per-workgroup partials summed on
//! the GPU by `icp_reduce_final`: 29 floats, 116 bytes) and the 4-byte surfel counter.
//! The `compact` step's flags, offsets and second map (`Compaction`) are allocated at its
//! first call and follow the map as it grows; after it the two map sets swap (and so do
//! their bind groups).
//! Not a scheduler: the order of steps is `pipeline::Slam`'s.

use super::bind_groups::{BindGroups, CompactionGroups, Resources};
use super::buffers::{GpuArray, Readback};
use super::compaction::Compaction;
use super::context::GpuContext;
use super::kernel::Kernel;
use super::kernels::Kernels;
use super::map_buffers::MapBuffers;
use super::recording::{record_passes, submit_profiled, Pass, Profiler, PROFILED_PASSES_MAX};
use super::resources::{FrameBuffers, Uniforms};
use super::timing::StageTimer;
use crate::layout::scan_params;
use crate::layout::{
    BilateralParams, BoundsParams, CompactParams, FuseParams, IcpParams, NormalParams,
    PreprocessParams, ProjectParams, BLOCK_SURFELS, ICP_SYSTEM_LEN,
};
use crate::slam::backend::{Backend, PyramidLevel};
use crate::slam::fused_view::FusedView;
use crate::slam::plan::{self, Buffer, Call};
use crate::{Error, Result};
use std::collections::BTreeMap;

// Packed RGBA8 u32s are uploaded as rgba8uint texels (r in the low byte) and the u64
// index map is read as vec2<u32> (low word first): both assume a little-endian host, like
// every platform wgpu runs on.
#[cfg(target_endian = "big")]
compile_error!("the GPU backend assumes a little-endian host (u32/u64 data read as bytes/words)");

/// Surfel slots allocated up front: a little over three 320x240 frames, ~10 MB.
pub const DEFAULT_INITIAL_CAPACITY: usize = 256 * 1024;
/// Growth factor of the map buffers when a frame might not fit.
const GROWTH_NUM: usize = 3;
const GROWTH_DEN: usize = 2;
/// Storage buffers bound at once by the largest kernel (`compact_scatter`: params, flags,
/// offsets, and an input and an output chunk's `MapChunk` and three arrays).
const MAX_STORAGE_BUFFERS_USED: u32 = 11;
/// Storage textures bound at once by the largest kernel (`depth_to_vertex`,
/// `predict_model`: two maps).
const MAX_STORAGE_TEXTURES_USED: u32 = 2;

/// Runs the pipeline's steps on a GPU through wgpu. See the module header.
pub struct GpuBackend {
    pub(super) ctx: GpuContext,
    kernels: Kernels,
    uniforms: Uniforms,
    reduction_workgroups: u32,
    partials: GpuArray<f32>,
    /// The summed system (`icp_reduce_final`), the one read-back per ICP iteration.
    system: GpuArray<f32>,
    system_readback: Readback<f32>,
    /// `icp_reduce_final` over `partials` into `system` (neither is ever re-created).
    icp_final_group: wgpu::BindGroup,
    counter: GpuArray<u32>,
    counter_readback: Readback<u32>,
    pub(super) frame: Option<FrameBuffers>,
    pub(super) map: MapBuffers,
    /// Per culling block of map slots, its box: entries `2b` (min) and `2b + 1` (max),
    /// ordered-encoded (see `block_bounds.wgsl`); one buffer for both map sets.
    pub(super) block_bounds: GpuArray<[u32; 4]>,
    /// Blocks from the one holding this surfel index on have stale boxes (fusion appended
    /// to them, or the map was compacted or uploaded); recomputed before the next culling.
    pub(super) bounds_dirty_from: usize,
    /// The view the frame's `index_map` was built at by the last `fuse`, while the map is
    /// as that fusion left it (see [`FusedView`]).
    pub(super) fused_view: Option<FusedView>,
    /// Surfels in the map (the GPU counter as last read back).
    pub(super) count: usize,
    /// Largest map the backend may allocate, in surfels.
    max_surfels: usize,
    /// `None` after any buffer a bind group refers to was re-created.
    bind_groups: Option<BindGroups>,
    /// The same for the compaction's spare map set: `compact` swaps the map with the
    /// spare and these with `bind_groups`, so no bind group is made per frame.
    spare_bind_groups: Option<BindGroups>,
    /// Per-kernel timing, off unless [`GpuBackend::enable_kernel_timing`] was called.
    profiler: Option<Profiler>,
    /// Buffers of the `compact` step, `None` until its first call.
    pub(super) compaction: Option<Compaction>,
}

/// Builds the bind groups if a buffer changed, then lends what a step needs to encode and
/// submit its passes: `(ctx, kernels, bind groups, profiler)`. A macro rather than a method
/// so the borrows stay per field: the step still reads its uniforms, frame buffers and
/// read-backs while the profiler is borrowed mutably.
macro_rules! encoding_parts {
    ($backend:ident) => {{
        $backend.bind_groups();
        (
            &$backend.ctx,
            &$backend.kernels,
            $backend.bind_groups.as_ref().expect("just built"),
            &mut $backend.profiler,
        )
    }};
}

impl GpuBackend {
    /// Opens the GPU ([`GpuContext::new`]: logs the adapter; [`Error::NoAdapter`] without
    /// one) and builds a backend on it: what `--backend gpu` needs.
    pub fn open() -> Result<GpuBackend> {
        Self::new(GpuContext::new()?)
    }

    /// A backend on `ctx` with [`DEFAULT_INITIAL_CAPACITY`] surfel slots.
    ///
    /// [`Error::Gpu`] when the adapter lacks 64-bit atomics (`project_model`'s packed
    /// `atomicMax`) or enough storage buffers per stage; kernel creation errors likewise.
    pub fn new(ctx: GpuContext) -> Result<GpuBackend> {
        Self::with_initial_capacity(ctx, DEFAULT_INITIAL_CAPACITY)
    }

    /// A backend whose map starts with `capacity` surfel slots (tests force growth with a
    /// tiny value).
    pub fn with_initial_capacity(ctx: GpuContext, capacity: usize) -> Result<GpuBackend> {
        let chunk_surfels = MapBuffers::device_chunk_surfels(&ctx);
        Self::with_map_layout(ctx, capacity, chunk_surfels)
    }

    /// A backend whose map starts with `capacity` surfel slots in chunks of
    /// `chunk_surfels` (a positive multiple of [`BLOCK_SURFELS`], at most what the device
    /// allows; tests use small chunks to run every kernel across chunk boundaries).
    pub fn with_map_layout(
        ctx: GpuContext,
        capacity: usize,
        chunk_surfels: usize,
    ) -> Result<GpuBackend> {
        let block = BLOCK_SURFELS as usize;
        if chunk_surfels == 0
            || chunk_surfels % block != 0
            || chunk_surfels > MapBuffers::device_chunk_surfels(&ctx)
        {
            return Err(Error::Argument(format!(
                "map chunks of {chunk_surfels} surfels: need a positive multiple of {block} \
                 of at most {}",
                MapBuffers::device_chunk_surfels(&ctx)
            )));
        }
        if !ctx.has_int64_atomics() {
            return Err(Error::Gpu(format!(
                "adapter \"{}\" lacks 64-bit atomics (SHADER_INT64 + SHADER_INT64_ATOMIC_MIN_MAX), \
                 which project_model needs; use --backend cpu",
                ctx.adapter_info().name
            )));
        }
        let per_stage = ctx.limits().max_storage_buffers_per_shader_stage;
        if per_stage < MAX_STORAGE_BUFFERS_USED {
            return Err(Error::Gpu(format!(
                "adapter \"{}\" allows {per_stage} storage buffers per shader stage; \
                 compact_scatter needs {MAX_STORAGE_BUFFERS_USED}; use --backend cpu",
                ctx.adapter_info().name
            )));
        }
        let per_stage = ctx.limits().max_storage_textures_per_shader_stage;
        if per_stage < MAX_STORAGE_TEXTURES_USED {
            return Err(Error::Gpu(format!(
                "adapter \"{}\" allows {per_stage} storage textures per shader stage; \
                 predict_model needs {MAX_STORAGE_TEXTURES_USED}; use --backend cpu",
                ctx.adapter_info().name
            )));
        }
        let max_surfels = MapBuffers::max_surfels();
        let capacity = capacity.clamp(1, max_surfels);
        let reduction_workgroups = ctx.reduction_workgroups();
        let system_floats = reduction_workgroups as usize * ICP_SYSTEM_LEN;
        let (kernels, small, map) = ctx.scoped("creating the GPU backend", || {
            let kernels = Kernels::new(&ctx)?;
            let mut partials = GpuArray::new(&ctx, "icp partials", system_floats)?;
            partials.set_len(system_floats);
            let mut counter = GpuArray::new(&ctx, "surfel counter", 1)?;
            counter.set_len(1);
            let mut system = GpuArray::new(&ctx, "icp system", ICP_SYSTEM_LEN)?;
            system.set_len(ICP_SYSTEM_LEN);
            let small = (
                partials,
                system,
                Readback::new(&ctx, "icp system read-back", ICP_SYSTEM_LEN),
                counter,
                Readback::new(&ctx, "surfel counter read-back", 1),
            );
            let map = MapBuffers::new(&ctx, capacity, chunk_surfels)?;
            let mut block_bounds = GpuArray::new(&ctx, "block bounds", bounds_entries(&map))?;
            block_bounds.set_len(bounds_entries(&map));
            Ok((kernels, small, (map, block_bounds)))
        })?;
        let (partials, system, system_readback, counter, counter_readback) = small;
        let (map, block_bounds) = map;
        let icp_final_group = kernels.icp_reduce_final.bind_group(
            &ctx,
            &[
                ("partials", partials.binding()),
                ("system", system.binding()),
            ],
        );
        let uniforms = Uniforms::new(&ctx);
        Ok(GpuBackend {
            ctx,
            kernels,
            uniforms,
            reduction_workgroups,
            partials,
            system,
            system_readback,
            icp_final_group,
            counter,
            counter_readback,
            frame: None,
            map,
            block_bounds,
            bounds_dirty_from: 0,
            fused_view: None,
            count: 0,
            max_surfels,
            bind_groups: None,
            spare_bind_groups: None,
            profiler: None,
            compaction: None,
        })
    }

    /// Caps the map at `max_surfels` surfels (below the device limit): a fusion that might
    /// need more fails with [`Error::Capacity`] (tests use it to force that error).
    pub fn with_max_surfels(mut self, max_surfels: usize) -> GpuBackend {
        self.max_surfels = max_surfels.min(MapBuffers::max_surfels());
        self
    }

    /// Turns on per-kernel timing (GPU timestamps when the device has them, else wall time
    /// per step). Costs a wait after every step: use for profiling, not for throughput.
    pub fn enable_kernel_timing(&mut self) {
        self.profiler = Some(Profiler {
            timer: StageTimer::new(&self.ctx, PROFILED_PASSES_MAX),
            totals: BTreeMap::new(),
        });
    }

    /// Per-kernel totals since timing was enabled: name -> (passes, milliseconds). In
    /// wall-time mode (no timestamp queries) the entry is `"all stages"` per submission.
    pub fn kernel_times(&self) -> BTreeMap<String, (u64, f64)> {
        self.profiler
            .as_ref()
            .map(|p| p.totals.clone())
            .unwrap_or_default()
    }

    /// The context (device, queue, limits, byte counters).
    pub fn ctx(&self) -> &GpuContext {
        &self.ctx
    }

    /// Allocated surfel slots.
    pub fn capacity(&self) -> usize {
        self.map.capacity()
    }

    /// Chunks the map is made of (see [`MapBuffers`]).
    pub fn map_chunks(&self) -> usize {
        self.map.chunks.len()
    }

    /// The cap set by [`GpuBackend::with_max_surfels`] or the device limit.
    pub fn max_surfels(&self) -> usize {
        self.max_surfels
    }

    /// Workgroups `icp_reduce` is dispatched with (partial systems per iteration).
    pub fn reduction_workgroups(&self) -> u32 {
        self.reduction_workgroups
    }

    /// (Re-)creates the per-frame buffers when the frame size or the pyramid's levels
    /// change.
    fn ensure_frame(&mut self, p: &PreprocessParams, pyramid: &[PyramidLevel]) -> Result<()> {
        if self.frame.as_ref().is_some_and(|f| f.fits(p, pyramid)) {
            return Ok(());
        }
        // A new index map holds no fusion's keys.
        self.fused_view = None;
        self.frame = Some(FrameBuffers::new(&self.ctx, p, pyramid)?);
        self.bind_groups = None;
        self.spare_bind_groups = None;
        Ok(())
    }

    /// Grows the map (its last chunk x1.5 keeping contents, then new chunks) and the block
    /// boxes so `needed` surfels fit, or [`Error::Capacity`] when `needed` exceeds
    /// [`GpuBackend::max_surfels`].
    pub(super) fn ensure_capacity(&mut self, needed: usize) -> Result<()> {
        if needed <= self.capacity() {
            return Ok(());
        }
        if needed > self.max_surfels {
            return Err(Error::Capacity(format!(
                "fusing this frame may need {needed} surfels ({} bytes of map) but the GPU \
                 map is limited to {} surfels ({} bytes; the chunked map indexes at most {})",
                needed * 48,
                self.max_surfels,
                self.max_surfels * 48,
                MapBuffers::max_surfels(),
            )));
        }
        let grown = (self.capacity() * GROWTH_NUM / GROWTH_DEN)
            .max(needed)
            .min(self.max_surfels);
        self.map.grow(&self.ctx, grown, self.count)?;
        self.block_bounds
            .grow(&self.ctx, bounds_entries(&self.map))?;
        self.block_bounds.set_len(bounds_entries(&self.map));
        // The spare map follows the new layout at the next `compact`.
        self.bind_groups = None;
        self.spare_bind_groups = None;
        Ok(())
    }

    /// Allocates the `compact` step's flags, offsets and second map for the current map
    /// layout (first call, or after the map grew). [`Error::Capacity`] when a flag per
    /// surfel slot outgrows the device's storage-buffer binding limit.
    fn ensure_compaction(&mut self) -> Result<()> {
        match self.compaction.as_mut() {
            Some(c) => {
                if c.follow(&self.ctx, &self.map)? {
                    self.spare_bind_groups = None;
                }
            }
            None => {
                self.compaction = Some(Compaction::new(&self.ctx, &self.map)?);
                self.spare_bind_groups = None;
            }
        }
        Ok(())
    }

    /// Builds the bind groups if a buffer changed since they were made.
    fn bind_groups(&mut self) {
        if self.bind_groups.is_none() {
            let resources = Resources {
                uniforms: &self.uniforms,
                frame: self
                    .frame
                    .as_ref()
                    .expect("preprocess() runs before any other step"),
                map: &self.map,
                block_bounds: &self.block_bounds,
                partials: &self.partials,
                counter: &self.counter,
            };
            self.bind_groups = Some(BindGroups::new(&self.ctx, &self.kernels, &resources));
        }
    }

    /// Workgroups for a grid-stride loop over `n` items: one thread each, capped by
    /// [`GpuContext::grid_workgroups_cap`] (few on a CPU adapter; the loop covers the rest).
    fn grid_stride_workgroups(&self, kernel: &Kernel, n: usize) -> u32 {
        kernel.workgroups_for(n).min(self.ctx.grid_workgroups_cap())
    }

    /// Per map chunk, the workgroups of a block-walking kernel (`project_model`,
    /// `fuse_select`, `fuse_merge`, `fuse_prune`: one workgroup per block, capped by
    /// [`GpuContext::block_workgroups_cap`]) and of a grid-stride kernel over the chunk's
    /// live surfels (`compact_flags`, `compact_scatter`) with `kernel`'s workgroup size,
    /// capped like [`GpuBackend::grid_stride_workgroups`].
    fn chunk_workgroups(&self, kernel: &Kernel) -> Vec<(u32, u32)> {
        let (block_cap, cap) = (
            self.ctx.block_workgroups_cap(),
            self.ctx.grid_workgroups_cap(),
        );
        self.map
            .chunks
            .iter()
            .map(|ch| {
                let live = ch.live(self.count);
                let blocks = live.div_ceil(BLOCK_SURFELS as usize) as u32;
                (blocks.min(block_cap), kernel.workgroups_for(live).min(cap))
            })
            .collect()
    }

    /// The `block_bounds` passes, `(chunk, workgroups)`, that recompute the blocks whose
    /// boxes are stale (see `bounds_dirty_from`), one per chunk holding any; writes their
    /// params and marks the boxes fresh. Planned first in every culling step.
    fn stale_bounds_passes(&mut self) -> Vec<(usize, u32)> {
        let from_block = self.bounds_dirty_from / BLOCK_SURFELS as usize;
        let block = BLOCK_SURFELS as usize;
        let mut out = Vec::new();
        if self.bounds_dirty_from < self.count {
            for (c, ch) in self.map.chunks.iter().enumerate() {
                let first = ch.info.base as usize / block;
                let blocks = ch.live(self.count).div_ceil(block);
                let todo = (first + blocks).saturating_sub(from_block.max(first));
                if todo > 0 {
                    let wg = self.grid_stride_workgroups(&self.kernels.block_bounds, todo);
                    out.push((c, wg));
                }
            }
            self.uniforms.bounds.write(
                &self.ctx,
                &BoundsParams::stale(self.count, self.bounds_dirty_from),
            );
        }
        self.bounds_dirty_from = self.count;
        out
    }

    pub(super) fn frame(&self) -> &FrameBuffers {
        self.frame
            .as_ref()
            .expect("preprocess() runs before any other step")
    }
}

/// The workgroups of one step's passes, worked out before its bind groups are lent out.
#[derive(Default)]
struct StepGrid {
    /// The stale block boxes' `block_bounds` passes, `(chunk, workgroups)`.
    bounds: Vec<(usize, u32)>,
    /// Per map chunk, block-walking and grid-stride workgroups (see `chunk_workgroups`).
    chunks: Vec<(u32, u32)>,
    /// Per-pixel kernels at the frame's size, by kernel name.
    image: BTreeMap<&'static str, [u32; 2]>,
    /// Per coarser pyramid level, the grids of the level's kernels, by kernel name.
    levels: Vec<BTreeMap<&'static str, [u32; 2]>>,
}

impl StepGrid {
    fn image(&self, kernel: &str) -> [u32; 2] {
        self.image[kernel]
    }
    fn level(&self, level: usize, kernel: &str) -> [u32; 2] {
        self.levels[level - 1][kernel]
    }
    /// One pass of `kernel` per map chunk with the chunk's block-walking workgroups.
    fn per_block<'a>(&self, kernel: &'a Kernel, groups: &'a [wgpu::BindGroup]) -> Vec<Pass<'a>> {
        groups
            .iter()
            .zip(&self.chunks)
            .map(|(g, &(blocks, _))| (kernel, g, [blocks, 1]))
            .collect()
    }
    /// The `block_bounds` passes over the stale boxes.
    fn bounds<'a>(&self, k: &'a Kernels, bg: &'a BindGroups) -> Vec<Pass<'a>> {
        self.bounds
            .iter()
            .map(|&(c, wg)| (&k.block_bounds, &bg.block_bounds[c], [wg, 1]))
            .collect()
    }
}

/// [`Error::Argument`] unless each pyramid level halves the one before (rounded up), the
/// first level 0's `width` x `height`: the kernels read finer pixel `(2u, 2v)` for coarse
/// pixel `(u, v)` without a bounds check of their own.
fn check_pyramid(width: u32, height: u32, pyramid: &[PyramidLevel]) -> Result<()> {
    let mut fine = (width, height);
    for (l, p) in pyramid.iter().enumerate() {
        let d = &p.down;
        let coarse = (fine.0.div_ceil(2), fine.1.div_ceil(2));
        if (d.fine_width, d.fine_height) != fine
            || (d.width, d.height) != coarse
            || (p.normal.width, p.normal.height) != coarse
        {
            return Err(Error::Argument(format!(
                "pyramid level {}: a {}x{} level (normals {}x{}) made from {}x{} does not halve \
                 the {}x{} level before it",
                l + 1,
                d.width,
                d.height,
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

/// Entries of `block_bounds` for `map`'s slots: a min and a max corner per block.
fn bounds_entries(map: &MapBuffers) -> usize {
    2 * map.capacity().div_ceil(BLOCK_SURFELS as usize)
}

impl Backend for GpuBackend {
    fn name(&self) -> &'static str {
        "gpu"
    }

    fn preprocess(
        &mut self,
        params: &PreprocessParams,
        bilateral: Option<&BilateralParams>,
        normal: &NormalParams,
        pyramid: &[PyramidLevel],
        raw_depth: &[u16],
        raw_rgba: &[u32],
    ) -> Result<()> {
        let raw_n = (params.raw_width * params.raw_height) as usize;
        if raw_depth.len() != raw_n || raw_rgba.len() != raw_n {
            return Err(Error::Argument(format!(
                "frame of {}x{} pixels needs {raw_n} depth and colour values, got {} and {}",
                params.raw_width,
                params.raw_height,
                raw_depth.len(),
                raw_rgba.len()
            )));
        }
        if params.stride == 0
            || params.width * params.stride > params.raw_width
            || params.height * params.stride > params.raw_height
        {
            return Err(Error::Argument(format!(
                "a {}x{} map with stride {} does not fit a {}x{} frame",
                params.width, params.height, params.stride, params.raw_width, params.raw_height
            )));
        }
        check_pyramid(params.width, params.height, pyramid)?;
        self.ensure_frame(params, pyramid)?;
        let ctx = &self.ctx;
        let u = &self.uniforms;
        ctx.scoped("preprocess", || {
            let f = self.frame.as_mut().expect("ensure_frame made it");
            f.raw_depth.upload(ctx, raw_depth)?;
            f.raw_rgba.upload(ctx, raw_rgba)?;
            f.filtered = bilateral.is_some();
            u.preprocess.write(ctx, params);
            if let Some(b) = bilateral {
                u.bilateral.write(ctx, b);
            }
            u.normal.write(ctx, normal);
            for (level, p) in f.levels.iter().zip(pyramid) {
                level.u_pyramid.write(ctx, &p.down);
                level.u_normal.write(ctx, &p.normal);
            }
            Ok(())
        })?;
        let (w, h) = (params.width, params.height);
        let (k, ctx) = (&self.kernels, &self.ctx);
        let grid = StepGrid {
            image: [&k.depth_to_vertex, &k.bilateral_filter, &k.vertex_to_normal]
                .map(|kernel| {
                    (
                        kernel_name(kernel),
                        kernel.grid_workgroups_for_image(ctx, w, h),
                    )
                })
                .into(),
            levels: pyramid
                .iter()
                .map(|p| {
                    let (w, h) = (p.down.width, p.down.height);
                    [&k.pyramid_depth, &k.vertex_to_normal]
                        .map(|kernel| {
                            (
                                kernel_name(kernel),
                                kernel.grid_workgroups_for_image(ctx, w, h),
                            )
                        })
                        .into()
                })
                .collect(),
            ..StepGrid::default()
        };
        let plan = plan::preprocess(bilateral.is_some(), pyramid.len());
        let (ctx, k, bg, profiler) = encoding_parts!(self);
        ctx.scoped("preprocess", || {
            let mut enc = ctx.encoder("preprocess");
            for call in plan {
                let pass: Pass = match call {
                    Call::DepthToVertex => (
                        &k.depth_to_vertex,
                        &bg.depth_to_vertex,
                        grid.image("depth_to_vertex"),
                    ),
                    Call::BilateralFilter => (
                        &k.bilateral_filter,
                        &bg.bilateral_filter,
                        grid.image("bilateral_filter"),
                    ),
                    Call::VertexToNormal { level: 0, filtered } => (
                        &k.vertex_to_normal,
                        match filtered {
                            true => &bg.vertex_to_normal_filtered,
                            false => &bg.vertex_to_normal,
                        },
                        grid.image("vertex_to_normal"),
                    ),
                    Call::VertexToNormal { level, .. } => (
                        &k.vertex_to_normal,
                        &bg.levels[level - 1].vertex_to_normal,
                        grid.level(level, "vertex_to_normal"),
                    ),
                    Call::PyramidDepth { level, filtered } => {
                        let g = &bg.levels[level - 1];
                        (
                            &k.pyramid_depth,
                            match filtered {
                                true => &g.pyramid_depth_filtered,
                                false => &g.pyramid_depth,
                            },
                            grid.level(level, "pyramid_depth"),
                        )
                    }
                    other => unreachable!("{other:?} is not a preprocessing kernel"),
                };
                record_passes(ctx, profiler, &mut enc, &[pass])?;
            }
            submit_profiled(ctx, profiler, enc)
        })
    }

    fn predict(&mut self, params: &ProjectParams, pyramid: &[PyramidLevel]) -> Result<()> {
        let mut params = *params;
        params.surfel_count = self.count as u32;
        let f = self.frame();
        let made: Vec<(u32, u32)> = f.levels.iter().map(|l| (l.width, l.height)).collect();
        let asked: Vec<(u32, u32)> = pyramid
            .iter()
            .map(|l| (l.down.width, l.down.height))
            .collect();
        if made != asked {
            return Err(Error::Argument(format!(
                "predict() asked for pyramid levels {asked:?} but preprocess() made {made:?}"
            )));
        }
        let project = !self.fused_view.is_some_and(|v| v.is_view_of(&params));
        let plan = plan::predict(project, pyramid.len());
        let (k, ctx) = (&self.kernels, &self.ctx);
        let mut grid = StepGrid {
            image: [(
                "predict_model",
                k.predict_model
                    .grid_workgroups_for_image(ctx, f.width, f.height),
            )]
            .into(),
            levels: f
                .levels
                .iter()
                .map(|l| {
                    [(
                        "pyramid_model",
                        k.pyramid_model
                            .grid_workgroups_for_image(ctx, l.width, l.height),
                    )]
                    .into()
                })
                .collect(),
            chunks: self.chunk_workgroups(&self.kernels.project_model),
            ..StepGrid::default()
        };
        if plan.contains(&Call::BlockBounds) {
            grid.bounds = self.stale_bounds_passes();
        }
        let (ctx, k, bg, profiler) = encoding_parts!(self);
        let f = self
            .frame
            .as_ref()
            .expect("preprocess() runs before predict()");
        let u = &self.uniforms;
        ctx.scoped("predict", || {
            u.project.write(ctx, &params);
            let mut enc = ctx.encoder("predict");
            for call in plan {
                let passes = match call {
                    Call::BlockBounds => grid.bounds(k, bg),
                    Call::Clear(Buffer::IndexMap) => {
                        f.index_map.clear(&mut enc);
                        Vec::new()
                    }
                    Call::ProjectModel => grid.per_block(&k.project_model, &bg.project_model),
                    Call::PredictModel => bg
                        .predict_model
                        .iter()
                        .map(|g| (&k.predict_model, g, grid.image("predict_model")))
                        .collect(),
                    Call::PyramidModel { level } => vec![(
                        &k.pyramid_model,
                        &bg.levels[level - 1].pyramid_model,
                        grid.level(level, "pyramid_model"),
                    )],
                    other => unreachable!("{other:?} is not a prediction kernel"),
                };
                record_passes(ctx, profiler, &mut enc, &passes)?;
            }
            submit_profiled(ctx, profiler, enc)
        })
    }

    fn icp_system(&mut self, level: usize, params: &IcpParams) -> Result<[f64; ICP_SYSTEM_LEN]> {
        let levels = 1 + self.frame().levels.len();
        if level >= levels {
            return Err(Error::Argument(format!(
                "ICP at pyramid level {level}, but preprocess() made {levels} level(s)"
            )));
        }
        let wg = self.reduction_workgroups;
        let (ctx, k, bg, profiler) = encoding_parts!(self);
        let group = match level {
            0 => &bg.icp_reduce,
            l => &bg.levels[l - 1].icp_reduce,
        };
        let final_group = &self.icp_final_group;
        let u = &self.uniforms;
        let system = ctx.scoped("icp_reduce", || {
            u.icp.write(ctx, params);
            let mut enc = ctx.encoder("icp_reduce");
            record_passes(
                ctx,
                profiler,
                &mut enc,
                &[
                    (&k.icp_reduce, group, [wg, 1]),
                    (&k.icp_reduce_final, final_group, [1, 1]),
                ],
            )?;
            self.system_readback
                .copy_from(&mut enc, &self.system, ICP_SYSTEM_LEN);
            submit_profiled(ctx, profiler, enc)?;
            self.system_readback.read(ctx)
        })?;
        let mut sys = [0.0f64; ICP_SYSTEM_LEN];
        for (s, &x) in sys.iter_mut().zip(&system) {
            *s = x as f64;
        }
        Ok(sys)
    }

    fn fuse(&mut self, params: &FuseParams) -> Result<usize> {
        let n = self.frame().pixels();
        self.fused_view = None;
        self.ensure_capacity(self.count + n)?;
        let mut params = *params;
        params.surfel_count = self.count as u32;
        params.capacity = self.capacity() as u32;
        let plan = plan::fuse(&params);
        let (f, k, ctx) = (self.frame(), &self.kernels, &self.ctx);
        let mut grid = StepGrid {
            image: [&k.fuse_add, &k.fuse_flags, &k.fuse_merge_chosen]
                .map(|kernel| {
                    (
                        kernel_name(kernel),
                        kernel.grid_workgroups_for_image(ctx, f.width, f.height),
                    )
                })
                .into(),
            chunks: self.chunk_workgroups(&self.kernels.fuse_merge),
            ..StepGrid::default()
        };
        if plan.contains(&Call::BlockBounds) {
            grid.bounds = self.stale_bounds_passes();
        }
        let (ctx, k, bg, profiler) = encoding_parts!(self);
        let f = self
            .frame
            .as_ref()
            .expect("preprocess() runs before fuse()");
        let u = &self.uniforms;
        let added = ctx.scoped("fuse", || {
            u.fuse.write(ctx, &params);
            u.fuse_scan.write(ctx, &scan_params(f.add_flags.len()));
            let mut enc = ctx.encoder("fuse");
            for call in plan {
                let passes = match call {
                    Call::Clear(Buffer::Assoc) => {
                        f.assoc.clear(&mut enc);
                        Vec::new()
                    }
                    Call::Clear(Buffer::Merged) => {
                        f.merged.clear(&mut enc);
                        Vec::new()
                    }
                    Call::Clear(Buffer::IndexMap) => {
                        f.index_map.clear(&mut enc);
                        Vec::new()
                    }
                    Call::BlockBounds => grid.bounds(k, bg),
                    // Surfels pick pixels, then each picked surfel merges from its pixel.
                    Call::FuseSelect => grid.per_block(&k.fuse_select, &bg.fuse_select),
                    Call::FuseMergeChosen => bg
                        .fuse_merge_chosen
                        .iter()
                        .map(|g| (&k.fuse_merge_chosen, g, grid.image("fuse_merge_chosen")))
                        .collect(),
                    Call::FusePrune => grid.per_block(&k.fuse_prune, &bg.fuse_prune),
                    Call::FuseMerge => grid.per_block(&k.fuse_merge, &bg.fuse_merge),
                    Call::FuseFlags => {
                        vec![(&k.fuse_flags, &bg.fuse_flags, grid.image("fuse_flags"))]
                    }
                    Call::FuseScan => vec![(&k.prefix_sum, &bg.fuse_scan, [1, 1])],
                    Call::FuseAdd => bg
                        .fuse_add
                        .iter()
                        .map(|g| (&k.fuse_add, g, grid.image("fuse_add")))
                        .collect(),
                    other => unreachable!("{other:?} is not a fusion kernel"),
                };
                record_passes(ctx, profiler, &mut enc, &passes)?;
            }
            self.counter_readback.copy_from(&mut enc, &self.counter, 1);
            submit_profiled(ctx, profiler, enc)?;
            self.counter_readback.read(ctx)
        })?[0] as usize;
        let total = self.count + added;
        if total > params.capacity as usize {
            return Err(Error::Capacity(format!(
                "fusion added {added} surfels to {} but only {} slots exist; surfels past \
                 the capacity were dropped (the host should have grown the map first)",
                self.count, params.capacity
            )));
        }
        // The blocks from the one that held the old last surfel on have new surfels.
        self.bounds_dirty_from = self.bounds_dirty_from.min(self.count);
        self.count = total;
        self.fused_view = FusedView::of_fuse(&params);
        Ok(total)
    }

    fn compact(&mut self, params: &CompactParams) -> Result<usize> {
        let n = self.count;
        if n == 0 {
            return Ok(0);
        }
        self.ensure_compaction()?;
        let mut params = *params;
        params.surfel_count = n as u32;
        let flags_wg = self.chunk_workgroups(&self.kernels.compact_flags);
        let scatter_wg = self.chunk_workgroups(&self.kernels.compact_scatter);
        let (ctx, k, u) = (&self.ctx, &self.kernels, &self.uniforms);
        let c = self.compaction.as_mut().expect("ensure_compaction made it");
        // Made once per map set (live and spare swap every call, and so do these).
        if c.groups.is_none() {
            c.groups = Some(CompactionGroups::new(
                ctx,
                k,
                u,
                &self.counter,
                &self.map,
                c,
            ));
        }
        let g = c.groups.as_ref().expect("just made");
        let profiler = &mut self.profiler;
        let kept = ctx.scoped("compact", || {
            u.compact.write(ctx, &params);
            let mut enc = ctx.encoder("compact");
            for call in plan::compact() {
                let passes: Vec<Pass> = match call {
                    Call::CompactFlags => g
                        .flags
                        .iter()
                        .zip(&flags_wg)
                        .map(|(group, &(_, wg))| (&k.compact_flags, group, [wg, 1]))
                        .collect(),
                    Call::CompactScan => vec![(&k.prefix_sum, &g.scan, [1, 1])],
                    Call::CompactScatter => scatter_wg
                        .iter()
                        .enumerate()
                        .flat_map(|(s, &(_, wg))| {
                            (0..=s).map(move |d| {
                                (&k.compact_scatter, &g.scatter[s * (s + 1) / 2 + d], [wg, 1])
                            })
                        })
                        .collect(),
                    other => unreachable!("{other:?} is not a compaction kernel"),
                };
                record_passes(ctx, profiler, &mut enc, &passes)?;
            }
            self.counter_readback.copy_from(&mut enc, &self.counter, 1);
            submit_profiled(ctx, profiler, enc)?;
            self.counter_readback.read(ctx)
        })?[0] as usize;
        if kept > n {
            return Err(Error::Gpu(format!(
                "prefix_sum kept {kept} of {n} surfels (an internal contract)"
            )));
        }
        let c = self.compaction.as_mut().expect("ensure_compaction made it");
        std::mem::swap(&mut self.map, &mut c.spare);
        std::mem::swap(&mut c.groups, &mut c.spare_groups);
        std::mem::swap(&mut self.bind_groups, &mut self.spare_bind_groups);
        self.count = kept;
        // Every surfel may have moved to another block, and to another index.
        self.bounds_dirty_from = 0;
        self.fused_view = None;
        Ok(kept)
    }

    fn surfel_count(&self) -> usize {
        self.count
    }

    fn finish(&mut self) -> Result<()> {
        self.ctx.wait_idle()
    }
}

/// A kernel's name as the `'static` key of a [`StepGrid`] map.
fn kernel_name(kernel: &Kernel) -> &'static str {
    crate::gpu::shaders::KERNELS
        .iter()
        .map(|(name, _)| *name)
        .find(|name| *name == kernel.name)
        .expect("every kernel is in shaders::KERNELS")
}
