//! The GPU backend: runs the dense-SLAM steps of [`wgslam_core::backend::Backend`] as the
//! WGSL kernels in `shaders/`, each the twin of a CPU function in `crates/core/src/cpu/`, in the order
//! of each step's plan (`wgslam_core::plan`, shared with the CPU backend): one compute
//! pass per planned kernel (one per map chunk for the kernels that walk the map), one
//! command buffer per step: submitted at once by the steps whose results the host reads,
//! deferred to the next submission by `preprocess` and `predict` (see `super::steps`).
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
//! `block_boxes`: the culling kernels skip the blocks the camera cannot see, `fuse_merge`
//! grows a box a merge moved a surfel out of, and `block_bounds` recomputes the boxes of the
//! blocks fusion appended to (all of them after a compaction or an upload) at the start of
//! the next culling step.
//! Every pipeline, uniform and small buffer is created once in [`GpuBackend::new`]; the
//! frame's buffers at the first `preprocess` (again only if the frame size changes); the
//! surfel map lives on the GPU for the whole run and grows before a fusion could overflow
//! it (its last chunk x1.5 by a GPU-side copy, then new chunks). Per frame the host reads
//! back only the ICP system (per iteration, `icp_reduce`'s per-workgroup partials summed on
//! the GPU by `icp_reduce_final`'s fixed tree: 29 floats, 116 bytes), the candidate counts,
//! the 4-byte surfel counter and the fern codes.
//! The `compact` step's flags, offsets and second map (`Compaction`) are allocated at its
//! first call and follow the map as it grows; after it the two map sets swap (and so do
//! their bind groups).
//! Not a scheduler: the order of steps is `pipeline::Slam`'s.

use super::bind_groups::{BindGroups, Resources};
use super::buffers::{GpuArray, Readback};
use super::compaction::Compaction;
use super::context::GpuContext;
use super::map_buffers::MapBuffers;
use super::pipelines::Kernels;
use super::recording::{Profiler, PROFILED_PASSES_MAX};
use super::resources::{FrameBuffers, Systems, Uniforms};
use super::timing::StageTimer;
use crate::layout::{BoundsParams, DeformNode, PreprocessParams, BLOCK_SURFELS, ICP_SYSTEM_LEN};
use crate::{Error, Result};
use std::collections::BTreeMap;
use wgslam_core::backend::PyramidLevel;
use wgslam_core::fused_view::FusedView;

/// Builds the bind groups if a buffer changed, then lends what a step needs to encode and
/// submit its passes: `(ctx, kernels, bind groups, profiler, frame buffers, uniforms)`. A
/// macro rather than a method so the borrows stay per field: the step still reads its
/// read-backs (and its own buffers) while the profiler is borrowed mutably. Used by
/// `super::steps` and `super::single_steps` (hence `#[macro_use]` on this module).
macro_rules! encoding_parts {
    ($backend:ident) => {{
        $backend.bind_groups();
        (
            &$backend.ctx,
            &$backend.kernels,
            $backend.bind_groups.as_ref().expect("just built"),
            &mut $backend.profiler,
            $backend
                .frame
                .as_ref()
                .expect("preprocess() runs before any other step"),
            &$backend.uniforms,
        )
    }};
}

// Packed RGBA8 u32s are uploaded as rgba8uint texels (r in the low byte) and the u64
// index map is read as vec2<u32> (low word first): both assume a little-endian host, like
// every platform wgpu runs on.
#[cfg(target_endian = "big")]
compile_error!("the GPU backend assumes a little-endian host (u32/u64 data read as bytes/words)");

/// Surfel slots allocated up front: a little over three 320x240 frames, ~10 MB.
pub const DEFAULT_INITIAL_CAPACITY: usize = 256 * 1024;
/// Nodes the loop closure's node table holds before its first growth (a few KB).
const DEFORM_NODES_INITIAL: usize = 64;
/// Growth factor of the map buffers when a frame might not fit.
const GROWTH_NUM: usize = 3;
const GROWTH_DEN: usize = 2;
/// Storage buffers bound at once by the largest kernels (`fuse_select`, `fuse_add`,
/// `fuse_merge_chosen`): WebGPU's default of 8 per shader stage.
const MAX_STORAGE_BUFFERS_USED: u32 = 8;
/// Storage textures bound at once by the largest kernel (`depth_to_vertex`,
/// `predict_model`: two maps).
const MAX_STORAGE_TEXTURES_USED: u32 = 2;

