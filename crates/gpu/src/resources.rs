//! The GPU backend's per-frame resources: the kernels' parameter buffers ([`Uniforms`],
//! made once) and the buffers sized by the frame ([`FrameBuffers`]: raw inputs, per-pixel
//! maps as textures, the prediction, the association buffers, the pyramid's coarser levels),
//! made at the first `preprocess` and again only when the frame size or the pyramid changes;
//! and ICP's reduced systems ([`Systems`], made once).
//! The surfel map is [`super::map_buffers::MapBuffers`]; the bind groups over all of them are
//! [`super::bind_groups`].

use super::buffers::{GpuArray, ParamBuffer, Readback};
use super::context::GpuContext;
use super::images::GpuImage;
use crate::layout::append_slots;
use crate::layout::{
    BilateralParams, BoundsParams, CompactParams, DeformParams, FernParams, FuseParams, IcpParams,
    IntensityParams, KeypointParams, NormalParams, PreprocessParams, ProjectParams, PyramidParams,
    ICP_SYSTEM_LEN,
};
use crate::Result;
use wgslam_core::backend::PyramidLevel;

/// One parameter buffer per kernel parameter struct, written before each step (one per
/// step at a time: a step's passes share its buffer).
pub(super) struct Uniforms {
    pub preprocess: ParamBuffer<PreprocessParams>,
    pub bilateral: ParamBuffer<BilateralParams>,
    pub normal: ParamBuffer<NormalParams>,
    pub project: ParamBuffer<ProjectParams>,
    pub icp: ParamBuffer<IcpParams>,
    pub fuse: ParamBuffer<FuseParams>,
    /// The scan's parameters (`layout::scan_params`), written by the step that scans:
    /// fusion over its new-surfel flags, compaction over its keep flags.
    pub scan: ParamBuffer<CompactParams>,
    pub compact: ParamBuffer<CompactParams>,
    /// `block_bounds`' parameters.
    pub bounds: ParamBuffer<BoundsParams>,
    /// `deform_surfels`' parameters (a loop closure's deformation).
    pub deform: ParamBuffer<DeformParams>,
    /// `fern_encode`'s parameters.
    pub ferns: ParamBuffer<FernParams>,
    /// The keypoint kernels' parameters.
    pub keypoints: ParamBuffer<KeypointParams>,
}

impl Uniforms {
    /// Every parameter buffer, zeroed.
    pub fn new(ctx: &GpuContext) -> Uniforms {
        Uniforms {
            preprocess: ParamBuffer::new(ctx, "PreprocessParams", &bytemuck::Zeroable::zeroed()),
            bilateral: ParamBuffer::new(ctx, "BilateralParams", &bytemuck::Zeroable::zeroed()),
            normal: ParamBuffer::new(ctx, "NormalParams", &bytemuck::Zeroable::zeroed()),
            project: ParamBuffer::new(ctx, "ProjectParams", &bytemuck::Zeroable::zeroed()),
            icp: ParamBuffer::new(ctx, "IcpParams", &bytemuck::Zeroable::zeroed()),
            fuse: ParamBuffer::new(ctx, "FuseParams", &bytemuck::Zeroable::zeroed()),
            scan: ParamBuffer::new(ctx, "CompactParams (scan)", &bytemuck::Zeroable::zeroed()),
            compact: ParamBuffer::new(ctx, "CompactParams", &bytemuck::Zeroable::zeroed()),
            bounds: ParamBuffer::new(ctx, "BoundsParams", &bytemuck::Zeroable::zeroed()),
            deform: ParamBuffer::new(ctx, "DeformParams", &bytemuck::Zeroable::zeroed()),
            ferns: ParamBuffer::new(ctx, "FernParams", &bytemuck::Zeroable::zeroed()),
            keypoints: ParamBuffer::new(ctx, "KeypointParams", &bytemuck::Zeroable::zeroed()),
        }
    }
}

