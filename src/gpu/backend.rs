//! The GPU backend: runs the dense-SLAM steps of [`crate::slam::pipeline::Backend`] as the WGSL
//! kernels in `shaders/`, each the twin of a CPU function in `src/cpu/`.
//!
//! Per-pixel maps (raw inputs, vertex / filtered-vertex / normal / colour maps, the
//! prediction) are 2D textures ([`GpuImage`]): kernels read them with `textureLoad` and
//! write them as storage textures, which lavapipe loads 3-5x faster than storage-buffer
//! elements (`examples/lavapipe_loads.rs`).
//! The frame's normal map carries the vertex's depth in w (`normal_depth`), so the kernels
//! that associate with the frame fetch one texel and rebuild the vertex (see
//! vertex_to_normal.wgsl), as does the twin; `download_frame` reads it as it is.
//! The surfel map is three packed textures ([`MapTextures`]); only the index map, the
//! association flags, the counter and the ICP partials are storage buffers (atomics).
//! Every pipeline, uniform and small buffer is created once in [`GpuBackend::new`]; the
//! per-frame textures are sized at the first `preprocess` and reused (re-created only if the
//! frame size changes); the surfel map lives on the GPU for the whole run and grows
//! geometrically (x1.5, a GPU-side copy) before a fusion could overflow it. Per frame the
//! host reads back only the ICP partials (one 29-float system per workgroup per iteration)
//! and the 4-byte surfel counter; maps are downloaded only on request.
//! With the bilateral filter on, `preprocess` runs three kernels and `vertex_to_normal`
//! reads the filtered-vertex texture through a second bind group; the unfiltered vertex
//! texture is kept (the filtered one is allocated either way, one frame map's worth).
//! The `compact` step (robust profile) runs `compact_flags`, `prefix_sum` and
//! `compact_scatter` in one submission and reads back only the 4-byte counter that
//! `prefix_sum` writes; its flags, offsets (one `u32` per surfel slot, storage buffers) and
//! second set of map textures are allocated at its first call and re-allocated when the map
//! grows, and after the scatter the two map sets swap (so the bind groups are rebuilt).
//! Not a scheduler: the order of steps is `pipeline::Slam`'s.

use std::collections::BTreeMap;

use super::buffers::{GpuArray, Readback, Uniform};
use super::context::GpuContext;
use super::images::GpuImage;
use super::kernel::{Binding, Kernel, TexelFormat};
use super::map_textures::MapTextures;
use super::timing::StageTimer;
use crate::layout::{
    BilateralParams, CompactParams, FuseParams, IcpParams, NormalParams, PreprocessParams,
    ProjectParams, ICP_SYSTEM_LEN,
};
use crate::slam::map::SurfelMap;
use crate::slam::pipeline::{Backend, BackendCounters, FrameMaps};
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
/// Storage buffers bound at once by the largest kernel (`prefix_sum`: flags, offsets,
/// counter; `fuse_add`: assoc, counter).
const MAX_STORAGE_BUFFERS_USED: u32 = 3;
/// Storage textures bound at once by the largest kernel (`fuse_merge`, `fuse_add`: the
/// three packed map textures; `depth_to_vertex`, `predict_model`: two maps).
const MAX_STORAGE_TEXTURES_USED: u32 = 3;