/// Runs the pipeline's steps on a GPU through wgpu. See the module header.
pub struct GpuBackend {
    pub(super) ctx: GpuContext,
    pub(super) kernels: Kernels,
    pub(super) uniforms: Uniforms,
    pub(super) reduction_workgroups: u32,
    pub(super) counter: GpuArray<u32>,
    pub(super) counter_readback: Readback<u32>,
    /// ICP's and RGB-D tracking's systems: per system its partials and their sum, the one
    /// read-back per ICP iteration.
    pub(super) systems: Systems,
    pub(super) frame: Option<FrameBuffers>,
    pub(super) map: MapBuffers,
    /// Per culling block of map slots, its box: entries `2b` (min) and `2b + 1` (max),
    /// ordered-encoded (see `block_bounds.wgsl`); one buffer for both map sets.
    pub(super) block_boxes: GpuArray<[u32; 4]>,
    /// Blocks from the one holding this surfel index on have stale boxes (fusion appended
    /// to them, or the map was compacted or uploaded); recomputed before the next culling.
    pub(super) bounds_dirty_from: usize,
    /// The view the frame's `index_map` was built at by the last `fuse`, while the map is
    /// as that fusion left it (see [`FusedView`]).
    pub(super) fused_view: Option<FusedView>,
    /// Surfels in the map (the GPU counter as last read back): while the last `fuse`'s
    /// read-back of the surfels it added is pending (`counter_readback.is_requested()`),
    /// the count before that fusion; see [`GpuBackend::settle_count`].
    pub(super) count: usize,
    /// The frame whose raw images the last `fuse` uploaded for `preprocess_staged` (while
    /// they are still in the frame's raw textures).
    pub(super) staged_frame: Option<u32>,
    /// Largest map the backend may allocate, in surfels.
    pub(super) max_surfels: usize,
    /// `None` after any buffer a bind group refers to was re-created.
    pub(super) bind_groups: Option<BindGroups>,
    /// The same for the compaction's spare map set: `compact` swaps the map with the
    /// spare and these with `bind_groups`, so no bind group is made per frame.
    pub(super) spare_bind_groups: Option<BindGroups>,
    /// Per-kernel timing, off unless [`GpuBackend::enable_kernel_timing`] was called.
    pub(super) profiler: Option<Profiler>,
    /// Buffers of the `compact` step, `None` until its first call.
    pub(super) compaction: Option<Compaction>,
    /// Buffers of `fern_encode`, `None` until its first call.
    pub(super) ferns: Option<super::ferns::FernBuffers>,
    /// Buffers of the candidate count, `None` until its first call.
    pub(super) candidates: Option<super::candidates::CandidateBuffers>,
    /// Buffers of the keypoint kernels, `None` until their first call.
    pub(super) keypoints: Option<super::keypoints::KeypointBuffers>,
    /// A loop closure's node table (`deform_surfels`' `nodes`), grown to the next power
    /// of two when a closure needs more nodes (the bind groups are then re-made).
    pub(super) deform_nodes: GpuArray<DeformNode>,
}

impl GpuBackend {
    /// Opens the GPU ([`GpuContext::new`]: logs the adapter; [`Error::NoAdapter`] without
    /// one) and builds a backend on it: what `--backend gpu` needs.
    pub fn open() -> Result<GpuBackend> {
        Self::new(GpuContext::new()?)
    }