/// Buffers sized by the frame: raw inputs, per-pixel maps, prediction, association flags.
pub(super) struct FrameBuffers {
    pub raw_width: u32,
    pub raw_height: u32,
    pub width: u32,
    pub height: u32,
    pub raw_depth: GpuImage,
    pub raw_rgba: GpuImage,
    /// `depth_to_vertex`'s output, never filtered.
    pub vertex: GpuImage,
    /// `bilateral_filter`'s output; meaningful only when `filtered` is set.
    pub filtered_vertex: GpuImage,
    /// Whether the last `preprocess` ran the filter (and made the normals from
    /// `filtered_vertex`).
    pub filtered: bool,
    /// The normal map with the vertex's depth in w (see vertex_to_normal.wgsl).
    pub normal_depth: GpuImage,
    pub color: GpuImage,
    pub index_map: GpuArray<u64>,
    pub pred_vertex: GpuImage,
    pub pred_normal: GpuImage,
    /// `predict_model`'s predicted intensity per pixel (0..1; see `cpu::photo_reduce`).
    pub pred_intensity: GpuArray<f32>,
    /// Level 0 of the intensity pyramid (`intensity_pyramid`, RGB-D tracking only) and
    /// its parameters (fixed by the frame's size).
    pub intensity: IntensityLevel,
    /// One u64 key per pixel: fuse_select's choice, or fuse_merge's flag.
    pub assoc: GpuArray<u64>,
    /// Per pixel, the surfel it merged into (two entries; see fuse_merge_chosen.wgsl),
    /// cleared and filled on every frame of best-candidate association (fuse_flags and
    /// fuse_prune read it).
    pub merged: GpuArray<[f32; 4]>,
    /// Fusion's new-surfel flag and slot offset per pixel (`fuse_flags`, the scan), in
    /// append order (`append_slots` entries; see `layout::APPEND_TILE_PX`).
    pub add_flags: GpuArray<u32>,
    pub add_offsets: GpuArray<u32>,
    /// The scan's per-block sums over `add_flags`.
    pub add_block_sums: GpuArray<u32>,
    /// The ICP pyramid's coarser levels 1, 2, ... (none with a one-level schedule).
    pub levels: Vec<LevelBuffers>,
}

/// One coarser level (1, 2, ...) of the ICP pyramid: the frame's and the model's maps at
/// its size, and the uniforms of the kernels that make them (one per level: `preprocess`
/// records every level's passes in one submission, so they cannot share one).
pub(super) struct LevelBuffers {
    pub width: u32,
    pub height: u32,
    /// `pyramid_depth`'s output.
    pub vertex: GpuImage,
    pub normal_depth: GpuImage,
    /// `pyramid_model`'s outputs.
    pub pred_vertex: GpuImage,
    pub pred_normal: GpuImage,
    pub u_pyramid: ParamBuffer<PyramidParams>,
    pub u_normal: ParamBuffer<NormalParams>,
    /// The level of the intensity pyramid.
    pub intensity: IntensityLevel,
}

/// One pyramid level's parameter buffers by the names the registry's `generic_levels` rows
/// give as their uniforms (see [`FrameBuffers::level_uniforms`]); `None` where the level
/// has none, and then a row of that uniform has no bind group there (level 0 is made by no
/// pyramid kernel).
pub(super) struct LevelUniforms<'a> {
    /// `vertex_to_normal`'s.
    pub normal: Option<wgpu::BindingResource<'a>>,
    /// `pyramid_depth`'s and `pyramid_model`'s (the level's size and its finer level's).
    pub pyramid: Option<wgpu::BindingResource<'a>>,
    /// `intensity_pyramid`'s (the level's [`IntensityLevel`]'s).
    pub intensity: Option<wgpu::BindingResource<'a>>,
}

/// One level of the frame's intensity pyramid: `intensity_pyramid`'s output and its
/// parameters (written once: they depend on the sizes only).
pub(super) struct IntensityLevel {
    pub patch: GpuImage,
    pub u_params: ParamBuffer<IntensityParams>,
}

impl IntensityLevel {
    fn new(ctx: &GpuContext, params: IntensityParams) -> Result<Self> {
        Ok(IntensityLevel {
            patch: GpuImage::new(
                ctx,
                "intensity patches",
                params.width,
                params.height,
                wgpu::TextureFormat::Rgba32Float,
                true,
            )?,
            u_params: ParamBuffer::new(ctx, "IntensityParams", &params),
        })
    }
}

