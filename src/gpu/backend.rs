//! The GPU backend: runs the dense-SLAM steps of [`crate::slam::backend::Backend`] as the WGSL
//! kernels in `shaders/`, each the twin of a CPU function in `src/cpu/`.
//!
//! Per-pixel maps (raw inputs, vertex / filtered-vertex / normal / colour maps, the
//! prediction) are 2D textures ([`GpuImage`]): kernels read them with `textureLoad` and
//! write them as storage textures, which lavapipe loads 3-5x faster than storage-buffer
//! elements (`examples/lavapipe_loads.rs`).
//! The frame's normal map carries the vertex's depth in w (`normal_depth`), so the kernels
//! that associate with the frame fetch one texel and rebuild the vertex (see
//! vertex_to_normal.wgsl), as does the twin; `download_frame` reads it as it is.
//! The surfel map is chunks of three storage buffers each ([`MapBuffers`]), and every kernel
//! that walks it is recorded once per chunk, with bind groups made per chunk; the index
//! map, the association flags, the counter and the ICP partials are storage buffers too
//! (atomics). Each block of [`BLOCK_SURFELS`] map slots has a world-frame box in
//! `block_bounds`: `project_model`, `fuse_select` and `fuse_merge` skip the blocks the
//! camera cannot see, `fuse_merge` grows a box a merge moved a surfel out of, and
//! `block_bounds` recomputes the boxes of the blocks fusion appended to (all of them after
//! a compaction or an upload) at the start of the next `predict` or `fuse` submission.
//! Every pipeline, uniform and small buffer is created once in [`GpuBackend::new`]; the
//! per-frame textures are sized at the first `preprocess` and reused (re-created only if the
//! frame size changes); the surfel map lives on the GPU for the whole run and grows before
//! a fusion could overflow it (its last chunk x1.5 by a GPU-side copy, then new chunks). Per frame the
//! host reads back only the ICP system (per iteration, `icp_reduce`'s per-workgroup
//! partials summed on the GPU by `icp_reduce_final`: 29 floats, 116 bytes) and the 4-byte
//! surfel counter; maps are downloaded only on request.
//! With the bilateral filter on, `preprocess` runs three kernels and `vertex_to_normal`
//! reads the filtered-vertex texture through a second bind group; the unfiltered vertex
//! texture is kept (the filtered one is allocated either way, one frame map's worth).
//! The `compact` step (robust profile) runs `compact_flags`, `prefix_sum` and
//! `compact_scatter` in one submission and reads back only the 4-byte counter that
//! `prefix_sum` writes; its flags, offsets (one `u32` per surfel slot, storage buffers) and
//! second map of the same chunk sizes are allocated at its first call and follow the map
//! as it grows; `compact_scatter` runs once per (input chunk, output chunk) pair, and after
//! it the two map sets swap (and so do their bind groups).
//! The ICP pyramid's coarser levels (a schedule of more than one level) are textures of
//! their own (`LevelBuffers`: the frame's vertex and normal-depth maps, the model's
//! predicted maps, and their `pyramid_depth` / `vertex_to_normal` uniforms), made with the
//! frame's other buffers, with their bind groups (`pyramid_depth` from level 0's filtered or
//! unfiltered vertex map, `vertex_to_normal`, `pyramid_model`, and `icp_reduce` bound to
//! the level's maps) built once with the rest. `preprocess` records every level's two
//! passes in its one submission, `predict` one `pyramid_model` pass per level in its own;
//! `icp_system` at level `l` dispatches the same `icp_reduce` pipeline with level `l`'s
//! bind group and the level's size and intrinsics in the uniform.
//! Not a scheduler: the order of steps is `pipeline::Slam`'s.

use std::collections::BTreeMap;

use super::buffers::{GpuArray, ParamBuffer, Readback};
use super::context::GpuContext;
use super::images::GpuImage;
use super::kernel::{Binding, Kernel};
use super::map_buffers::MapBuffers;
use super::timing::StageTimer;
use crate::layout::{append_slots, scan_params};
use crate::layout::{
    BilateralParams, BoundsParams, CompactParams, FuseParams, IcpParams, NormalParams,
    PreprocessParams, ProjectParams, PyramidParams, ASSOCIATION_BEST_CANDIDATE, BLOCK_SURFELS,
    ICP_SYSTEM_LEN,
};
use crate::slam::backend::{
    Backend, BackendCounters, FrameLevel, FrameMaps, Inspect, Prediction, PyramidLevel,
};
use crate::slam::fused_view::FusedView;
use crate::slam::map::SurfelMap;
use crate::{Error, Result};

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
/// Passes one submission may time when profiling (a few per map chunk and pyramid level).
const PROFILED_PASSES_MAX: u32 = 64;