/// Bindings of each dense-SLAM kernel, in the order of its CPU twin's arguments
/// (`@binding(i)`); `kernel::layout_entries` turns them into the layout.
pub mod bindings {
    use super::{Binding, TexelFormat};
    pub const DEPTH_TO_VERTEX: [Binding; 5] = [
        Binding::uniform("params: PreprocessParams"),
        Binding::texture_u32("raw_depth: r16uint"),
        Binding::texture_u32("raw_rgba: rgba8uint"),
        Binding::write_texture("vertex_map: camera frame"),
        Binding::write_texture("color_map: RGB 0..255"),
    ];
    pub const BILATERAL_FILTER: [Binding; 3] = [
        Binding::uniform("params: BilateralParams"),
        Binding::texture_f32("vertex_map: camera frame, unfiltered"),
        Binding::write_texture("filtered_vertex: camera frame"),
    ];
    pub const VERTEX_TO_NORMAL: [Binding; 3] = [
        Binding::uniform("params: NormalParams"),
        Binding::texture_f32("vertex_map: camera frame (filtered_vertex with the filter)"),
        Binding::write_texture("normal_depth: camera-frame normal, w = depth"),
    ];
    pub const PROJECT_MODEL: [Binding; 3] = [
        Binding::uniform("params: ProjectParams"),
        Binding::texture_f32("position_weight: world frame"),
        Binding::read_write("index_map: atomic u64 keys"),
    ];
    pub const PREDICT_MODEL: [Binding; 6] = [
        Binding::uniform("params: ProjectParams"),
        Binding::read("index_map: u64 keys as vec2<u32>"),
        Binding::texture_f32("position_weight: world frame"),
        Binding::texture_u32("normal_frame: world frame normal bits"),
        Binding::write_texture("pred_vertex: world frame"),
        Binding::write_texture("pred_normal: world frame"),
    ];
    pub const ICP_REDUCE: [Binding; 5] = [
        Binding::uniform("params: IcpParams"),
        Binding::texture_f32("pred_vertex: source, world frame"),
        Binding::texture_f32("pred_normal: source normals, world frame"),
        Binding::texture_f32("normal_depth: target, camera frame, w = depth"),
        Binding::read_write("partials: 29 f32 per workgroup"),
    ];
    pub const FUSE_MERGE: [Binding; 7] = [
        Binding::uniform("params: FuseParams"),
        Binding::texture_f32("normal_depth: camera frame, w = depth"),
        Binding::texture_f32("color_map"),
        Binding::storage_texture(TexelFormat::Rgba32F, true, "position_weight"),
        Binding::storage_texture(TexelFormat::Rgba32U, true, "normal_frame"),
        Binding::storage_texture(TexelFormat::Rgba32F, true, "color"),
        Binding::read_write("assoc: atomic flag per pixel"),
    ];
    pub const FUSE_ADD: [Binding; 8] = [
        Binding::uniform("params: FuseParams"),
        Binding::texture_f32("normal_depth: camera frame, w = depth"),
        Binding::texture_f32("color_map"),
        Binding::read("assoc"),
        Binding::read_write("counter: atomic surfel count"),
        Binding::storage_texture(TexelFormat::Rgba32F, false, "position_weight"),
        Binding::storage_texture(TexelFormat::Rgba32U, false, "normal_frame"),
        Binding::storage_texture(TexelFormat::Rgba32F, false, "color"),
    ];
    pub const COMPACT_FLAGS: [Binding; 4] = [
        Binding::uniform("params: CompactParams"),
        Binding::texture_f32("position_weight: w = weight"),
        Binding::texture_u32("normal_frame: w = last_frame"),
        Binding::read_write("flags: 1 keep / 0 remove per surfel"),
    ];
    pub const PREFIX_SUM: [Binding; 4] = [
        Binding::uniform("params: CompactParams"),
        Binding::read("flags"),
        Binding::read_write("offsets: exclusive prefix sum of flags"),
        Binding::read_write("counter: surfels kept"),
    ];
    pub const COMPACT_SCATTER: [Binding; 9] = [
        Binding::uniform("params: CompactParams"),
        Binding::read("flags"),
        Binding::read("offsets"),
        Binding::texture_f32("position_weight"),
        Binding::texture_u32("normal_frame"),
        Binding::texture_f32("color"),
        Binding::storage_texture(TexelFormat::Rgba32F, false, "out_position_weight"),
        Binding::storage_texture(TexelFormat::Rgba32U, false, "out_normal_frame"),
        Binding::storage_texture(TexelFormat::Rgba32F, false, "out_color"),
    ];
}

struct Kernels {
    depth_to_vertex: Kernel,
    bilateral_filter: Kernel,
    vertex_to_normal: Kernel,
    project_model: Kernel,
    predict_model: Kernel,
    icp_reduce: Kernel,
    fuse_merge: Kernel,
    fuse_add: Kernel,
    compact_flags: Kernel,
    prefix_sum: Kernel,
    compact_scatter: Kernel,
}