impl FrameBuffers {
    /// The buffers for frames of `p`'s raw and map sizes with `pyramid`'s coarser levels.
    pub fn new(ctx: &GpuContext, p: &PreprocessParams, pyramid: &[PyramidLevel]) -> Result<Self> {
        let n = (p.camera.width * p.camera.height) as usize;
        let full = |label: &str| -> Result<GpuImage> {
            GpuImage::new(
                ctx,
                label,
                p.camera.width,
                p.camera.height,
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
        let n_append = append_slots(p.camera.width, p.camera.height);
        let mut add_flags = GpuArray::new(ctx, "new-surfel flags", n_append)?;
        add_flags.set_len(n_append);
        let mut add_offsets = GpuArray::new(ctx, "new-surfel offsets", n_append)?;
        add_offsets.set_len(n_append);
        let n_blocks = crate::layout::scan_blocks(n_append);
        let mut add_block_sums = GpuArray::new(ctx, "new-surfel block sums", n_blocks)?;
        add_block_sums.set_len(n_blocks);
        let mut intensity =
            PyramidLevel::intensity_params(p.camera.width, p.camera.height, pyramid).into_iter();
        let intensity0 = IntensityLevel::new(ctx, intensity.next().expect("level 0"))?;
        let levels = pyramid
            .iter()
            .zip(intensity)
            .map(|(l, intensity)| {
                let (w, h) = (l.down.camera.width, l.down.camera.height);
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
                    intensity: IntensityLevel::new(ctx, intensity)?,
                })
            })
            .collect::<Result<Vec<_>>>()?;
        let mut pred_intensity = GpuArray::new(ctx, "predicted intensity", n)?;
        pred_intensity.set_len(n);
        Ok(FrameBuffers {
            raw_width: p.raw_width,
            raw_height: p.raw_height,
            width: p.camera.width,
            height: p.camera.height,
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
            pred_intensity,
            intensity: intensity0,
            assoc,
            merged,
            add_flags,
            add_offsets,
            add_block_sums,
            levels,
        })
    }

    /// Whether these buffers fit frames of `p`'s sizes with `pyramid`'s levels.
    pub fn fits(&self, p: &PreprocessParams, pyramid: &[PyramidLevel]) -> bool {
        (self.raw_width, self.raw_height, self.width, self.height)
            == (p.raw_width, p.raw_height, p.camera.width, p.camera.height)
            && self.levels.len() == pyramid.len()
            && self
                .levels
                .iter()
                .zip(pyramid)
                .all(|(l, p)| (l.width, l.height) == (p.down.camera.width, p.down.camera.height))
    }

    /// Pyramid level `level`'s parameter buffers, as a `generic_levels` row of the registry
    /// names its uniform: level 0's are the frame's (`u`), a coarser level's its own.
    pub fn level_uniforms<'a>(&'a self, u: &'a Uniforms, level: usize) -> LevelUniforms<'a> {
        match level {
            0 => LevelUniforms {
                normal: Some(u.normal.binding()),
                pyramid: None,
                intensity: Some(self.intensity.u_params.binding()),
            },
            l => {
                let lv = &self.levels[l - 1];
                LevelUniforms {
                    normal: Some(lv.u_normal.binding()),
                    pyramid: Some(lv.u_pyramid.binding()),
                    intensity: Some(lv.intensity.u_params.binding()),
                }
            }
        }
    }

    pub fn pixels(&self) -> usize {
        (self.width * self.height) as usize
    }
}

/// ICP's and RGB-D tracking's normal-equation systems on the GPU (see
/// `GpuBackend::systems`), made with the backend and never re-created.
pub(super) struct Systems {
    /// Per system, in `System::ALL`'s order (geometric, photometric): its reduction's
    /// per-workgroup partial systems and their sum (`ICP_SYSTEM_LEN` floats).
    pub buffers: [SystemBuffers; 2],
    /// The sums an ICP iteration reads, `ICP_SYSTEM_LEN` floats each, in plan order.
    pub readback: Readback<f32>,
    /// How many levels of the frame's intensity pyramid (`intensity_pyramid`), finest
    /// first, are of the last `preprocess`'s frame: each made by the frame's first
    /// `rgbd_system` at it or a coarser level.
    pub intensity_made: usize,
}

/// One system's buffers: the per-workgroup partial systems (`system_floats` floats) and
/// their sum.
pub(super) struct SystemBuffers {
    pub partials: GpuArray<f32>,
    pub sum: GpuArray<f32>,
}

impl Systems {
    /// Partials of `system_floats` per system, the sums and the read-back of both.
    pub fn new(ctx: &GpuContext, system_floats: usize) -> Result<Self> {
        let buffers = |what: &str| -> Result<SystemBuffers> {
            let mut partials = GpuArray::new(ctx, &format!("{what} partials"), system_floats)?;
            partials.set_len(system_floats);
            let mut sum = GpuArray::new(ctx, &format!("{what} system"), ICP_SYSTEM_LEN)?;
            sum.set_len(ICP_SYSTEM_LEN);
            Ok(SystemBuffers { partials, sum })
        };
        Ok(Systems {
            buffers: [buffers("icp")?, buffers("photometric")?],
            readback: Readback::new(ctx, "icp systems read-back", 2 * ICP_SYSTEM_LEN),
            intensity_made: 0,
        })
    }
}
