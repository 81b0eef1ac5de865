//! The surfel map on the GPU: three 2D textures [`MAP_TEXTURE_WIDTH`] texels wide, surfel
//! `i` at texel `(i % MAP_TEXTURE_WIDTH, i / MAP_TEXTURE_WIDTH)` of each, packing the five
//! surfel attributes (world frame) exactly as [`SurfelMap`] holds them on the host:
//!
//! | texture | format | x, y, z | w |
//! |---|---|---|---|
//! | `position_weight` | rgba32float | position, metres | weight |
//! | `normal_frame` | rgba32uint | bits of the unit normal (`bitcast<u32>`) | last_frame |
//! | `color` | rgba32float | RGB 0..255 | 255 |
//!
//! Textures rather than storage buffers because lavapipe loads texels 3-5x faster than
//! storage-buffer elements (measured by `examples/lavapipe_loads.rs`), and every frame
//! reads the whole map twice (`project_model`, `fuse_merge`). Packing five attributes into three texels cuts
//! `fuse_merge`'s loads and stores per merged surfel from five to three; the packing is
//! exact (the normal's bits are kept, not converted). `fuse_merge` reads and writes its
//! own surfel through read-write storage textures (128-bit formats need the
//! adapter-specific format feature; `GpuBackend::new` checks it). The logical capacity may
//! be smaller than the textures (whole rows): kernels never write at or past it.

use super::context::GpuContext;
use super::images::GpuImage;
use crate::layout::MAP_TEXTURE_WIDTH;
use crate::slam::map::SurfelMap;
use crate::Result;

/// Surfel attributes packed into three textures, `capacity` logical slots each.
pub struct MapTextures {
    /// rgba32float: xyz metres, w = weight.
    pub position_weight: GpuImage,
    /// rgba32uint: xyz = bits of the unit normal, w = last_frame.
    pub normal_frame: GpuImage,
    /// rgba32float: RGB 0..255, a = 255.
    pub color: GpuImage,
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
        let image =
            |label: &str, format| GpuImage::new(ctx, label, MAP_TEXTURE_WIDTH, rows, format, true);
        use wgpu::TextureFormat as F;
        Ok(MapTextures {
            position_weight: image("surfel position+weight", F::Rgba32Float)?,
            normal_frame: image("surfel normal+last_frame", F::Rgba32Uint)?,
            color: image("surfel color", F::Rgba32Float)?,
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

    /// The first `n` surfels, downloaded: the textures' texels are `SurfelMap`'s packing,
    /// so this is a plain copy.
    pub fn download(&self, ctx: &GpuContext, n: usize) -> Result<SurfelMap> {
        Ok(SurfelMap {
            position_weight: self.position_weight.read_back_prefix(ctx, n)?,
            normal_frame: self.normal_frame.read_back_prefix(ctx, n)?,
            color: self.color.read_back_prefix(ctx, n)?,
        })
    }

    /// Writes `map` into slots `0..map.len()` as it is (the caller grows first).
    pub fn upload(&self, ctx: &GpuContext, map: &SurfelMap) -> Result<()> {
        self.position_weight
            .upload_prefix(ctx, &map.position_weight)?;
        self.normal_frame.upload_prefix(ctx, &map.normal_frame)?;
        self.color.upload_prefix(ctx, &map.color)
    }

    fn images(&self) -> [&GpuImage; 3] {
        [&self.position_weight, &self.normal_frame, &self.color]
    }
}
