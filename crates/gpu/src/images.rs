//! [`GpuImage`]: a 2D texture holding one per-pixel map (width x height texels, row-major
//! like the CPU twins' `Vec`s, pixel `k` at `(k % width, k / width)`), with upload and
//! read-back.
//!
//! Why textures and not storage buffers for per-pixel maps: on Mesa lavapipe (the CPU
//! Vulkan driver) a storage-buffer load is emitted as a loop over the SIMD lanes with one
//! scalar load and bounds check per lane and component, while `textureLoad` goes through
//! the vectorised texel-fetch path. Measured here with `examples/lavapipe_loads.rs`
//! (fastest of 10 dispatches, several runs): a 5-point stencil over 640x480 took 22-28 ms
//! from a storage buffer and 4-8 ms from a texture; a sequential pass over 1.3M vec4 23-25
//! ms vs 8 ms; a gather of 307k vec4 at scattered indices from 1.3M 10-18 ms vs 6-8 ms.
//! Writes cost about the same either way (one scalar store per lane and component), so
//! kernels write maps through write-only storage textures.

use std::sync::Arc;

use bytemuck::Pod;

use super::buffers::map_read;
use super::context::GpuContext;
use super::stats::GpuStats;
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

    /// Uploads `texels` (row-major, exactly width x height of them).
    pub fn upload<T: Pod>(&self, ctx: &GpuContext, texels: &[T]) -> Result<()> {
        let n = self.texels();
        if texels.len() != n {
            return Err(Error::Argument(format!(
                "{}: upload of {} texels into a {}x{} texture",
                self.label,
                texels.len(),
                self.width,
                self.height
            )));
        }
        self.upload_prefix(ctx, texels)
    }

    /// Writes `texels` into texels `0..texels.len()` (row-major) with `write_texture`; the
    /// rest of the last row written is zeroed. [`Error::Argument`] when they do not fit or
    /// `T` is not one texel.
    pub fn upload_prefix<T: Pod>(&self, ctx: &GpuContext, texels: &[T]) -> Result<()> {
        self.check_texel_type::<T>()?;
        if texels.len() > self.texels() {
            return Err(Error::Argument(format!(
                "{}: {} texels do not fit a {}x{} texture",
                self.label,
                texels.len(),
                self.width,
                self.height
            )));
        }
        let rows = self.rows_for(texels.len());
        if rows == 0 {
            return Ok(());
        }
        // Only a partial last row needs a padded copy (map uploads); whole frames go as is.
        let whole = rows as usize * self.width as usize;
        let padded: Vec<T>;
        let texels = if texels.len() == whole {
            texels
        } else {
            padded = texels
                .iter()
                .copied()
                .chain(std::iter::repeat(T::zeroed()))
                .take(whole)
                .collect();
            &padded
        };
        let bytes: &[u8] = bytemuck::cast_slice(texels);
        ctx.write_texture(
            self.texture.as_image_copy(),
            bytes,
            wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(self.width * texel_bytes(self.format)),
                rows_per_image: Some(rows),
            },
            self.extent_rows(rows),
        );
        self.stats.upload(bytes.len() as u64);
        Ok(())
    }

    /// Copies every texel back to the host, row-major (one submission, blocking).
    pub fn read_back<T: Pod>(&self, ctx: &GpuContext) -> Result<Vec<T>> {
        self.read_back_prefix(ctx, self.texels())
    }

    /// Copies texels `0..n` (row-major) back to the host: the rows holding them go through
    /// a staging buffer with the 256-byte row pitch `copy_texture_to_buffer` needs, and the
    /// padding is dropped (one submission, blocking).
    pub fn read_back_prefix<T: Pod>(&self, ctx: &GpuContext, n: usize) -> Result<Vec<T>> {
        self.check_texel_type::<T>()?;
        if n > self.texels() {
            return Err(Error::Capacity(format!(
                "{}: read-back of {n} texels from a {}x{} texture",
                self.label, self.width, self.height
            )));
        }
        let rows = self.rows_for(n);
        if rows == 0 {
            return Ok(Vec::new());
        }
        let row = self.width * texel_bytes(self.format);
        let padded_row =
            row.div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT) * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT;
        let staging = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("wgslam texture read-back staging"),
            size: padded_row as u64 * rows as u64,
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
                    rows_per_image: Some(rows),
                },
            },
            self.extent_rows(rows),
        );
        ctx.submit(enc);
        let out = map_read(ctx, &staging, |view| {
            let mut bytes = Vec::with_capacity(row as usize * rows as usize);
            for r in view.chunks_exact(padded_row as usize) {
                bytes.extend_from_slice(&r[..row as usize]);
            }
            let mut texels = bytemuck::pod_collect_to_vec::<u8, T>(&bytes);
            texels.truncate(n);
            texels
        })?;
        self.stats.readback((n * std::mem::size_of::<T>()) as u64);
        Ok(out)
    }

    /// Records a GPU copy of the rows holding texels `0..n` into `dst` (same width and
    /// format, at least as tall): how the surfel map grows.
    pub fn copy_prefix_to(&self, encoder: &mut wgpu::CommandEncoder, dst: &GpuImage, n: usize) {
        assert!(
            dst.width == self.width && dst.format == self.format && n <= dst.texels(),
            "{} -> {}: copy of {n} texels between incompatible textures",
            self.label,
            dst.label
        );
        let rows = self.rows_for(n.min(self.texels()));
        if rows > 0 {
            encoder.copy_texture_to_texture(
                self.texture.as_image_copy(),
                dst.texture.as_image_copy(),
                self.extent_rows(rows),
            );
        }
    }

    /// width x height.
    pub fn texels(&self) -> usize {
        self.width as usize * self.height as usize
    }

    fn rows_for(&self, n: usize) -> u32 {
        n.div_ceil(self.width as usize) as u32
    }

    fn check_texel_type<T>(&self) -> Result<()> {
        if std::mem::size_of::<T>() != texel_bytes(self.format) as usize {
            return Err(Error::Argument(format!(
                "{}: {:?} texels accessed as {} bytes each",
                self.label,
                self.format,
                std::mem::size_of::<T>()
            )));
        }
        Ok(())
    }

    fn extent_rows(&self, rows: u32) -> wgpu::Extent3d {
        wgpu::Extent3d {
            width: self.width,
            height: rows,
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
