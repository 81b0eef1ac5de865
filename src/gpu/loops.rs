//! The GPU side of loop closure (`crate::slam::loops`): `deform_surfels` over every map
//! chunk (its kernel and node table made at the first closure, so a run without one pays
//! nothing), and the two copies a loop's verification needs: one pyramid level of the
//! frame's maps down (a keyframe's snapshot) and a snapshot up into a level's prediction
//! (ICP then registers the frame against the keyframe, not the map).

use super::backend::GpuBackend;
use super::buffers::{GpuArray, ParamBuffer};
use super::images::GpuImage;
use super::kernel::Kernel;
use super::recording::{record_passes, submit_profiled};
use crate::layout::{DeformNode, DeformParams};
use crate::slam::backend::Prediction;
use crate::Result;

/// `deform_surfels`' kernel, parameters and node table.
pub(super) struct DeformBuffers {
    kernel: Kernel,
    params: ParamBuffer<DeformParams>,
    nodes: GpuArray<DeformNode>,
}

impl GpuBackend {
    /// `deform_surfels` over the live surfels of every chunk; see `Backend::deform`.
    pub(super) fn deform_on_gpu(&mut self, nodes: &[DeformNode]) -> Result<()> {
        if nodes.is_empty() || self.count == 0 {
            return Ok(());
        }
        let params = DeformParams {
            surfel_count: self.count as u32,
            node_count: nodes.len() as u32,
            _pad0: 0,
            _pad1: 0,
        };
        let ctx = &self.ctx;
        if self
            .deform
            .as_ref()
            .is_none_or(|b| b.nodes.capacity() < nodes.len())
        {
            self.deform = Some(DeformBuffers {
                kernel: Kernel::new(ctx, "deform_surfels")?,
                params: ParamBuffer::new(ctx, "DeformParams", &params),
                nodes: GpuArray::new(ctx, "deformation nodes", nodes.len().next_power_of_two())?,
            });
        }
        let b = self.deform.as_mut().expect("just made");
        let count = self.count;
        let cap = self.ctx.grid_workgroups_cap();
        let map = &self.map;
        ctx.scoped("deform_surfels", || {
            b.params.write(ctx, &params);
            b.nodes.upload(ctx, nodes)?;
            // One bind group per chunk: made per closure (closures are rare).
            let groups: Vec<(wgpu::BindGroup, u32)> = map
                .chunks
                .iter()
                .filter(|ch| ch.live(count) > 0)
                .map(|ch| {
                    let group = b.kernel.bind_group(
                        ctx,
                        &[
                            ("params", b.params.binding()),
                            ("chunk", ch.info_buffer.binding()),
                            ("nodes", b.nodes.binding()),
                            ("position_weight", ch.position_weight.binding()),
                            ("normal_frame", ch.normal_frame.binding()),
                        ],
                    );
                    (group, b.kernel.workgroups_for(ch.live(count)).min(cap))
                })
                .collect();
            let passes: Vec<_> = groups
                .iter()
                .map(|(g, wg)| (&b.kernel, g, [*wg, 1]))
                .collect();
            let mut enc = ctx.encoder("deform_surfels");
            record_passes(ctx, &mut self.profiler, &mut enc, &passes)?;
            submit_profiled(ctx, &mut self.profiler, enc)?;
            Ok(())
        })?;
        // Every surfel may have left its block's box, and the fused view is of the old map.
        self.bounds_dirty_from = 0;
        self.fused_view = None;
        Ok(())
    }

    /// Pyramid `level`'s frame `vertex` and `normal_depth` and predicted vertex and normal
    /// maps (level 0: the full maps).
    fn level_images(&self, level: usize) -> [&GpuImage; 4] {
        let f = self.frame();
        match level {
            0 => [&f.vertex, &f.normal_depth, &f.pred_vertex, &f.pred_normal],
            l => {
                let lv = f.levels.get(l - 1).unwrap_or_else(|| {
                    panic!("level {l}: the pyramid has {} levels", 1 + f.levels.len())
                });
                [
                    &lv.vertex,
                    &lv.normal_depth,
                    &lv.pred_vertex,
                    &lv.pred_normal,
                ]
            }
        }
    }

    /// The frame's `vertex` and `normal_depth` maps at pyramid `level`; see
    /// `Backend::frame_level`.
    pub(super) fn frame_level_on_gpu(&mut self, level: usize) -> Result<Prediction> {
        let [vertex, normal_depth, _, _] = self.level_images(level);
        let ctx = &self.ctx;
        ctx.scoped("download frame level", || {
            Ok((vertex.read_back(ctx)?, normal_depth.read_back(ctx)?))
        })
    }

    /// Writes a prediction into pyramid `level`'s predicted maps; see
    /// `Backend::set_prediction`.
    pub(super) fn set_prediction_on_gpu(
        &mut self,
        level: usize,
        vertex: &[[f32; 4]],
        normal: &[[f32; 4]],
    ) -> Result<()> {
        let [_, _, pv, pn] = self.level_images(level);
        let ctx = &self.ctx;
        ctx.scoped("upload prediction", || {
            pv.upload(ctx, vertex)?;
            pn.upload(ctx, normal)
        })
    }
}