/// Bindings of each dense-SLAM kernel, in the order of its CPU twin's arguments
/// (`@binding(i)`); `kernel::layout_entries` turns them into the layout.
pub mod bindings {
    use super::Binding;
    pub const DEPTH_TO_VERTEX: [Binding; 5] = [
        Binding::params("params: PreprocessParams"),
        Binding::texture_u32("raw_depth: r16uint"),
        Binding::texture_u32("raw_rgba: rgba8uint"),
        Binding::write_texture("vertex_map: camera frame"),
        Binding::write_texture("color_map: RGB 0..255"),
    ];
    pub const BILATERAL_FILTER: [Binding; 3] = [
        Binding::params("params: BilateralParams"),
        Binding::texture_f32("vertex_map: camera frame, unfiltered"),
        Binding::write_texture("filtered_vertex: camera frame"),
    ];
    pub const VERTEX_TO_NORMAL: [Binding; 3] = [
        Binding::params("params: NormalParams"),
        Binding::texture_f32("vertex_map: camera frame (filtered_vertex with the filter)"),
        Binding::write_texture("normal_depth: camera-frame normal, w = depth"),
    ];
    pub const PYRAMID_DEPTH: [Binding; 3] = [
        Binding::params("params: PyramidParams"),
        Binding::texture_f32("fine_vertex: camera frame, the finer level"),
        Binding::write_texture("coarse_vertex: camera frame"),
    ];
    pub const PYRAMID_MODEL: [Binding; 5] = [
        Binding::params("params: PyramidParams"),
        Binding::texture_f32("fine_vertex: the finer level's pred_vertex, world frame"),
        Binding::texture_f32("fine_normal: the finer level's pred_normal, world frame"),
        Binding::write_texture("coarse_vertex: world frame"),
        Binding::write_texture("coarse_normal: world frame"),
    ];
    pub const BLOCK_BOUNDS: [Binding; 4] = [
        Binding::params("params: BoundsParams"),
        Binding::params("chunk: MapChunk"),
        Binding::read("position_weight: the chunk's, world frame"),
        Binding::read_write("block_bounds: min/max corner per block"),
    ];
    pub const PROJECT_MODEL: [Binding; 5] = [
        Binding::params("params: ProjectParams"),
        Binding::params("chunk: MapChunk"),
        Binding::read("block_bounds: min/max corner per block"),
        Binding::read("position_weight: the chunk's, world frame"),
        Binding::read_write("index_map: atomic u64 keys"),
    ];
    pub const PREDICT_MODEL: [Binding; 7] = [
        Binding::params("params: ProjectParams"),
        Binding::read("index_map: u64 keys as vec2<u32>"),
        Binding::params("chunk: MapChunk"),
        Binding::read("position_weight: the chunk's, world frame"),
        Binding::read("normal_frame: the chunk's normal bits"),
        Binding::write_texture("pred_vertex: world frame"),
        Binding::write_texture("pred_normal: world frame"),
    ];
    pub const ICP_REDUCE: [Binding; 5] = [
        Binding::params("params: IcpParams"),
        Binding::texture_f32("pred_vertex: source, world frame"),
        Binding::texture_f32("pred_normal: source normals, world frame"),
        Binding::texture_f32("normal_depth: target, camera frame, w = depth"),
        Binding::read_write("partials: 29 f32 per workgroup"),
    ];
    pub const ICP_REDUCE_FINAL: [Binding; 2] = [
        Binding::read("partials: 29 f32 per icp_reduce workgroup"),
        Binding::read_write("system: the 29 summed f32"),
    ];
    pub const FUSE_SELECT: [Binding; 9] = [
        Binding::params("params: FuseParams"),
        Binding::texture_f32("normal_depth: camera frame, w = depth"),
        Binding::params("chunk: MapChunk"),
        Binding::read("block_bounds: min/max corner per block"),
        Binding::read("position_weight: w = confidence"),
        Binding::read("normal_frame: w = last_frame"),
        Binding::read("color: a = radius"),
        Binding::read_write("assoc: atomic u64 key per pixel"),
        Binding::read_write("index_map: the next prediction's atomic u64 keys"),
    ];
    pub const FUSE_MERGE: [Binding; 9] = [
        Binding::params("params: FuseParams"),
        Binding::texture_f32("normal_depth: camera frame, w = depth"),
        Binding::texture_f32("color_map"),
        Binding::params("chunk: MapChunk"),
        Binding::read_write("block_bounds: atomic min/max words per block"),
        Binding::read_write("position_weight"),
        Binding::read_write("normal_frame"),
        Binding::read_write("color"),
        Binding::read_write("assoc: atomic u64 key per pixel"),
    ];
    pub const FUSE_MERGE_CHOSEN: [Binding; 10] = [
        Binding::params("params: FuseParams"),
        Binding::texture_f32("normal_depth: camera frame, w = depth"),
        Binding::texture_f32("color_map"),
        Binding::params("chunk: MapChunk"),
        Binding::read_write("block_bounds: atomic min/max words per block"),
        Binding::read_write("position_weight"),
        Binding::read_write("normal_frame"),
        Binding::read_write("color"),
        Binding::read("assoc: fuse_select's u64 key per pixel"),
        Binding::read_write("merged: the merged surfel per pixel"),
    ];
    pub const FUSE_PRUNE: [Binding; 7] = [
        Binding::params("params: FuseParams"),
        Binding::params("chunk: MapChunk"),
        Binding::read("block_bounds: min/max corner per block"),
        Binding::read_write("position_weight"),
        Binding::read_write("normal_frame"),
        Binding::read("color: a = radius"),
        Binding::read("merged: the merged surfel per pixel"),
    ];
    pub const FUSE_FLAGS: [Binding; 5] = [
        Binding::params("params: FuseParams"),
        Binding::texture_f32("normal_depth: camera frame, w = depth"),
        Binding::read("assoc: u64 key per pixel"),
        Binding::read("merged: the merged surfel per pixel"),
        Binding::read_write("flags: 1 new surfel / 0 per pixel"),
    ];
    pub const FUSE_ADD: [Binding; 10] = [
        Binding::params("params: FuseParams"),
        Binding::texture_f32("normal_depth: camera frame, w = depth"),
        Binding::texture_f32("color_map"),
        Binding::read("flags: new surfel per pixel"),
        Binding::read("offsets: prefix sum of flags"),
        Binding::params("chunk: MapChunk"),
        Binding::read_write("position_weight"),
        Binding::read_write("normal_frame"),
        Binding::read_write("color"),
        Binding::read_write("index_map: the new surfels' keys (best candidate)"),
    ];
    pub const COMPACT_FLAGS: [Binding; 5] = [
        Binding::params("params: CompactParams"),
        Binding::params("chunk: MapChunk"),
        Binding::read("position_weight: w = weight"),
        Binding::read("normal_frame: w = last_frame"),
        Binding::read_write("flags: 1 keep / 0 remove per surfel"),
    ];
    pub const PREFIX_SUM: [Binding; 4] = [
        Binding::params("params: CompactParams"),
        Binding::read("flags"),
        Binding::read_write("offsets: exclusive prefix sum of flags"),
        Binding::read_write("counter: surfels kept"),
    ];
    pub const COMPACT_SCATTER: [Binding; 11] = [
        Binding::params("params: CompactParams"),
        Binding::read("flags"),
        Binding::read("offsets"),
        Binding::params("chunk: MapChunk, input"),
        Binding::read("position_weight"),
        Binding::read("normal_frame"),
        Binding::read("color"),
        Binding::params("out_chunk: MapChunk, output"),
        Binding::read_write("out_position_weight"),
        Binding::read_write("out_normal_frame"),
        Binding::read_write("out_color"),
    ];
}

struct Kernels {
    depth_to_vertex: Kernel,
    bilateral_filter: Kernel,
    vertex_to_normal: Kernel,
    pyramid_depth: Kernel,
    block_bounds: Kernel,
    project_model: Kernel,
    predict_model: Kernel,
    pyramid_model: Kernel,
    icp_reduce: Kernel,
    icp_reduce_final: Kernel,
    fuse_select: Kernel,
    fuse_merge: Kernel,
    fuse_merge_chosen: Kernel,
    fuse_prune: Kernel,
    fuse_flags: Kernel,
    fuse_add: Kernel,
    compact_flags: Kernel,
    prefix_sum: Kernel,
    compact_scatter: Kernel,
}

/// What the `compact` step needs besides the map, allocated at its first call (the
/// assignment profile never pays for it) and re-allocated when the map grows: one flag and
/// one offset per surfel slot, and a second map of the same chunk sizes that
/// `compact_scatter` writes and that then swaps with the map.
struct Compaction {
    flags: GpuArray<u32>,
    offsets: GpuArray<u32>,
    spare: MapBuffers,
    /// The three passes' bind groups for the live map (`groups`) and for the spare one
    /// (`spare_groups`), made once each and swapped with the maps.
    groups: Option<CompactionGroups>,
    spare_groups: Option<CompactionGroups>,
}

