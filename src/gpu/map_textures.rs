//! The surfel map on the GPU: five 2D textures, one per attribute (structure of arrays,
//! world frame), [`MAP_TEXTURE_WIDTH`] texels wide, surfel `i` at texel
//! `(i % MAP_TEXTURE_WIDTH, i / MAP_TEXTURE_WIDTH)`.
//!
//! Textures rather than storage buffers because lavapipe loads texels 2-4x faster than
//! storage-buffer elements (measured in `images.rs`), and every frame reads the whole map
//! twice (`project_model`, `fuse_merge`). `fuse_merge` reads and writes its own surfel
//! through read-write storage textures (rgba32float needs the adapter-specific format
//! feature; `GpuBackend::new` checks it). The logical capacity may be smaller than the
//! texture (whole rows): kernels never write at or past it.

use super::context::GpuContext;
use super::images::GpuImage;
use crate::layout::MAP_TEXTURE_WIDTH;
use crate::map::SurfelMap;
use crate::Result;

/// Surfel attributes as textures, `capacity` logical slots each.
pub struct MapTextures {
    /// rgba32float: xyz metres, w = 1.
    pub positions: GpuImage,
    /// rgba32float: unit xyz, w = 0.
    pub normals: GpuImage,
    /// rgba32float: RGB 0..255, a = 255.
    pub colors: GpuImage,
    /// r32float: observations.
    pub weights: GpuImage,
    /// r32uint: frame that last touched the surfel.
    pub last_frame: GpuImage,
    capacity: usize,
}

impl MapTextures {
    /// Largest map the device's texture size limit allows, in surfels.
    pub fn device_max_surfels(ctx: &GpuContext) -> usize {
        let rows = ctx.limits().max_texture_dimension_2d as usize;
        (MAP_TEXTURE_WIDTH as usize * rows).min(u32::MAX as usize)
    }

    /// Zero-filled textures with room for `capacity` surfels (whole rows).
    pub fn new(ctx: &GpuContext, capacity: usize) -> Result<MapTextures> {
        let rows = capacity.max(1).div_ceil(MAP_TEXTURE_WIDTH as usize) as u32;
        let image = |label: &str, format| {
            GpuImage::new(ctx, label, MAP_TEXTURE_WIDTH, rows, format, true)
        };
        use wgpu::TextureFormat as F;
        Ok(MapTextures {
            positions: image("surfel positions", F::Rgba32Float)?,
            normals: image("surfel normals", F::Rgba32Float)?,
            colors: image("surfel colors", F::Rgba32Float)?,
            weights: image("surfel weights", F::R32Float)?,
            last_frame: image("surfel last_frame", F::R32Uint)?,
            capacity,
        })
    }

    /// Logical surfel slots.
    pub fn capacity(&self) -> usize {
        self.capacity
    }

    /// Re-allocates with room for `new_capacity` surfels and copies the first `keep` on the
    /// GPU (one submission). No-op when already large enough.
    pub fn grow(&mut self, ctx: &GpuContext, new_capacity: usize, keep: usize) -> Result<()> {
        if new_capacity <= self.capacity {
            return Ok(());
        }
        let bigger = MapTextures::new(ctx, new_capacity)?;
        let keep = keep.min(self.capacity);
        let mut enc = ctx.encoder("grow surfel map");
        for (from, to) in self.images().into_iter().zip(bigger.images()) {
            from.copy_prefix_to(&mut enc, to, keep);
        }
        ctx.submit(enc);
        *self = bigger;
        Ok(())
    }

    /// The first `n` surfels, downloaded.
    pub fn download(&self, ctx: &GpuContext, n: usize) -> Result<SurfelMap> {
        Ok(SurfelMap {
            positions: self.positions.read_back_prefix(ctx, n)?,
            normals: self.normals.read_back_prefix(ctx, n)?,
            colors: self.colors.read_back_prefix(ctx, n)?,
            weights: self.weights.read_back_prefix(ctx, n)?,
            last_frame: self.last_frame.read_back_prefix(ctx, n)?,
        })
    }

    /// Writes `map` into slots `0..map.len()` (the caller grows first).
    pub fn upload(&self, ctx: &GpuContext, map: &SurfelMap) -> Result<()> {
        self.positions.upload_prefix(ctx, &map.positions)?;
        self.normals.upload_prefix(ctx, &map.normals)?;
        self.colors.upload_prefix(ctx, &map.colors)?;
        self.weights.upload_prefix(ctx, &map.weights)?;
        self.last_frame.upload_prefix(ctx, &map.last_frame)
    }

    fn images(&self) -> [&GpuImage; 5] {
        [
            &self.positions,
            &self.normals,
            &self.colors,
            &self.weights,
            &self.last_frame,
        ]
    }
}