    /// A backend on `ctx` with [`DEFAULT_INITIAL_CAPACITY`] surfel slots.
    ///
    /// [`Error::Gpu`] when the adapter allows too few storage buffers or textures per stage
    /// (WebGPU's defaults suffice); kernel creation errors likewise. Without 64-bit atomics
    /// the key kernels are the portable ones ([`crate::kernel::KeyKernel`]).
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
        let limits = ctx.limits();
        for (per_stage, needed, what, who) in [
            (
                limits.max_storage_buffers_per_shader_stage,
                MAX_STORAGE_BUFFERS_USED,
                "buffers",
                "the fusion kernels need",
            ),
            (
                limits.max_storage_textures_per_shader_stage,
                MAX_STORAGE_TEXTURES_USED,
                "textures",
                "the prediction kernel needs",
            ),
        ] {
            if per_stage < needed {
                return Err(Error::Gpu(format!(
                    "adapter \"{}\" allows {per_stage} storage {what} per shader stage; \
                     {who} {needed}; use --backend cpu",
                    ctx.adapter_info().name
                )));
            }
        }
        let max_surfels = MapBuffers::max_surfels();
        let capacity = capacity.clamp(1, max_surfels);
        let reduction_workgroups = ctx.reduction_workgroups();
        let system_floats = reduction_workgroups as usize * ICP_SYSTEM_LEN;
        let (kernels, small, map) = ctx.scoped("creating the GPU backend", || {
            let kernels = Kernels::new(&ctx)?;
            let mut counter = GpuArray::new(&ctx, "surfel counter", 1)?;
            counter.set_len(1);
            let small = (
                Systems::new(&ctx, system_floats)?,
                counter,
                Readback::new(&ctx, "surfel counter read-back", 1),
            );
            let map = MapBuffers::new(&ctx, capacity, chunk_surfels)?;
            let nodes = GpuArray::new(&ctx, "deformation nodes", DEFORM_NODES_INITIAL)?;
            let mut block_boxes = GpuArray::new(&ctx, "block bounds", bounds_entries(&map))?;
            block_boxes.set_len(bounds_entries(&map));
            Ok((kernels, (small, nodes), (map, block_boxes)))
        })?;
        let ((systems, counter, counter_readback), deform_nodes) = small;
        let (map, block_boxes) = map;
        let uniforms = Uniforms::new(&ctx);
        Ok(GpuBackend {
            ctx,
            kernels,
            uniforms,
            reduction_workgroups,
            systems,
            counter,
            counter_readback,
            frame: None,
            map,
            block_boxes,
            bounds_dirty_from: 0,
            fused_view: None,
            count: 0,
            staged_frame: None,
            max_surfels,
            bind_groups: None,
            spare_bind_groups: None,
            profiler: None,
            compaction: None,
            ferns: None,
            candidates: None,
            keypoints: None,
            deform_nodes,
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

    /// The map's surfel count, after reading the surfels the last `fuse` added when that
    /// read-back is pending: at no wait when a later wait (the next frame's ICP
    /// iterations') covered the fusion, else after waiting for it. Every step that needs
    /// the count calls this first; the frame loop of a tracked frame never waits here.
    /// [`Error::Capacity`] when the fusion added more than the map's slots (an internal
    /// contract: `fuse` grows the map first).
    pub(super) fn settle_count(&mut self) -> Result<usize> {
        if self.counter_readback.is_requested() {
            let ctx = &self.ctx;
            let rb = &mut self.counter_readback;
            let added = ctx.scoped("fuse", || rb.take(ctx))?[0] as usize;
            let total = self.count + added;
            if total > self.capacity() {
                return Err(Error::Capacity(format!(
                    "fusion added {added} surfels to {} but only {} slots exist; surfels \
                     past the capacity were dropped (the host should have grown the map \
                     first)",
                    self.count,
                    self.capacity()
                )));
            }
            self.count = total;
        }
        Ok(self.count)
    }

    /// Debug builds: panics when the last fusion's count is still pending, in a helper
    /// that reads `count` (its caller should have called [`GpuBackend::settle_count`]).
    fn debug_assert_count_settled(&self) {
        debug_assert!(
            !self.counter_readback.is_requested(),
            "a count a fusion left pending"
        );
    }

    /// (Re-)creates the per-frame buffers when the frame size or the pyramid's levels
    /// change.
    pub(super) fn ensure_frame(
        &mut self,
        p: &PreprocessParams,
        pyramid: &[PyramidLevel],
    ) -> Result<()> {
        if self.frame.as_ref().is_some_and(|f| f.fits(p, pyramid)) {
            return Ok(());
        }
        // A new index map holds no fusion's keys, new raw textures no staged images.
        self.fused_view = None;
        self.staged_frame = None;
        let frame = FrameBuffers::new(&self.ctx, p, pyramid).map_err(|e| match e {
            // Name the image, not an internal array: fusion's per-pixel arrays are in a
            // tiled (Morton) order that pads a long, thin image far beyond its pixels.
            Error::Capacity(why) => Error::Capacity(format!(
                "a {}x{} map does not fit this GPU's frame buffers ({why}); use a smaller \
                 map (--downsample 2 or more, or a less elongated image) or --backend cpu",
                p.camera.width, p.camera.height
            )),
            other => other,
        })?;
        self.frame = Some(frame);
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
        self.block_boxes
            .grow(&self.ctx, bounds_entries(&self.map))?;
        self.block_boxes.set_len(bounds_entries(&self.map));
        // The spare map follows the new layout at the next `compact`.
        self.bind_groups = None;
        self.spare_bind_groups = None;
        Ok(())
    }

    /// Allocates the `compact` step's flags, offsets and second map for the current map
    /// layout (first call, or after the map grew). [`Error::Capacity`] when a flag per
    /// surfel slot outgrows the device's storage-buffer binding limit.
    pub(super) fn ensure_compaction(&mut self) -> Result<()> {
        let remade = match self.compaction.as_mut() {
            Some(c) => c.follow(&self.ctx, &self.map)?,
            None => {
                self.compaction = Some(Compaction::new(&self.ctx, &self.map)?);
                true
            }
        };
        if remade {
            // Both map sets' bind groups bind the keep flags and offsets, and each the
            // other's map (the copy of the survivors writes into it).
            self.drop_bind_groups();
        }
        Ok(())
    }

    /// Drops both map sets' bind groups: a buffer they bind was made or re-made.
    pub(super) fn drop_bind_groups(&mut self) {
        self.bind_groups = None;
        self.spare_bind_groups = None;
    }

    /// Builds the bind groups if a buffer changed since they were made.
    pub(super) fn bind_groups(&mut self) {
        if self.bind_groups.is_none() {
            let resources = Resources {
                uniforms: &self.uniforms,
                frame: self.frame.as_ref(),
                map: &self.map,
                nodes: &self.deform_nodes,
                compaction: super::compaction::bindings(self.compaction.as_ref()),
                spare: self.compaction.as_ref().map(|c| &c.spare),
                steps: [
                    super::ferns::bindings(self.ferns.as_ref()),
                    super::keypoints::bindings(self.keypoints.as_ref()),
                    super::candidates::bindings(self.candidates.as_ref()),
                ]
                .concat(),
                block_boxes: &self.block_boxes,
                systems: &self.systems.buffers,
                counter: &self.counter,
            };
            self.bind_groups = Some(BindGroups::new(&self.ctx, &self.kernels, &resources));
        }
    }

    /// Per map chunk, the workgroups of a block-walking kernel (`project_model`,
    /// `fuse_select`, `fuse_merge`, `fuse_prune`: one workgroup per block holding live
    /// surfels, capped by [`GpuContext::block_workgroups_cap`]).
    pub(super) fn chunk_blocks(&self) -> Vec<u32> {
        self.debug_assert_count_settled();
        let cap = self.ctx.block_workgroups_cap();
        self.map
            .chunks
            .iter()
            .map(|ch| {
                let blocks = ch.live(self.count).div_ceil(BLOCK_SURFELS as usize) as u32;
                blocks.min(cap)
            })
            .collect()
    }

    /// Per map chunk, its live surfels (a `PerSurfel` or `PerChunkPair` row's passes:
    /// `StepGrid::live`).
    pub(super) fn chunk_live(&self) -> Vec<usize> {
        self.debug_assert_count_settled();
        self.map
            .chunks
            .iter()
            .map(|ch| ch.live(self.count))
            .collect()
    }

    /// The `block_bounds` passes, `(chunk, workgroups)`, that recompute the blocks whose
    /// boxes are stale (see `bounds_dirty_from`), one per chunk holding any; writes their
    /// params and marks the boxes fresh. Planned first in every culling step.
    pub(super) fn stale_bounds_passes(&mut self) -> Vec<(usize, u32)> {
        self.debug_assert_count_settled();
        let from_block = self.bounds_dirty_from / BLOCK_SURFELS as usize;
        let block = BLOCK_SURFELS as usize;
        let mut out = Vec::new();
        if self.bounds_dirty_from < self.count {
            for (c, ch) in self.map.chunks.iter().enumerate() {
                let first = ch.info.base as usize / block;
                let blocks = ch.live(self.count).div_ceil(block);
                let todo = (first + blocks).saturating_sub(from_block.max(first));
                if todo > 0 {
                    // One workgroup per stale block (block_bounds.wgsl), capped.
                    let wg = (todo as u32).min(self.ctx.block_workgroups_cap());
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

/// Entries of `block_boxes` for `map`'s slots: a min and a max corner per block.
fn bounds_entries(map: &MapBuffers) -> usize {
    2 * map.capacity().div_ceil(BLOCK_SURFELS as usize)
}