/// Bind groups of `compact_flags` (per chunk), `prefix_sum` and `compact_scatter` (per
/// input chunk and output chunk no later than it) for one map set.
struct CompactionGroups {
    flags: Vec<wgpu::BindGroup>,
    scan: wgpu::BindGroup,
    scatter: Vec<wgpu::BindGroup>,
}

/// Buffers sized by the frame: raw inputs, per-pixel maps, prediction, association flags.
struct FrameBuffers {
    raw_width: u32,
    raw_height: u32,
    width: u32,
    height: u32,
    raw_depth: GpuImage,
    raw_rgba: GpuImage,
    /// `depth_to_vertex`'s output, never filtered.
    vertex: GpuImage,
    /// `bilateral_filter`'s output; meaningful only when `filtered` is set.
    filtered_vertex: GpuImage,
    /// Whether the last `preprocess` ran the filter (and made the normals from
    /// `filtered_vertex`).
    filtered: bool,
    /// The normal map with the vertex's depth in w (see vertex_to_normal.wgsl).
    normal_depth: GpuImage,
    color: GpuImage,
    index_map: GpuArray<u64>,
    pred_vertex: GpuImage,
    pred_normal: GpuImage,
    /// One u64 key per pixel: fuse_select's choice, or fuse_merge's flag.
    assoc: GpuArray<u64>,
    /// Per pixel, the surfel it merged into (two entries; see fuse_merge_chosen.wgsl),
    /// cleared and filled on every frame of best-candidate association (fuse_flags and
    /// fuse_prune read it).
    merged: GpuArray<[f32; 4]>,
    /// Fusion's new-surfel flag and slot offset per pixel (`fuse_flags`, `prefix_sum`), in
    /// append order (`append_slots` entries; see `layout::APPEND_TILE_PX`).
    add_flags: GpuArray<u32>,
    add_offsets: GpuArray<u32>,
    /// The ICP pyramid's coarser levels 1, 2, ... (none with a one-level schedule).
    levels: Vec<LevelBuffers>,
}

/// One coarser level (1, 2, ...) of the ICP pyramid: the frame's and the model's maps at
/// its size, and the uniforms of the kernels that make them (one per level: `preprocess`
/// records every level's passes in one submission, so they cannot share one).
struct LevelBuffers {
    width: u32,
    height: u32,
    /// `pyramid_depth`'s output.
    vertex: GpuImage,
    normal_depth: GpuImage,
    /// `pyramid_model`'s outputs.
    pred_vertex: GpuImage,
    pred_normal: GpuImage,
    u_pyramid: ParamBuffer<PyramidParams>,
    u_normal: ParamBuffer<NormalParams>,
}

impl FrameBuffers {
    fn pixels(&self) -> usize {
        (self.width * self.height) as usize
    }
}

struct BindGroups {
    depth_to_vertex: wgpu::BindGroup,
    bilateral_filter: wgpu::BindGroup,
    /// `vertex_to_normal` reading the unfiltered vertex map (filter off) ...
    vertex_to_normal: wgpu::BindGroup,
    /// ... and reading the filtered one (filter on).
    vertex_to_normal_filtered: wgpu::BindGroup,
    /// The map kernels' bind groups, one per map chunk.
    block_bounds: Vec<wgpu::BindGroup>,
    project_model: Vec<wgpu::BindGroup>,
    predict_model: Vec<wgpu::BindGroup>,
    icp_reduce: wgpu::BindGroup,
    fuse_select: Vec<wgpu::BindGroup>,
    fuse_merge: Vec<wgpu::BindGroup>,
    fuse_merge_chosen: Vec<wgpu::BindGroup>,
    fuse_prune: Vec<wgpu::BindGroup>,
    fuse_flags: wgpu::BindGroup,
    /// `prefix_sum` over the new-surfel flags (in append order, `append_slots` entries).
    fuse_scan: wgpu::BindGroup,
    fuse_add: Vec<wgpu::BindGroup>,
    /// Per coarser pyramid level (1, 2, ...).
    levels: Vec<LevelBindGroups>,
}

/// The bind groups of one coarser pyramid level.
struct LevelBindGroups {
    /// `pyramid_depth` reading the finer level's vertex map: at level 1 the unfiltered
    /// one (filter off) ...
    pyramid_depth: wgpu::BindGroup,
    /// ... or the filtered one (filter on); at levels 2 and up the same as `pyramid_depth`.
    pyramid_depth_filtered: wgpu::BindGroup,
    vertex_to_normal: wgpu::BindGroup,
    pyramid_model: wgpu::BindGroup,
    icp_reduce: wgpu::BindGroup,
}

/// Runs the pipeline's steps on a GPU through wgpu. See the module header.
pub struct GpuBackend {
    ctx: GpuContext,
    kernels: Kernels,
    u_preprocess: ParamBuffer<PreprocessParams>,
    u_bilateral: ParamBuffer<BilateralParams>,
    u_normal: ParamBuffer<NormalParams>,
    u_project: ParamBuffer<ProjectParams>,
    u_icp: ParamBuffer<IcpParams>,
    u_fuse: ParamBuffer<FuseParams>,
    reduction_workgroups: u32,
    partials: GpuArray<f32>,
    /// The summed system (`icp_reduce_final`), the one read-back per ICP iteration.
    system: GpuArray<f32>,
    system_readback: Readback<f32>,
    /// `icp_reduce_final` over `partials` into `system` (neither is ever re-created).
    icp_final_group: wgpu::BindGroup,
    counter: GpuArray<u32>,
    counter_readback: Readback<u32>,
    frame: Option<FrameBuffers>,
    map: MapBuffers,
    /// Per culling block of map slots, its box: entries `2b` (min) and `2b + 1` (max),
    /// ordered-encoded (see `block_bounds.wgsl`); one buffer for both map sets.
    block_bounds: GpuArray<[u32; 4]>,
    /// `block_bounds`' parameters.
    u_bounds: ParamBuffer<BoundsParams>,
    /// Blocks from the one holding this surfel index on have stale boxes (fusion appended
    /// to them, or the map was compacted or uploaded); recomputed before the next culling.
    bounds_dirty_from: usize,
    /// The view the frame's `index_map` was built at by the last `fuse`, while the map is
    /// as that fusion left it (see [`FusedView`]).
    fused_view: Option<FusedView>,
    /// Surfels in the map (the GPU counter as last read back).
    count: usize,
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
    compaction: Option<Compaction>,
    u_compact: ParamBuffer<CompactParams>,
    /// `prefix_sum`'s parameters for fusion's scan over the new-surfel flags.
    u_fuse_scan: ParamBuffer<CompactParams>,
}

