//! [`GpuImage`]: a 2D texture holding one per-pixel map (width x height texels, row-major
//! like the CPU twins' `Vec`s, pixel `k` at `(k % width, k / width)`), with upload and
//! read-back.
//!
//! Why textures and not storage buffers for per-pixel maps: on Mesa lavapipe (the CPU
//! Vulkan driver) a storage-buffer load is emitted as a loop over the SIMD lanes with one
//! scalar load and bounds check per lane and component, while `textureLoad` goes through
//! the vectorised texel-fetch path. Measured here (`examples/lvp_probe.rs`, 640x480, five
//! vec4 loads per pixel): 23-28 ms from a storage buffer, 5-8 ms from a texture; a random
//! gather of 307k vec4 from a 1.3M-entry table: 18 ms vs 7.7 ms. Writes stay cheap either
//! way, so kernels write maps through write-only storage textures.

use std::sync::Arc;

use bytemuck::Pod;

use super::buffers::{map_read, GpuStats};
use super::context::GpuContext;
use crate::{Error, Result};

/// A 2D texture of one format, sampled with `textureLoad` and/or written as a write-only
/// storage texture.
pub struct GpuImage {
    texture: wgpu::Texture,
    view: wgpu::TextureView,
    width: u32,
    height: u32,
    format: wgpu::TextureFormat,
    label: String,
    bytes: u64,
    stats: Arc<GpuStats>,
}

impl std::fmt::Debug for GpuImage {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GpuImage")
            .field("label", &self.label)
            .field("width", &self.width)
            .field("height", &self.height)
            .field("format", &self.format)
            .finish()
    }
}

impl Drop for GpuImage {
    fn drop(&mut self) {
        self.stats.free(self.bytes);
    }
}

impl GpuImage {
    /// A `width x height` texture of `format` usable as a sampled texture, a storage
    /// texture (when `storage`), and a copy source and destination. [`Error::Capacity`] when a
    /// side exceeds the device's `max_texture_dimension_2d`.
    pub fn new(
        ctx: &GpuContext,
        label: &str,
        width: u32,
        height: u32,
        format: wgpu::TextureFormat,
        storage: bool,
    ) -> Result<GpuImage> {
        let max = ctx.limits().max_texture_dimension_2d;
        if width == 0 || height == 0 || width > max || height > max {
            return Err(Error::Capacity(format!(
                "{label}: a {width}x{height} texture is outside the device's 1..={max} \
                 texels per side"
            )));
        }
        let mut usage = wgpu::TextureUsages::TEXTURE_BINDING
            | wgpu::TextureUsages::COPY_SRC
            | wgpu::TextureUsages::COPY_DST;
        if storage {
            usage |= wgpu::TextureUsages::STORAGE_BINDING;
        }
        let texture = ctx.device.create_texture(&wgpu::TextureDescriptor {
            label: Some(label),
            size: wgpu::Extent3d {
                width,
                height,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format,
            usage,
            view_formats: &[],
        });
        let view = texture.create_view(&wgpu::TextureViewDescriptor::default());
        let bytes = width as u64 * height as u64 * texel_bytes(format) as u64;
        ctx.stats_handle().alloc(bytes);
        Ok(GpuImage {
            texture,
            view,
            width,
            height,
            format,
            label: label.to_string(),
            bytes,
            stats: Arc::clone(ctx.stats_handle()),
        })
    }

    /// Texels per row.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Rows.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// The whole texture as a bind-group resource (sampled or storage, as the layout says).
    pub fn binding(&self) -> wgpu::BindingResource<'_> {
        wgpu::BindingResource::TextureView(&self.view)
    }

    /// Uploads `texels` (row-major, exactly width x height of them) with `write_texture`.
    pub fn upload<T: Pod>(&self, ctx: &GpuContext, texels: &[T]) -> Result<()> {
        let n = self.width as usize * self.height as usize;
        if texels.len() != n || std::mem::size_of::<T>() != texel_bytes(self.format) as usize {
            return Err(Error::Argument(format!(
                "{}: upload of {} texels of {} bytes into a {}x{} texture of {:?}",
                self.label,
                texels.len(),
                std::mem::size_of::<T>(),
                self.width,
                self.height,
                self.format
            )));
        }
        let bytes: &[u8] = bytemuck::cast_slice(texels);
        ctx.queue.write_texture(
            self.texture.as_image_copy(),
            bytes,
            wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(self.width * texel_bytes(self.format)),
                rows_per_image: Some(self.height),
            },
            self.extent(),
        );
        self.stats.upload(bytes.len() as u64);
        Ok(())
    }

    /// Copies every texel back to the host, row-major, without the row padding
    /// `copy_texture_to_buffer` needs (one submission, blocking).
    pub fn read_back<T: Pod>(&self, ctx: &GpuContext) -> Result<Vec<T>> {
        let texel = texel_bytes(self.format);
        if std::mem::size_of::<T>() != texel as usize {
            return Err(Error::Argument(format!(
                "{}: reading {:?} texels as {} bytes each",
                self.label,
                self.format,
                std::mem::size_of::<T>()
            )));
        }
        let row = self.width * texel;
        let padded_row = row.div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT)
            * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT;
        let staging = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("wgslam texture read-back staging"),
            size: padded_row as u64 * self.height as u64,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut enc = ctx.encoder("texture read back");
        enc.copy_texture_to_buffer(
            self.texture.as_image_copy(),
            wgpu::TexelCopyBufferInfo {
                buffer: &staging,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(padded_row),
                    rows_per_image: Some(self.height),
                },
            },
            self.extent(),
        );
        ctx.submit(enc);
        let out = map_read(ctx, &staging, |view| {
            let mut bytes = Vec::with_capacity(row as usize * self.height as usize);
            for r in view.chunks_exact(padded_row as usize) {
                bytes.extend_from_slice(&r[..row as usize]);
            }
            bytemuck::pod_collect_to_vec::<u8, T>(&bytes)
        })?;
        self.stats.readback(row as u64 * self.height as u64);
        Ok(out)
    }

    fn extent(&self) -> wgpu::Extent3d {
        wgpu::Extent3d {
            width: self.width,
            height: self.height,
            depth_or_array_layers: 1,
        }
    }
}

/// Bytes per texel of the formats used here.
fn texel_bytes(format: wgpu::TextureFormat) -> u32 {
    format
        .block_copy_size(None)
        .expect("only plain colour formats are used")
}
