//! The GPU pass of the renderer: the render plan (`plan::render`: a cleared index map, the
//! splats' keys, the pixels) in one submission, each kernel bound and dispatched by its
//! registry row (`RowKernels`) over the picture's pool of named buffers, as the CPU
//! path runs the same plan through the twins (`super::render_cpu_raw`).
//!
//! Thin wrapper: the kernels created once, buffers created per picture (a render is a
//! one-off, not a per-frame step), one read-back of the packed pixels. The splatting
//! kernel is a key kernel: the 64-bit kernel, or on a device without 64-bit atomics its
//! portable variant in two passes, with the same keys.

use image::RgbImage;

use super::{render_params, rgba_to_image, Cloud, RenderCamera, RenderSettings, View};
use crate::gpu::{GpuArray, GpuContext, ParamBuffer, RowKernels};
use crate::layout::render::RenderParams;
use crate::Result;
use wgslam_core::plan::{self, RenderCall};

/// The render kernels, created once per context from their registry rows.
#[derive(Debug)]
pub struct GpuRenderer {
    rows: RowKernels,
}

impl GpuRenderer {
    /// Creates the pipelines (three on a device without 64-bit atomics).
    pub fn new(ctx: &GpuContext) -> Result<GpuRenderer> {
        Ok(GpuRenderer {
            rows: RowKernels::of_plan(ctx, &plan::render())?,
        })
    }

    /// Runs the render plan for `params` and reads back the index map and the packed
    /// pixels (`width * height` each, row-major). Attributes the cloud lacks are bound as a
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
        ctx.scoped("render", || {
            let pool = [
                ("render", params_buf.binding()),
                ("positions", positions.binding()),
                ("normals", normals.binding()),
                ("colors", colors.binding()),
                ("weights", weights.binding()),
                ("index_map", index_map.binding()),
                ("out_rgba", out.binding()),
            ];
            let mut enc = ctx.encoder("render");
            // One pass per call (a key kernel's per key pass): every splat lands before
            // any pixel is resolved.
            for call in plan::render() {
                let points = match call {
                    RenderCall::ClearIndexMap => {
                        index_map.clear(&mut enc);
                        continue;
                    }
                    RenderCall::RenderSplat => params.surfel_count as usize,
                    RenderCall::RenderResolve => n,
                };
                self.rows.record(ctx, &mut enc, call, &pool, points)?;
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