/// What the `compact` step needs besides the map, allocated at its first call (the
/// assignment profile never pays for it) and re-allocated when the map grows: one flag and
/// one offset per surfel slot, and a second set of map textures of the same capacity that
/// `compact_scatter` writes and that then swaps with the map.
struct Compaction {
    flags: GpuArray<u32>,
    offsets: GpuArray<u32>,
    spare: MapTextures,
    /// The three passes' bind groups for the live map (`groups`) and for the spare one
    /// (`spare_groups`), made once each and swapped with the maps.
    groups: Option<CompactionGroups>,
    spare_groups: Option<CompactionGroups>,
}

/// Bind groups of `compact_flags`, `prefix_sum` and `compact_scatter` for one map set.
struct CompactionGroups {
    flags: wgpu::BindGroup,
    scan: wgpu::BindGroup,
    scatter: wgpu::BindGroup,
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
    assoc: GpuArray<u32>,
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
    project_model: wgpu::BindGroup,
    predict_model: wgpu::BindGroup,
    icp_reduce: wgpu::BindGroup,
    fuse_merge: wgpu::BindGroup,
    fuse_add: wgpu::BindGroup,
}

/// Runs the pipeline's steps on a GPU through wgpu. See the module header.
pub struct GpuBackend {
    ctx: GpuContext,
    kernels: Kernels,
    u_preprocess: Uniform<PreprocessParams>,
    u_bilateral: Uniform<BilateralParams>,
    u_normal: Uniform<NormalParams>,
    u_project: Uniform<ProjectParams>,
    u_icp: Uniform<IcpParams>,
    u_fuse: Uniform<FuseParams>,
    reduction_workgroups: u32,
    partials: GpuArray<f32>,
    partials_readback: Readback<f32>,
    counter: GpuArray<u32>,
    counter_readback: Readback<u32>,
    frame: Option<FrameBuffers>,
    map: MapTextures,
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
    u_compact: Uniform<CompactParams>,
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
                 prefix_sum needs {MAX_STORAGE_BUFFERS_USED}; use --backend cpu",
                ctx.adapter_info().name
            )));
        }
        let per_stage = ctx.limits().max_storage_textures_per_shader_stage;
        if per_stage < MAX_STORAGE_TEXTURES_USED {
            return Err(Error::Gpu(format!(
                "adapter \"{}\" allows {per_stage} storage textures per shader stage; \
                 fuse_merge needs {MAX_STORAGE_TEXTURES_USED}; use --backend cpu",
                ctx.adapter_info().name
            )));
        }
        if !ctx.has_read_write_rgba32() {
            return Err(Error::Gpu(format!(
                "adapter \"{}\" cannot read and write rgba32float/rgba32uint storage textures \
                 (TEXTURE_ADAPTER_SPECIFIC_FORMAT_FEATURES), which fuse_merge needs for the \
                 surfel map; use --backend cpu",
                ctx.adapter_info().name
            )));
        }
        let max_surfels = Self::device_max_surfels(&ctx);
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
                project_model: Kernel::new(&ctx, "project_model", &bindings::PROJECT_MODEL)?,
                predict_model: Kernel::new(&ctx, "predict_model", &bindings::PREDICT_MODEL)?,
                icp_reduce: Kernel::new(&ctx, "icp_reduce", &bindings::ICP_REDUCE)?,
                fuse_merge: Kernel::new(&ctx, "fuse_merge", &bindings::FUSE_MERGE)?,
                fuse_add: Kernel::new(&ctx, "fuse_add", &bindings::FUSE_ADD)?,
                compact_flags: Kernel::new(&ctx, "compact_flags", &bindings::COMPACT_FLAGS)?,
                prefix_sum: Kernel::new(&ctx, "prefix_sum", &bindings::PREFIX_SUM)?,
                compact_scatter: Kernel::new(&ctx, "compact_scatter", &bindings::COMPACT_SCATTER)?,
            };
            let uniforms = (
                Uniform::new(&ctx, "PreprocessParams", &bytemuck::Zeroable::zeroed()),
                Uniform::new(&ctx, "BilateralParams", &bytemuck::Zeroable::zeroed()),
                Uniform::new(&ctx, "NormalParams", &bytemuck::Zeroable::zeroed()),
                Uniform::new(&ctx, "ProjectParams", &bytemuck::Zeroable::zeroed()),
                Uniform::new(&ctx, "IcpParams", &bytemuck::Zeroable::zeroed()),
                Uniform::new(&ctx, "FuseParams", &bytemuck::Zeroable::zeroed()),
            );
            let mut partials = GpuArray::new(&ctx, "icp partials", system_floats)?;
            partials.set_len(system_floats);
            let mut counter = GpuArray::new(&ctx, "surfel counter", 1)?;
            counter.set_len(1);
            let small = (
                partials,
                Readback::new(&ctx, "icp partials read-back", system_floats),
                counter,
                Readback::new(&ctx, "surfel counter read-back", 1),
            );
            let map = MapTextures::new(&ctx, capacity)?;
            Ok((kernels, uniforms, small, map))
        })?;
        let (u_preprocess, u_bilateral, u_normal, u_project, u_icp, u_fuse) = uniforms;
        let (partials, partials_readback, counter, counter_readback) = small;
        let u_compact = Uniform::new(&ctx, "CompactParams", &bytemuck::Zeroable::zeroed());
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
            partials_readback,
            counter,
            counter_readback,
            frame: None,
            map,
            count: 0,
            max_surfels,
            bind_groups: None,
            spare_bind_groups: None,
            profiler: None,
            compaction: None,
            u_compact,
        })
    }

    /// Caps the map at `max_surfels` surfels (below the device limit): a fusion that might
    /// need more fails with [`Error::Capacity`] (tests use it to force that error).
    pub fn with_max_surfels(mut self, max_surfels: usize) -> GpuBackend {
        self.max_surfels = max_surfels.min(Self::device_max_surfels(&self.ctx));
        self
    }

    /// Most surfels the device's texture size limit allows.
    fn device_max_surfels(ctx: &GpuContext) -> usize {
        MapTextures::device_max_surfels(ctx)
    }

    /// Turns on per-kernel timing (GPU timestamps when the device has them, else wall time
    /// per step). Costs a wait after every step: use for profiling, not for throughput.
    pub fn enable_kernel_timing(&mut self) {
        self.profiler = Some(Profiler {
            // At most three kernels per submission (preprocess with the bilateral filter,
            // compact; predict and fuse have two).
            timer: StageTimer::new(&self.ctx, 3),
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

    /// The cap set by [`GpuBackend::with_max_surfels`] or the device limit.
    pub fn max_surfels(&self) -> usize {
        self.max_surfels
    }

    /// Workgroups `icp_reduce` is dispatched with (partial systems per iteration).
    pub fn reduction_workgroups(&self) -> u32 {
        self.reduction_workgroups
    }

    /// (Re-)creates the per-frame buffers when the frame size changes.
    fn ensure_frame(&mut self, p: &PreprocessParams) -> Result<()> {
        if let Some(f) = &self.frame {
            if (f.raw_width, f.raw_height, f.width, f.height)
                == (p.raw_width, p.raw_height, p.width, p.height)
            {
                return Ok(());
            }
        }
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
        });
        self.bind_groups = None;
        self.spare_bind_groups = None;
        Ok(())
    }

    /// Grows the map arrays (x1.5, keeping contents) so `needed` surfels fit, or
    /// [`Error::Capacity`] when `needed` exceeds [`GpuBackend::max_surfels`].
    fn ensure_capacity(&mut self, needed: usize) -> Result<()> {
        if needed <= self.capacity() {
            return Ok(());
        }
        if needed > self.max_surfels {
            return Err(Error::Capacity(format!(
                "fusing this frame may need {needed} surfels ({} bytes of positions) but the \
                 GPU map is limited to {} surfels ({} bytes; the device allows {} surfels: \
                 {} texels per row x {} rows)",
                needed * 16,
                self.max_surfels,
                self.max_surfels * 16,
                Self::device_max_surfels(&self.ctx),
                crate::layout::MAP_TEXTURE_WIDTH,
                self.ctx.limits().max_texture_dimension_2d
            )));
        }
        let grown = (self.capacity() * GROWTH_NUM / GROWTH_DEN)
            .max(needed)
            .min(self.max_surfels);
        self.map.grow(&self.ctx, grown, self.count)?;
        // The spare map is re-made at the new capacity by the next `compact`.
        self.bind_groups = None;
        self.spare_bind_groups = None;
        Ok(())
    }

    /// Allocates the `compact` step's flags, offsets and second map for the current
    /// capacity (first call, or after the map grew). [`Error::Capacity`] when a flag per
    /// surfel slot outgrows the device's storage-buffer binding limit.
    fn ensure_compaction(&mut self) -> Result<()> {
        let cap = self.capacity();
        if self.compaction.as_ref().map(|c| c.spare.capacity()) == Some(cap) {
            return Ok(());
        }
        let ctx = &self.ctx;
        let compaction = ctx.scoped("allocating the compaction buffers", || {
            let mut flags = GpuArray::new(ctx, "compact flags", cap)?;
            flags.set_len(cap);
            let mut offsets = GpuArray::new(ctx, "compact offsets", cap)?;
            offsets.set_len(cap);
            Ok(Compaction {
                flags,
                offsets,
                spare: MapTextures::new(ctx, cap)?,
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
            self.bind_groups = Some(BindGroups {
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
                project_model: k.project_model.bind_group(
                    c,
                    &[
                        self.u_project.binding(),
                        m.position_weight.binding(),
                        f.index_map.binding(),
                    ],
                ),
                predict_model: k.predict_model.bind_group(
                    c,
                    &[
                        self.u_project.binding(),
                        f.index_map.binding(),
                        m.position_weight.binding(),
                        m.normal_frame.binding(),
                        f.pred_vertex.binding(),
                        f.pred_normal.binding(),
                    ],
                ),
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
                fuse_merge: k.fuse_merge.bind_group(
                    c,
                    &[
                        self.u_fuse.binding(),
                        f.normal_depth.binding(),
                        f.color.binding(),
                        m.position_weight.binding(),
                        m.normal_frame.binding(),
                        m.color.binding(),
                        f.assoc.binding(),
                    ],
                ),
                fuse_add: k.fuse_add.bind_group(
                    c,
                    &[
                        self.u_fuse.binding(),
                        f.normal_depth.binding(),
                        f.color.binding(),
                        f.assoc.binding(),
                        self.counter.binding(),
                        m.position_weight.binding(),
                        m.normal_frame.binding(),
                        m.color.binding(),
                    ],
                ),
            });
        }
        self.bind_groups.as_ref().expect("just built")
    }

    /// Workgroups for a grid-stride loop over `n` items: one thread each, capped by
    /// [`GpuContext::grid_workgroups_cap`] (few on a CPU adapter; the loop covers the rest).
    fn grid_stride_workgroups(&self, kernel: &Kernel, n: usize) -> u32 {
        kernel.workgroups_for(n).min(self.ctx.grid_workgroups_cap())
    }

    fn frame(&self) -> &FrameBuffers {
        self.frame
            .as_ref()
            .expect("preprocess() runs before any other step")
    }
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
        self.ensure_frame(params)?;
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
            Ok(())
        })?;
        let (w, h) = (params.width, params.height);
        let d2v_wg = self.kernels.depth_to_vertex.workgroups_for_image(w, h);
        let bf_wg = self.kernels.bilateral_filter.workgroups_for_image(w, h);
        let v2n_wg = self.kernels.vertex_to_normal.workgroups_for_image(w, h);
        let (ctx, k, bg, profiler) = encoding_parts!(self);
        ctx.scoped("preprocess", || {
            let mut enc = ctx.encoder("preprocess");
            let d2v = (&k.depth_to_vertex, &bg.depth_to_vertex, d2v_wg);
            let bf = (&k.bilateral_filter, &bg.bilateral_filter, bf_wg);
            let v2n = (&k.vertex_to_normal, &bg.vertex_to_normal, v2n_wg);
            let v2n_filtered = (&k.vertex_to_normal, &bg.vertex_to_normal_filtered, v2n_wg);
            let passes = match bilateral {
                Some(_) => vec![d2v, bf, v2n_filtered],
                None => vec![d2v, v2n],
            };
            record_passes(ctx, profiler, &mut enc, &passes)?;
            submit_profiled(ctx, profiler, enc)
        })
    }

    fn predict(&mut self, params: &ProjectParams) -> Result<()> {
        let mut params = *params;
        params.surfel_count = self.count as u32;
        let f = self.frame();
        let surfel_wg = self.grid_stride_workgroups(&self.kernels.project_model, self.count);
        let pix_wg = self
            .kernels
            .predict_model
            .workgroups_for_image(f.width, f.height);
        let (ctx, k, bg, profiler) = encoding_parts!(self);
        let f = self
            .frame
            .as_ref()
            .expect("preprocess() runs before predict()");
        ctx.scoped("predict", || {
            self.u_project.write(ctx, &params);
            let mut enc = ctx.encoder("predict");
            f.index_map.clear(&mut enc);
            record_passes(
                ctx,
                profiler,
                &mut enc,
                &[
                    (&k.project_model, &bg.project_model, [surfel_wg, 1]),
                    (&k.predict_model, &bg.predict_model, pix_wg),
                ],
            )?;
            submit_profiled(ctx, profiler, enc)
        })
    }

    fn icp_system(&mut self, params: &IcpParams) -> Result<[f64; ICP_SYSTEM_LEN]> {
        let wg = self.reduction_workgroups;
        let (ctx, k, bg, profiler) = encoding_parts!(self);
        let partials = ctx.scoped("icp_reduce", || {
            self.u_icp.write(ctx, params);
            let mut enc = ctx.encoder("icp_reduce");
            record_passes(
                ctx,
                profiler,
                &mut enc,
                &[(&k.icp_reduce, &bg.icp_reduce, [wg, 1])],
            )?;
            self.partials_readback.copy_from(
                &mut enc,
                &self.partials,
                wg as usize * ICP_SYSTEM_LEN,
            );
            submit_profiled(ctx, profiler, enc)?;
            self.partials_readback.read(ctx)
        })?;
        let mut sys = [0.0f64; ICP_SYSTEM_LEN];
        for part in partials.chunks_exact(ICP_SYSTEM_LEN) {
            for (s, &p) in sys.iter_mut().zip(part) {
                *s += p as f64;
            }
        }
        Ok(sys)
    }

    fn fuse(&mut self, params: &FuseParams) -> Result<usize> {
        let n = self.frame().pixels();
        self.ensure_capacity(self.count + n)?;
        let mut params = *params;
        params.surfel_count = self.count as u32;
        params.capacity = self.capacity() as u32;
        let surfel_wg = self.grid_stride_workgroups(&self.kernels.fuse_merge, self.count);
        let f = self.frame();
        let pix_wg = self
            .kernels
            .fuse_add
            .workgroups_for_image(f.width, f.height);
        let (ctx, k, bg, profiler) = encoding_parts!(self);
        let f = self
            .frame
            .as_ref()
            .expect("preprocess() runs before fuse()");
        let counter = ctx.scoped("fuse", || {
            self.u_fuse.write(ctx, &params);
            ctx.queue.write_buffer(
                self.counter.buffer(),
                0,
                bytemuck::bytes_of(&params.surfel_count),
            );
            let mut enc = ctx.encoder("fuse");
            f.assoc.clear(&mut enc);
            record_passes(
                ctx,
                profiler,
                &mut enc,
                &[
                    (&k.fuse_merge, &bg.fuse_merge, [surfel_wg, 1]),
                    (&k.fuse_add, &bg.fuse_add, pix_wg),
                ],
            )?;
            self.counter_readback.copy_from(&mut enc, &self.counter, 1);
            submit_profiled(ctx, profiler, enc)?;
            self.counter_readback.read(ctx)
        })?[0] as usize;
        if counter > params.capacity as usize {
            return Err(Error::Capacity(format!(
                "fuse_add counted {counter} surfels but only {} slots exist; surfels past \
                 the capacity were dropped (the host should have grown the map first)",
                params.capacity
            )));
        }
        self.count = counter;
        Ok(counter)
    }

    fn compact(&mut self, params: &CompactParams) -> Result<usize> {
        let n = self.count;
        if n == 0 {
            return Ok(0);
        }
        self.ensure_compaction()?;
        let mut params = *params;
        params.surfel_count = n as u32;
        let surfel_wg = self.grid_stride_workgroups(&self.kernels.compact_flags, n);
        let scatter_wg = self.grid_stride_workgroups(&self.kernels.compact_scatter, n);
        let (ctx, k, m) = (&self.ctx, &self.kernels, &self.map);
        let c = self.compaction.as_mut().expect("ensure_compaction made it");
        // Made once per map set (live and spare swap every call, and so do these).
        let g = c.groups.get_or_insert_with(|| CompactionGroups {
            flags: k.compact_flags.bind_group(
                ctx,
                &[
                    self.u_compact.binding(),
                    m.position_weight.binding(),
                    m.normal_frame.binding(),
                    c.flags.binding(),
                ],
            ),
            scan: k.prefix_sum.bind_group(
                ctx,
                &[
                    self.u_compact.binding(),
                    c.flags.binding(),
                    c.offsets.binding(),
                    self.counter.binding(),
                ],
            ),
            scatter: k.compact_scatter.bind_group(
                ctx,
                &[
                    self.u_compact.binding(),
                    c.flags.binding(),
                    c.offsets.binding(),
                    m.position_weight.binding(),
                    m.normal_frame.binding(),
                    m.color.binding(),
                    c.spare.position_weight.binding(),
                    c.spare.normal_frame.binding(),
                    c.spare.color.binding(),
                ],
            ),
        });
        let profiler = &mut self.profiler;
        let kept = ctx.scoped("compact", || {
            self.u_compact.write(ctx, &params);
            let mut enc = ctx.encoder("compact");
            record_passes(
                ctx,
                profiler,
                &mut enc,
                &[
                    (&k.compact_flags, &g.flags, [surfel_wg, 1]),
                    (&k.prefix_sum, &g.scan, [1, 1]),
                    (&k.compact_scatter, &g.scatter, [scatter_wg, 1]),
                ],
            )?;
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
        Ok(kept)
    }

    fn surfel_count(&self) -> usize {
        self.count
    }

    fn download_map(&mut self) -> Result<SurfelMap> {
        let (ctx, m) = (&self.ctx, &self.map);
        ctx.scoped("download map", || {
            let map = m.download(ctx, self.count)?;
            map.assert_consistent();
            Ok(map)
        })
    }

    /// Writes `map` into the live map textures (growing them first if needed) and sets
    /// the count; the spare map set is untouched (compaction overwrites it).
    fn upload_map(&mut self, map: &SurfelMap) -> Result<()> {
        map.assert_consistent();
        let n = map.len();
        self.ensure_capacity(n)?;
        let (ctx, m) = (&self.ctx, &self.map);
        ctx.scoped("upload map", || m.upload(ctx, map))?;
        self.count = n;
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
            })
        })
    }

    fn download_prediction(&mut self) -> Result<crate::slam::pipeline::Prediction> {
        let Some(f) = self.frame.as_ref() else {
            return Ok((Vec::new(), Vec::new()));
        };
        let ctx = &self.ctx;
        ctx.scoped("download prediction", || {
            Ok((
                read_map(ctx, &f.pred_vertex)?,
                read_map(ctx, &f.pred_normal)?,
            ))
        })
    }

    fn counters(&self) -> BackendCounters {
        let s = self.ctx.stats();
        BackendCounters {
            readback_bytes: s.readback_bytes,
            submissions: s.submissions,
        }
    }

    fn finish(&mut self) -> Result<()> {
        self.ctx.wait_idle()
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
