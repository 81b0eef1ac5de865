//! The GPU pass of the renderer: `render_splat` then `render_resolve` in one submission,
//! the same kernels as the CPU twins in `crates/core/src/cpu/render_*.rs`.
//!
//! Thin wrapper: two kernels created once, buffers created per picture (a render is a
//! one-off, not a per-frame step), one read-back of the packed pixels. `render_splat` is
//! a [`KeyKernel`]: the 64-bit kernel, or on a device without 64-bit atomics its portable
//! variant `render_splat_portable` in two passes, with the same keys.

use image::RgbImage;

use super::{render_params, rgba_to_image, Cloud, RenderCamera, RenderSettings, View};
use crate::gpu::kernel::KeyKernel;
use crate::gpu::{GpuArray, GpuContext, Kernel, ParamBuffer};
use crate::layout::render::RenderParams;
use crate::Result;
use wgslam_core::registry::KernelId;

/// The two render kernels, created once per context.
#[derive(Debug)]
pub struct GpuRenderer {
    splat: KeyKernel,
    resolve: Kernel,
}

impl GpuRenderer {
    /// Creates the pipelines (three on a device without 64-bit atomics).
    pub fn new(ctx: &GpuContext) -> Result<GpuRenderer> {
        Ok(GpuRenderer {
            splat: KeyKernel::of(ctx, KernelId::render_splat)?,
            resolve: Kernel::of(ctx, KernelId::render_resolve)?,
        })
    }

    /// Runs both kernels for `params` and reads back the index map and the packed pixels
    /// (`width * height` each, row-major). Attributes the cloud lacks are bound as a
    /// one-element dummy that the chosen view never reads. [`Error::Capacity`] when a
    /// buffer exceeds the device's storage-binding limit.
    pub fn render_raw(
        &self,
        ctx: &GpuContext,
        params: &RenderParams,
        cloud: &Cloud,
    ) -> Result<(Vec<u64>, Vec<u32>)> {
        cloud.check()?;
        assert!(
            params.surfel_count as usize <= cloud.positions.len(),
            "surfel_count past the positions"
        );
        let n = params.camera.width as usize * params.camera.height as usize;
        const DUMMY4: [[f32; 4]; 1] = [[0.0; 4]];
        let positions = GpuArray::from_slice(ctx, "render positions", cloud.positions)?;
        let normals =
            GpuArray::from_slice(ctx, "render normals", cloud.normals.unwrap_or(&DUMMY4))?;
        let colors = GpuArray::from_slice(ctx, "render colors", cloud.colors.unwrap_or(&DUMMY4))?;
        let weights = GpuArray::from_slice(ctx, "render weights", cloud.weights.unwrap_or(&[0.0]))?;
        let mut index_map = GpuArray::<u64>::new(ctx, "render index map", n)?;
        index_map.set_len(n);
        let mut out = GpuArray::<u32>::new(ctx, "render pixels", n)?;
        out.set_len(n);
        let params_buf = ParamBuffer::new(ctx, "RenderParams", params);
        let max_groups = ctx.limits().max_compute_workgroups_per_dimension;
        let splat_groups = self
            .splat
            .first()
            .workgroups_for(params.surfel_count as usize)
            .min(max_groups);
        let resolve_groups = self.resolve.workgroups_for(n).min(max_groups);
        ctx.scoped("render", || {
            let splat_bg = self.splat.first().bind_group(
                ctx,
                &[
                    ("params", params_buf.binding()),
                    ("positions", positions.binding()),
                    ("normals", normals.binding()),
                    ("index_map", index_map.binding()),
                ],
            );
            let resolve_bg = self.resolve.bind_group(
                ctx,
                &[
                    ("params", params_buf.binding()),
                    ("index_map", index_map.binding()),
                    ("normals", normals.binding()),
                    ("colors", colors.binding()),
                    ("weights", weights.binding()),
                    ("out_rgba", out.binding()),
                ],
            );
            let mut enc = ctx.encoder("render");
            index_map.clear(&mut enc);
            // One pass per key pass: the portable kernel's second reads its first's map.
            for splat in &self.splat.passes {
                let mut pass = enc.begin_compute_pass(&Default::default());
                splat.dispatch(ctx, &mut pass, &splat_bg, splat_groups)?;
            }
            {
                // A second pass: every splat must land before any pixel is resolved.
                let mut pass = enc.begin_compute_pass(&Default::default());
                self.resolve
                    .dispatch(ctx, &mut pass, &resolve_bg, resolve_groups)?;
            }
            ctx.submit(enc);
            ctx.wait_idle()
        })?;
        Ok((index_map.read_back(ctx)?, out.read_back(ctx)?))
    }

    /// Renders `cloud` from `camera` on the GPU: the same picture as [`super::render_cpu`]
    /// (up to rounding at splat borders).
    pub fn render(
        &self,
        ctx: &GpuContext,
        cloud: &Cloud,
        camera: &RenderCamera,
        view: View,
        settings: &RenderSettings,
    ) -> Result<RgbImage> {
        let params = render_params(cloud, camera, view, settings)?;
        let (_, rgba) = self.render_raw(ctx, &params, cloud)?;
        Ok(rgba_to_image(
            params.camera.width,
            params.camera.height,
            &rgba,
        ))
    }
}