/// Per-kernel GPU times: timestamps around each kernel's pass (or wall time without the
/// feature), totalled by kernel name. Reading them waits for the GPU after every step, so
/// it is for profiling runs only.
struct Profiler {
    timer: StageTimer,
    totals: BTreeMap<String, (u64, f64)>,
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

/// Records one compute pass per `(kernel, bind group, [x, y] workgroups)`, timed when
/// profiling.
fn record_passes(
    ctx: &GpuContext,
    profiler: &mut Option<Profiler>,
    enc: &mut wgpu::CommandEncoder,
    dispatches: &[(&Kernel, &wgpu::BindGroup, [u32; 2])],
) -> Result<()> {
    for (kernel, bind_group, workgroups) in dispatches {
        let mut pass = match profiler {
            Some(p) => p.timer.begin_pass(enc, &kernel.name),
            None => enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some(&kernel.name),
                timestamp_writes: None,
            }),
        };
        kernel.dispatch_grid(ctx, &mut pass, bind_group, *workgroups)?;
    }
    Ok(())
}

/// Submits `enc`; when profiling, resolves the timestamps first and adds them to the totals.
fn submit_profiled(
    ctx: &GpuContext,
    profiler: &mut Option<Profiler>,
    mut enc: wgpu::CommandEncoder,
) -> Result<()> {
    match profiler {
        None => {
            ctx.submit(enc);
        }
        Some(p) => {
            p.timer.resolve(&mut enc);
            ctx.submit(enc);
            for t in p.timer.read(ctx)? {
                let e = p.totals.entry(t.name).or_insert((0, 0.0));
                e.0 += 1;
                e.1 += t.ms;
            }
        }
    }
    Ok(())
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
        let (kernels, uniforms, small, map) = ctx.scoped("creating the GPU backend", || {
            let kernels = Kernels {
                depth_to_vertex: Kernel::new(&ctx, "depth_to_vertex", &bindings::DEPTH_TO_VERTEX)?,
                bilateral_filter: Kernel::new(
                    &ctx,
                    "bilateral_filter",
                    &bindings::BILATERAL_FILTER,
                )?,
                vertex_to_normal: Kernel::new(
                    &ctx,
                    "vertex_to_normal",
                    &bindings::VERTEX_TO_NORMAL,
                )?,
                pyramid_depth: Kernel::new(&ctx, "pyramid_depth", &bindings::PYRAMID_DEPTH)?,
                block_bounds: Kernel::new(&ctx, "block_bounds", &bindings::BLOCK_BOUNDS)?,
                project_model: Kernel::new(&ctx, "project_model", &bindings::PROJECT_MODEL)?,
                predict_model: Kernel::new(&ctx, "predict_model", &bindings::PREDICT_MODEL)?,
                pyramid_model: Kernel::new(&ctx, "pyramid_model", &bindings::PYRAMID_MODEL)?,
                icp_reduce: Kernel::new(&ctx, "icp_reduce", &bindings::ICP_REDUCE)?,
                icp_reduce_final: Kernel::new(
                    &ctx,
                    "icp_reduce_final",
                    &bindings::ICP_REDUCE_FINAL,
                )?,
                fuse_select: Kernel::new(&ctx, "fuse_select", &bindings::FUSE_SELECT)?,
                fuse_merge: Kernel::new(&ctx, "fuse_merge", &bindings::FUSE_MERGE)?,
                fuse_merge_chosen: Kernel::new(
                    &ctx,
                    "fuse_merge_chosen",
                    &bindings::FUSE_MERGE_CHOSEN,
                )?,
                fuse_prune: Kernel::new(&ctx, "fuse_prune", &bindings::FUSE_PRUNE)?,
                fuse_flags: Kernel::new(&ctx, "fuse_flags", &bindings::FUSE_FLAGS)?,
                fuse_add: Kernel::new(&ctx, "fuse_add", &bindings::FUSE_ADD)?,
                compact_flags: Kernel::new(&ctx, "compact_flags", &bindings::COMPACT_FLAGS)?,
                prefix_sum: Kernel::new(&ctx, "prefix_sum", &bindings::PREFIX_SUM)?,
                compact_scatter: Kernel::new(&ctx, "compact_scatter", &bindings::COMPACT_SCATTER)?,
            };
            let uniforms = (
                ParamBuffer::new(&ctx, "PreprocessParams", &bytemuck::Zeroable::zeroed()),
                ParamBuffer::new(&ctx, "BilateralParams", &bytemuck::Zeroable::zeroed()),
                ParamBuffer::new(&ctx, "NormalParams", &bytemuck::Zeroable::zeroed()),
                ParamBuffer::new(&ctx, "ProjectParams", &bytemuck::Zeroable::zeroed()),
                ParamBuffer::new(&ctx, "IcpParams", &bytemuck::Zeroable::zeroed()),
                ParamBuffer::new(&ctx, "FuseParams", &bytemuck::Zeroable::zeroed()),
            );
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
            Ok((kernels, uniforms, small, (map, block_bounds)))
        })?;
        let (u_preprocess, u_bilateral, u_normal, u_project, u_icp, u_fuse) = uniforms;
        let (partials, system, system_readback, counter, counter_readback) = small;
        let (map, block_bounds) = map;
        let icp_final_group = kernels
            .icp_reduce_final
            .bind_group(&ctx, &[partials.binding(), system.binding()]);
        let u_compact = ParamBuffer::new(&ctx, "CompactParams", &bytemuck::Zeroable::zeroed());
        let u_bounds = ParamBuffer::new(&ctx, "BoundsParams", &bytemuck::Zeroable::zeroed());
        let u_fuse_scan =
            ParamBuffer::new(&ctx, "CompactParams (fuse)", &bytemuck::Zeroable::zeroed());
        Ok(GpuBackend {
            ctx,
            kernels,
            u_preprocess,
            u_bilateral,
            u_normal,
            u_project,
            u_icp,
            u_fuse,
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
            u_bounds,
            bounds_dirty_from: 0,
            fused_view: None,
            count: 0,
            max_surfels,
            bind_groups: None,
            spare_bind_groups: None,
            profiler: None,
            compaction: None,
            u_compact,
            u_fuse_scan,
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
        let level_sizes: Vec<(u32, u32)> = pyramid
            .iter()
            .map(|l| (l.down.width, l.down.height))
            .collect();
        if let Some(f) = &self.frame {
            let have: Vec<(u32, u32)> = f.levels.iter().map(|l| (l.width, l.height)).collect();
            if (f.raw_width, f.raw_height, f.width, f.height)
                == (p.raw_width, p.raw_height, p.width, p.height)
                && have == level_sizes
            {
                return Ok(());
            }
        }
        // A new index map holds no fusion's keys.
        self.fused_view = None;
        let ctx = &self.ctx;
        let n = (p.width * p.height) as usize;
        let full = |label: &str| -> Result<GpuImage> {
            GpuImage::new(
                ctx,
                label,
                p.width,
                p.height,
                wgpu::TextureFormat::Rgba32Float,
                true,
            )
        };
        let raw = |label: &str, format| -> Result<GpuImage> {
            GpuImage::new(ctx, label, p.raw_width, p.raw_height, format, false)
        };
        let raw_depth = raw("raw depth", wgpu::TextureFormat::R16Uint)?;
        let raw_rgba = raw("raw rgba", wgpu::TextureFormat::Rgba8Uint)?;
        let mut index_map = GpuArray::new(ctx, "index map", n)?;
        index_map.set_len(n);
        let mut assoc = GpuArray::new(ctx, "assoc", n)?;
        assoc.set_len(n);
        let mut merged = GpuArray::new(ctx, "merged surfel per pixel", 2 * n)?;
        merged.set_len(2 * n);
        // In append order, with holes for tiles outside the image that stay 0.
        let n_append = append_slots(p.width, p.height);
        let mut add_flags = GpuArray::new(ctx, "new-surfel flags", n_append)?;
        add_flags.set_len(n_append);
        let mut add_offsets = GpuArray::new(ctx, "new-surfel offsets", n_append)?;
        add_offsets.set_len(n_append);
        let levels = pyramid
            .iter()
            .map(|l| {
                let (w, h) = (l.down.width, l.down.height);
                let map = |label: &str| {
                    GpuImage::new(ctx, label, w, h, wgpu::TextureFormat::Rgba32Float, true)
                };
                Ok(LevelBuffers {
                    width: w,
                    height: h,
                    vertex: map("pyramid vertex map")?,
                    normal_depth: map("pyramid normal-depth map")?,
                    pred_vertex: map("pyramid predicted vertex map")?,
                    pred_normal: map("pyramid predicted normal map")?,
                    u_pyramid: ParamBuffer::new(ctx, "PyramidParams", &l.down),
                    u_normal: ParamBuffer::new(ctx, "NormalParams (pyramid)", &l.normal),
                })
            })
            .collect::<Result<Vec<_>>>()?;
        self.frame = Some(FrameBuffers {
            raw_width: p.raw_width,
            raw_height: p.raw_height,
            width: p.width,
            height: p.height,
            raw_depth,
            raw_rgba,
            vertex: full("vertex map")?,
            filtered_vertex: full("filtered vertex map")?,
            filtered: false,
            normal_depth: full("normal-depth map")?,
            color: full("color map")?,
            index_map,
            pred_vertex: full("predicted vertex map")?,
            pred_normal: full("predicted normal map")?,
            assoc,
            merged,
            add_flags,
            add_offsets,
            levels,
        });
        self.bind_groups = None;
        self.spare_bind_groups = None;
        Ok(())
    }

    /// Grows the map (its last chunk x1.5 keeping contents, then new chunks) and the block
    /// boxes so `needed` surfels fit, or [`Error::Capacity`] when `needed` exceeds
    /// [`GpuBackend::max_surfels`].
    fn ensure_capacity(&mut self, needed: usize) -> Result<()> {
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
        let cap = self.capacity();
        let ctx = &self.ctx;
        if let Some(c) = self.compaction.as_mut() {
            let relaid = c.spare.match_layout(ctx, &self.map)?;
            if c.flags.capacity() >= cap && !relaid {
                return Ok(());
            }
            if c.flags.capacity() < cap {
                c.flags = GpuArray::new(ctx, "compact flags", cap)?;
                c.offsets = GpuArray::new(ctx, "compact offsets", cap)?;
            }
            c.flags.set_len(cap);
            c.offsets.set_len(cap);
            c.groups = None;
            c.spare_groups = None;
            self.spare_bind_groups = None;
            return Ok(());
        }
        let map = &self.map;
        let compaction = ctx.scoped("allocating the compaction buffers", || {
            let mut flags = GpuArray::new(ctx, "compact flags", cap)?;
            flags.set_len(cap);
            let mut offsets = GpuArray::new(ctx, "compact offsets", cap)?;
            offsets.set_len(cap);
            let mut spare = MapBuffers::new(ctx, 1, map.chunk_surfels())?;
            spare.match_layout(ctx, map)?;
            Ok(Compaction {
                flags,
                offsets,
                spare,
                groups: None,
                spare_groups: None,
            })
        })?;
        self.compaction = Some(compaction);
        self.spare_bind_groups = None;
        Ok(())
    }

    /// Builds the bind groups if a buffer changed since they were made.
    fn bind_groups(&mut self) -> &BindGroups {
        if self.bind_groups.is_none() {
            let f = self
                .frame
                .as_ref()
                .expect("preprocess() runs before any other step");
            let (c, k, m) = (&self.ctx, &self.kernels, &self.map);
            let bounds = &self.block_bounds;
            // One bind group per map chunk.
            let per_chunk = |make: &dyn Fn(&super::map_buffers::Chunk) -> wgpu::BindGroup| {
                m.chunks.iter().map(make).collect::<Vec<_>>()
            };
            self.bind_groups = Some(BindGroups {
                block_bounds: per_chunk(&|ch| {
                    k.block_bounds.bind_group(
                        c,
                        &[
                            self.u_bounds.binding(),
                            ch.info_buffer.binding(),
                            ch.position_weight.binding(),
                            bounds.binding(),
                        ],
                    )
                }),
                depth_to_vertex: k.depth_to_vertex.bind_group(
                    c,
                    &[
                        self.u_preprocess.binding(),
                        f.raw_depth.binding(),
                        f.raw_rgba.binding(),
                        f.vertex.binding(),
                        f.color.binding(),
                    ],
                ),
                bilateral_filter: k.bilateral_filter.bind_group(
                    c,
                    &[
                        self.u_bilateral.binding(),
                        f.vertex.binding(),
                        f.filtered_vertex.binding(),
                    ],
                ),
                vertex_to_normal: k.vertex_to_normal.bind_group(
                    c,
                    &[
                        self.u_normal.binding(),
                        f.vertex.binding(),
                        f.normal_depth.binding(),
                    ],
                ),
                vertex_to_normal_filtered: k.vertex_to_normal.bind_group(
                    c,
                    &[
                        self.u_normal.binding(),
                        f.filtered_vertex.binding(),
                        f.normal_depth.binding(),
                    ],
                ),
                project_model: per_chunk(&|ch| {
                    k.project_model.bind_group(
                        c,
                        &[
                            self.u_project.binding(),
                            ch.info_buffer.binding(),
                            bounds.binding(),
                            ch.position_weight.binding(),
                            f.index_map.binding(),
                        ],
                    )
                }),
                predict_model: per_chunk(&|ch| {
                    k.predict_model.bind_group(
                        c,
                        &[
                            self.u_project.binding(),
                            f.index_map.binding(),
                            ch.info_buffer.binding(),
                            ch.position_weight.binding(),
                            ch.normal_frame.binding(),
                            f.pred_vertex.binding(),
                            f.pred_normal.binding(),
                        ],
                    )
                }),
                icp_reduce: k.icp_reduce.bind_group(
                    c,
                    &[
                        self.u_icp.binding(),
                        f.pred_vertex.binding(),
                        f.pred_normal.binding(),
                        f.normal_depth.binding(),
                        self.partials.binding(),
                    ],
                ),
                fuse_select: per_chunk(&|ch| {
                    k.fuse_select.bind_group(
                        c,
                        &[
                            self.u_fuse.binding(),
                            f.normal_depth.binding(),
                            ch.info_buffer.binding(),
                            bounds.binding(),
                            ch.position_weight.binding(),
                            ch.normal_frame.binding(),
                            ch.color.binding(),
                            f.assoc.binding(),
                            f.index_map.binding(),
                        ],
                    )
                }),
                fuse_merge: per_chunk(&|ch| {
                    k.fuse_merge.bind_group(
                        c,
                        &[
                            self.u_fuse.binding(),
                            f.normal_depth.binding(),
                            f.color.binding(),
                            ch.info_buffer.binding(),
                            bounds.binding(),
                            ch.position_weight.binding(),
                            ch.normal_frame.binding(),
                            ch.color.binding(),
                            f.assoc.binding(),
                        ],
                    )
                }),
                fuse_flags: k.fuse_flags.bind_group(
                    c,
                    &[
                        self.u_fuse.binding(),
                        f.normal_depth.binding(),
                        f.assoc.binding(),
                        f.merged.binding(),
                        f.add_flags.binding(),
                    ],
                ),
                fuse_scan: k.prefix_sum.bind_group(
                    c,
                    &[
                        self.u_fuse_scan.binding(),
                        f.add_flags.binding(),
                        f.add_offsets.binding(),
                        self.counter.binding(),
                    ],
                ),
                fuse_merge_chosen: per_chunk(&|ch| {
                    k.fuse_merge_chosen.bind_group(
                        c,
                        &[
                            self.u_fuse.binding(),
                            f.normal_depth.binding(),
                            f.color.binding(),
                            ch.info_buffer.binding(),
                            bounds.binding(),
                            ch.position_weight.binding(),
                            ch.normal_frame.binding(),
                            ch.color.binding(),
                            f.assoc.binding(),
                            f.merged.binding(),
                        ],
                    )
                }),
                fuse_prune: per_chunk(&|ch| {
                    k.fuse_prune.bind_group(
                        c,
                        &[
                            self.u_fuse.binding(),
                            ch.info_buffer.binding(),
                            bounds.binding(),
                            ch.position_weight.binding(),
                            ch.normal_frame.binding(),
                            ch.color.binding(),
                            f.merged.binding(),
                        ],
                    )
                }),
                fuse_add: per_chunk(&|ch| {
                    k.fuse_add.bind_group(
                        c,
                        &[
                            self.u_fuse.binding(),
                            f.normal_depth.binding(),
                            f.color.binding(),
                            f.add_flags.binding(),
                            f.add_offsets.binding(),
                            ch.info_buffer.binding(),
                            ch.position_weight.binding(),
                            ch.normal_frame.binding(),
                            ch.color.binding(),
                            f.index_map.binding(),
                        ],
                    )
                }),
                levels: (0..f.levels.len())
                    .map(|l| {
                        let level = &f.levels[l];
                        // The finer level's maps: level 0's, or the previous level's.
                        let (fine_vertex, fine_pred_vertex, fine_pred_normal) = match l {
                            0 => (&f.vertex, &f.pred_vertex, &f.pred_normal),
                            _ => {
                                let p = &f.levels[l - 1];
                                (&p.vertex, &p.pred_vertex, &p.pred_normal)
                            }
                        };
                        let pyramid_depth = |fine: &GpuImage| {
                            k.pyramid_depth.bind_group(
                                c,
                                &[
                                    level.u_pyramid.binding(),
                                    fine.binding(),
                                    level.vertex.binding(),
                                ],
                            )
                        };
                        let unfiltered = pyramid_depth(fine_vertex);
                        let filtered = match l {
                            0 => pyramid_depth(&f.filtered_vertex),
                            _ => unfiltered.clone(),
                        };
                        LevelBindGroups {
                            pyramid_depth: unfiltered,
                            pyramid_depth_filtered: filtered,
                            vertex_to_normal: k.vertex_to_normal.bind_group(
                                c,
                                &[
                                    level.u_normal.binding(),
                                    level.vertex.binding(),
                                    level.normal_depth.binding(),
                                ],
                            ),
                            pyramid_model: k.pyramid_model.bind_group(
                                c,
                                &[
                                    level.u_pyramid.binding(),
                                    fine_pred_vertex.binding(),
                                    fine_pred_normal.binding(),
                                    level.pred_vertex.binding(),
                                    level.pred_normal.binding(),
                                ],
                            ),
                            icp_reduce: k.icp_reduce.bind_group(
                                c,
                                &[
                                    self.u_icp.binding(),
                                    level.pred_vertex.binding(),
                                    level.pred_normal.binding(),
                                    level.normal_depth.binding(),
                                    self.partials.binding(),
                                ],
                            ),
                        }
                    })
                    .collect(),
            });
        }
        self.bind_groups.as_ref().expect("just built")
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
    /// params and marks the boxes fresh. Every submission that culls starts with these.
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
            self.u_bounds.write(
                &self.ctx,
                &BoundsParams::stale(self.count, self.bounds_dirty_from),
            );
        }
        self.bounds_dirty_from = self.count;
        out
    }

    fn frame(&self) -> &FrameBuffers {
        self.frame
            .as_ref()
            .expect("preprocess() runs before any other step")
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

/// A per-pixel `[f32; 4]` map read back row-major.
fn read_map(ctx: &GpuContext, image: &GpuImage) -> Result<Vec<[f32; 4]>> {
    image.read_back(ctx)
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
        ctx.scoped("preprocess", || {
            let f = self.frame.as_mut().expect("ensure_frame made it");
            f.raw_depth.upload(ctx, raw_depth)?;
            f.raw_rgba.upload(ctx, raw_rgba)?;
            f.filtered = bilateral.is_some();
            self.u_preprocess.write(ctx, params);
            if let Some(b) = bilateral {
                self.u_bilateral.write(ctx, b);
            }
            self.u_normal.write(ctx, normal);
            for (level, p) in f.levels.iter().zip(pyramid) {
                level.u_pyramid.write(ctx, &p.down);
                level.u_normal.write(ctx, &p.normal);
            }
            Ok(())
        })?;
        let (w, h) = (params.width, params.height);
        let (k, ctx) = (&self.kernels, &self.ctx);
        let d2v_wg = k.depth_to_vertex.grid_workgroups_for_image(ctx, w, h);
        let bf_wg = k.bilateral_filter.grid_workgroups_for_image(ctx, w, h);
        let v2n_wg = k.vertex_to_normal.grid_workgroups_for_image(ctx, w, h);
        let level_wg: Vec<([u32; 2], [u32; 2])> = pyramid
            .iter()
            .map(|p| {
                let (w, h) = (p.down.width, p.down.height);
                (
                    k.pyramid_depth.grid_workgroups_for_image(ctx, w, h),
                    k.vertex_to_normal.grid_workgroups_for_image(ctx, w, h),
                )
            })
            .collect();
        let (ctx, k, bg, profiler) = encoding_parts!(self);
        ctx.scoped("preprocess", || {
            let mut enc = ctx.encoder("preprocess");
            let d2v = (&k.depth_to_vertex, &bg.depth_to_vertex, d2v_wg);
            let bf = (&k.bilateral_filter, &bg.bilateral_filter, bf_wg);
            let v2n = (&k.vertex_to_normal, &bg.vertex_to_normal, v2n_wg);
            let v2n_filtered = (&k.vertex_to_normal, &bg.vertex_to_normal_filtered, v2n_wg);
            let mut passes = match bilateral {
                Some(_) => vec![d2v, bf, v2n_filtered],
                None => vec![d2v, v2n],
            };
            for (g, &(down_wg, normal_wg)) in bg.levels.iter().zip(&level_wg) {
                let down = match bilateral {
                    Some(_) => &g.pyramid_depth_filtered,
                    None => &g.pyramid_depth,
                };
                passes.push((&k.pyramid_depth, down, down_wg));
                passes.push((&k.vertex_to_normal, &g.vertex_to_normal, normal_wg));
            }
            record_passes(ctx, profiler, &mut enc, &passes)?;
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
        let pix_wg = self
            .kernels
            .predict_model
            .grid_workgroups_for_image(&self.ctx, f.width, f.height);
        let project = !self.fused_view.is_some_and(|v| v.is_view_of(&params));
        let chunk_wg = if project {
            self.chunk_workgroups(&self.kernels.project_model)
        } else {
            Vec::new()
        };
        let level_wg: Vec<[u32; 2]> = f
            .levels
            .iter()
            .map(|l| {
                self.kernels
                    .pyramid_model
                    .grid_workgroups_for_image(&self.ctx, l.width, l.height)
            })
            .collect();
        let bounds = if project {
            self.stale_bounds_passes()
        } else {
            Vec::new()
        };
        let (ctx, k, bg, profiler) = encoding_parts!(self);
        let f = self
            .frame
            .as_ref()
            .expect("preprocess() runs before predict()");
        ctx.scoped("predict", || {
            self.u_project.write(ctx, &params);
            let mut enc = ctx.encoder("predict");
            if project {
                f.index_map.clear(&mut enc);
            }
            let mut passes: Vec<_> = bounds
                .iter()
                .map(|&(c, wg)| (&k.block_bounds, &bg.block_bounds[c], [wg, 1]))
                .collect();
            for (c, &(blocks_wg, _)) in chunk_wg.iter().enumerate() {
                passes.push((&k.project_model, &bg.project_model[c], [blocks_wg, 1]));
            }
            for g in &bg.predict_model {
                passes.push((&k.predict_model, g, pix_wg));
            }
            for (g, &wg) in bg.levels.iter().zip(&level_wg) {
                passes.push((&k.pyramid_model, &g.pyramid_model, wg));
            }
            record_passes(ctx, profiler, &mut enc, &passes)?;
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
        let system = ctx.scoped("icp_reduce", || {
            self.u_icp.write(ctx, params);
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
        let chunk_wg = self.chunk_workgroups(&self.kernels.fuse_merge);
        let bounds = self.stale_bounds_passes();
        let f = self.frame();
        let pix_wg = self
            .kernels
            .fuse_add
            .grid_workgroups_for_image(&self.ctx, f.width, f.height);
        let flags_wg = self
            .kernels
            .fuse_flags
            .grid_workgroups_for_image(&self.ctx, f.width, f.height);
        let chosen_wg = self
            .kernels
            .fuse_merge_chosen
            .grid_workgroups_for_image(&self.ctx, f.width, f.height);
        let (ctx, k, bg, profiler) = encoding_parts!(self);
        let f = self
            .frame
            .as_ref()
            .expect("preprocess() runs before fuse()");
        let added = ctx.scoped("fuse", || {
            self.u_fuse.write(ctx, &params);
            self.u_fuse_scan.write(ctx, &scan_params(f.add_flags.len()));
            let mut enc = ctx.encoder("fuse");
            f.assoc.clear(&mut enc);
            if params.association == ASSOCIATION_BEST_CANDIDATE {
                f.merged.clear(&mut enc);
                f.index_map.clear(&mut enc);
            }
            let mut passes: Vec<_> = bounds
                .iter()
                .map(|&(c, wg)| (&k.block_bounds, &bg.block_bounds[c], [wg, 1]))
                .collect();
            if params.association == ASSOCIATION_BEST_CANDIDATE {
                // Surfels pick pixels, then each picked surfel merges from its pixel.
                for (c, &(blocks_wg, _)) in chunk_wg.iter().enumerate() {
                    passes.push((&k.fuse_select, &bg.fuse_select[c], [blocks_wg, 1]));
                }
                for g in &bg.fuse_merge_chosen {
                    passes.push((&k.fuse_merge_chosen, g, chosen_wg));
                }
                if params.prune_radius_scale > 0.0 {
                    for (c, &(blocks_wg, _)) in chunk_wg.iter().enumerate() {
                        passes.push((&k.fuse_prune, &bg.fuse_prune[c], [blocks_wg, 1]));
                    }
                }
            } else {
                for (c, &(blocks_wg, _)) in chunk_wg.iter().enumerate() {
                    passes.push((&k.fuse_merge, &bg.fuse_merge[c], [blocks_wg, 1]));
                }
            }
            passes.push((&k.fuse_flags, &bg.fuse_flags, flags_wg));
            passes.push((&k.prefix_sum, &bg.fuse_scan, [1, 1]));
            for g in &bg.fuse_add {
                passes.push((&k.fuse_add, g, pix_wg));
            }
            record_passes(ctx, profiler, &mut enc, &passes)?;
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
        let (ctx, k, m) = (&self.ctx, &self.kernels, &self.map);
        let c = self.compaction.as_mut().expect("ensure_compaction made it");
        // Made once per map set (live and spare swap every call, and so do these).
        let g = c.groups.get_or_insert_with(|| CompactionGroups {
            flags: m
                .chunks
                .iter()
                .map(|ch| {
                    k.compact_flags.bind_group(
                        ctx,
                        &[
                            self.u_compact.binding(),
                            ch.info_buffer.binding(),
                            ch.position_weight.binding(),
                            ch.normal_frame.binding(),
                            c.flags.binding(),
                        ],
                    )
                })
                .collect(),
            scan: k.prefix_sum.bind_group(
                ctx,
                &[
                    self.u_compact.binding(),
                    c.flags.binding(),
                    c.offsets.binding(),
                    self.counter.binding(),
                ],
            ),
            // Input chunk s, output chunk d <= s (offsets[i] <= i), at s (s + 1) / 2 + d.
            scatter: m
                .chunks
                .iter()
                .enumerate()
                .flat_map(|(s, from)| c.spare.chunks[..=s].iter().map(move |to| (from, to)))
                .map(|(from, to)| {
                    k.compact_scatter.bind_group(
                        ctx,
                        &[
                            self.u_compact.binding(),
                            c.flags.binding(),
                            c.offsets.binding(),
                            from.info_buffer.binding(),
                            from.position_weight.binding(),
                            from.normal_frame.binding(),
                            from.color.binding(),
                            to.info_buffer.binding(),
                            to.position_weight.binding(),
                            to.normal_frame.binding(),
                            to.color.binding(),
                        ],
                    )
                })
                .collect(),
        });
        let profiler = &mut self.profiler;
        let kept = ctx.scoped("compact", || {
            self.u_compact.write(ctx, &params);
            let mut enc = ctx.encoder("compact");
            let mut passes: Vec<_> = g
                .flags
                .iter()
                .zip(&flags_wg)
                .map(|(group, &(_, wg))| (&k.compact_flags, group, [wg, 1]))
                .collect();
            passes.push((&k.prefix_sum, &g.scan, [1, 1]));
            for (s, &(_, wg)) in scatter_wg.iter().enumerate() {
                for d in 0..=s {
                    let group = &g.scatter[s * (s + 1) / 2 + d];
                    passes.push((&k.compact_scatter, group, [wg, 1]));
                }
            }
            record_passes(ctx, profiler, &mut enc, &passes)?;
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

impl Inspect for GpuBackend {
    fn download_map(&mut self) -> Result<SurfelMap> {
        let (ctx, m) = (&self.ctx, &self.map);
        ctx.scoped("download map", || {
            let map = m.download(ctx, self.count)?;
            map.assert_consistent();
            Ok(map)
        })
    }

    /// Writes `map` into the live map chunks (growing them first if needed) and sets
    /// the count; the spare map set is untouched (compaction overwrites it).
    fn upload_map(&mut self, map: &SurfelMap) -> Result<()> {
        map.assert_consistent();
        let n = map.len();
        self.ensure_capacity(n)?;
        let (ctx, m) = (&self.ctx, &mut self.map);
        ctx.scoped("upload map", || m.upload(ctx, map))?;
        self.count = n;
        self.bounds_dirty_from = 0;
        self.fused_view = None;
        Ok(())
    }

    fn download_frame(&mut self) -> Result<FrameMaps> {
        // Before the first frame there is nothing to download (as on the CPU).
        let Some(f) = self.frame.as_ref() else {
            return Ok(FrameMaps::default());
        };
        let ctx = &self.ctx;
        ctx.scoped("download frame", || {
            Ok(FrameMaps {
                vertex: read_map(ctx, &f.vertex)?,
                filtered_vertex: if f.filtered {
                    read_map(ctx, &f.filtered_vertex)?
                } else {
                    Vec::new()
                },
                normal_depth: read_map(ctx, &f.normal_depth)?,
                color: read_map(ctx, &f.color)?,
                pyramid: f
                    .levels
                    .iter()
                    .map(|l| {
                        Ok(FrameLevel {
                            vertex: read_map(ctx, &l.vertex)?,
                            normal_depth: read_map(ctx, &l.normal_depth)?,
                        })
                    })
                    .collect::<Result<_>>()?,
            })
        })
    }

    fn download_prediction(&mut self, level: usize) -> Result<Prediction> {
        let Some(f) = self.frame.as_ref() else {
            return Ok(Prediction::default());
        };
        let (vertex, normal) = match level {
            0 => (&f.pred_vertex, &f.pred_normal),
            l => match f.levels.get(l - 1) {
                Some(level) => (&level.pred_vertex, &level.pred_normal),
                None => return Ok(Prediction::default()),
            },
        };
        let ctx = &self.ctx;
        ctx.scoped("download prediction", || {
            Ok((read_map(ctx, vertex)?, read_map(ctx, normal)?))
        })
    }

    fn counters(&self) -> BackendCounters {
        let s = self.ctx.stats();
        BackendCounters {
            readback_bytes: s.readback_bytes,
            submissions: s.submissions,
        }
    }
}

impl GpuBackend {
    /// The raw index map of the last `predict` (u64 keys, see `cpu::project_model`), for
    /// parity tests.
    pub fn download_index_map(&mut self) -> Result<Vec<u64>> {
        let (ctx, f) = (&self.ctx, self.frame());
        ctx.scoped("download index map", || f.index_map.read_back(ctx))
    }
}

impl GpuBackend {
    /// The first `n` keep flags and offsets of the last `compact` (`compact_flags`' and
    /// `prefix_sum`'s outputs), for parity tests; empty before the first `compact`.
    pub fn download_compaction(&mut self, n: usize) -> Result<(Vec<u32>, Vec<u32>)> {
        let Some(c) = self.compaction.as_ref() else {
            return Ok((Vec::new(), Vec::new()));
        };
        let ctx = &self.ctx;
        ctx.scoped("download compaction", || {
            Ok((
                c.flags.read_back_range(ctx, 0..n)?,
                c.offsets.read_back_range(ctx, 0..n)?,
            ))
        })
    }
}

impl GpuBackend {
    /// The culling blocks' boxes of the live map (entries `2b` min, `2b + 1` max,
    /// ordered-encoded), for tests; boxes of blocks fusion appended to since the last
    /// `predict` or `fuse` are stale until the next one.
    pub fn download_block_bounds(&mut self) -> Result<Vec<[u32; 4]>> {
        let (ctx, b) = (&self.ctx, &self.block_bounds);
        let n = 2 * self.count.div_ceil(BLOCK_SURFELS as usize);
        ctx.scoped("download block bounds", || b.read_back_range(ctx, 0..n))
    }
}

impl GpuBackend {
    /// The last `fuse`'s per-pixel association keys (for the parity test of
    /// `fuse_select`); empty before the first frame.
    pub fn download_assoc(&mut self) -> Result<Vec<u64>> {
        let (ctx, Some(f)) = (&self.ctx, self.frame.as_ref()) else {
            return Ok(Vec::new());
        };
        ctx.scoped("download assoc", || {
            f.assoc.read_back_range(ctx, 0..f.pixels())
        })
    }
}
