//! The GPU backend's steps of one kernel each (`wgslam_core::plan::Single`): relocalisation's
//! `fern_encode`, `keypoint_detect` and `keypoint_describe`, tracking health's candidate
//! count and loop closure's `deform_surfels` (each bound and dispatched by its registry
//! row); and the two copies a loop's verification needs (one pyramid level of the
//! frame's maps down, a keyframe's snapshot up into a level's prediction). Each step writes
//! its parameters, records its plan's one call in a command buffer of its own
//! ([`record_call`], as the other steps do) and reads its results back. Their buffers live
//! beside: `super::{ferns, keypoints, candidates}`, made at a step's first call (the
//! deformation's node table is the backend's).

use super::backend::GpuBackend;
use super::buffers::GpuArray;
use super::candidates::{CandidateBuffers, CANDIDATE_WORKGROUPS_MAX};
use super::context::GpuContext;
use super::ferns::FernBuffers;
use super::images::GpuImage;
use super::keypoints;
use super::recording::{record_call, submit_profiled, Pass, Profiler};
use super::step_grid::StepGrid;
use crate::layout::{
    DeformNode, DeformParams, Fern, FernParams, IcpParams, Keypoint, KeypointParams,
    DESCRIPTOR_WORDS,
};
use crate::Result;
use wgslam_core::backend::{Described, Prediction};
use wgslam_core::plan::{self, Call, Single};

/// Records `call`'s `passes` in a command buffer of their own, after `before` and before
/// `after` (a clear, the copies to read-backs), and submits it.
fn submit_single(
    ctx: &GpuContext,
    profiler: &mut Option<Profiler>,
    call: Single,
    passes: &[Pass],
    before: impl FnOnce(&mut wgpu::CommandEncoder),
    after: impl FnOnce(&mut wgpu::CommandEncoder),
) -> Result<()> {
    let mut enc = ctx.encoder(call.name());
    before(&mut enc);
    record_call(ctx, profiler, &mut enc, call.name(), passes)?;
    after(&mut enc);
    submit_profiled(ctx, profiler, enc)
}

impl GpuBackend {
    /// `fern_encode` over the frame's level-0 maps, bound and dispatched by its registry
    /// row; see `Backend::encode_ferns`.
    pub(super) fn encode_ferns_on_gpu(
        &mut self,
        params: &FernParams,
        fern_table: &[Fern],
    ) -> Result<Vec<u32>> {
        let n = params.fern_count as usize;
        assert!(
            fern_table.len() >= n,
            "{} ferns for fern_count {n}",
            fern_table.len()
        );
        if n == 0 {
            return Ok(vec![]);
        }
        let call = plan::encode_ferns();
        if self.ferns.as_ref().is_none_or(|b| b.ferns.capacity() < n) {
            self.ferns = Some(FernBuffers::new(&self.ctx, n)?);
            self.drop_bind_groups();
        }
        let b = self.ferns.as_mut().expect("just made");
        if b.ahead.take() == Some(*params) && b.uploaded[..] == fern_table[..n] {
            // Recorded by this frame's preprocess, and in the usual case done and covered
            // by an ICP wait already: only the read remains.
            let ctx = &self.ctx;
            return ctx.scoped(call.name(), || b.readback.take(ctx));
        }
        let grid = self.frame_grid(n);
        let (ctx, k, bg, profiler, _, u) = encoding_parts!(self);
        let b = self.ferns.as_mut().expect("just made");
        b.last = Some(*params);
        ctx.scoped(call.name(), || {
            u.ferns.write(ctx, params);
            if b.uploaded[..] != fern_table[..n] {
                b.ferns.upload(ctx, &fern_table[..n])?;
                b.uploaded = fern_table[..n].to_vec();
            }
            let passes = grid.generic(k, bg, call);
            let copy = |enc: &mut _| b.readback.copy_from(enc, &b.codes, n);
            submit_single(ctx, profiler, call, &passes, |_| {}, copy)?;
            b.readback.read(ctx)
        })
    }

    /// The ICP candidates at level 0, counted per workgroup (at most
    /// [`CANDIDATE_WORKGROUPS_MAX`]) by the kernel its registry row binds and dispatches,
    /// and summed here; see `Backend::count_candidates`.
    pub(super) fn count_candidates_on_gpu(&mut self, params: &IcpParams) -> Result<u64> {
        let call = plan::count_candidates();
        let wg = self.reduction_workgroups.min(CANDIDATE_WORKGROUPS_MAX);
        if self.candidates.is_none() {
            self.candidates = Some(CandidateBuffers::new(&self.ctx, wg)?);
            self.drop_bind_groups();
        }
        // One workgroup per count.
        let grid = self.frame_grid(wg as usize);
        let (ctx, k, bg, profiler, _, u) = encoding_parts!(self);
        let b = self.candidates.as_mut().expect("just made");
        ctx.scoped(call.name(), || {
            u.icp.write(ctx, params);
            let copy = |enc: &mut _| b.readback.copy_from(enc, &b.counts, wg as usize);
            let passes = grid.generic(k, bg, call);
            submit_single(ctx, profiler, call, &passes, |_| {}, copy)?;
            Ok(b.readback.read(ctx)?.iter().map(|&c| c as u64).sum())
        })
    }

    /// `keypoint_detect` over the frame's level-0 maps, bound and dispatched by its registry
    /// row; see `Backend::detect_keypoints`.
    pub(super) fn detect_keypoints_on_gpu(
        &mut self,
        params: &KeypointParams,
    ) -> Result<(Vec<Keypoint>, u32)> {
        let call = plan::detect_keypoints();
        let capacity = params.capacity as usize;
        if keypoints::ensure(&mut self.keypoints, &self.ctx, capacity, 1)? {
            self.drop_bind_groups();
        }
        // Over the frame's pixels: no items.
        let grid = self.frame_grid(0);
        let (ctx, k, bg, profiler, _, u) = encoding_parts!(self);
        let b = self.keypoints.as_mut().expect("ensure made them");
        ctx.scoped(call.name(), || {
            u.keypoints.write(ctx, params);
            let clear = |enc: &mut _| b.counter.clear(enc);
            let copy = |enc: &mut _| {
                b.counter_back.copy_from(enc, &b.counter, 1);
                b.keypoints_back.copy_from(enc, &b.keypoints, capacity);
            };
            let passes = grid.generic(k, bg, call);
            submit_single(ctx, profiler, call, &passes, clear, copy)?;
            let found = b.counter_back.read(ctx)?[0];
            let mut kps = b.keypoints_back.read(ctx)?;
            kps.truncate(found.min(params.capacity) as usize);
            Ok((kps, found))
        })
    }

    /// `keypoint_describe`, one thread per keypoint, bound and dispatched by its registry
    /// row; see `Backend::describe_keypoints`.
    pub(super) fn describe_keypoints_on_gpu(
        &mut self,
        params: &KeypointParams,
        found: &[Keypoint],
        pattern: &[[i32; 4]],
    ) -> Result<Described> {
        let (n, tests) = (params.count as usize, params.tests as usize);
        assert!(found.len() >= n && pattern.len() >= tests);
        if n == 0 {
            return Ok((vec![], vec![]));
        }
        let call = plan::describe_keypoints();
        if keypoints::ensure(&mut self.keypoints, &self.ctx, n, tests)? {
            self.drop_bind_groups();
        }
        let grid = self.frame_grid(n);
        let (ctx, k, bg, profiler, _, u) = encoding_parts!(self);
        let b = self.keypoints.as_mut().expect("ensure made them");
        ctx.scoped(call.name(), || {
            u.keypoints.write(ctx, params);
            b.keypoints.upload(ctx, &found[..n])?;
            b.pattern.upload(ctx, &pattern[..tests])?;
            let copy = |enc: &mut _| {
                b.descriptors_back
                    .copy_from(enc, &b.descriptors, n * DESCRIPTOR_WORDS);
                b.points_back.copy_from(enc, &b.points, n);
            };
            let passes = grid.generic(k, bg, call);
            submit_single(ctx, profiler, call, &passes, |_| {}, copy)?;
            let words = b.descriptors_back.read(ctx)?;
            let points = b.points_back.read(ctx)?;
            let descriptors = words
                .chunks_exact(DESCRIPTOR_WORDS)
                .map(|c| c.try_into().expect("chunks of DESCRIPTOR_WORDS"))
                .collect();
            Ok((descriptors, points))
        })
    }

    /// The grid of a one-kernel step over the frame's level-0 pixels and `items` items
    /// (ferns, keypoints, counts).
    fn frame_grid(&self, items: usize) -> StepGrid {
        let f = self.frame();
        let mut grid = StepGrid::new(&self.ctx, [f.width, f.height], Vec::new());
        grid.items = items;
        grid
    }

    /// `deform_surfels` over the live surfels of every chunk, bound and dispatched by its
    /// registry row (the map alone: it runs on an uploaded map before any frame too); see
    /// `Backend::deform`.
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
        let call = plan::deform();
        if self.deform_nodes.capacity() < nodes.len() {
            let grown = nodes.len().next_power_of_two();
            self.deform_nodes = GpuArray::new(&self.ctx, "deformation nodes", grown)?;
            // The bind groups refer to the table.
            self.drop_bind_groups();
        }
        // The map alone: no frame's pixels.
        let mut grid = StepGrid::new(&self.ctx, [0, 0], Vec::new());
        grid.live = self.chunk_live();
        self.bind_groups();
        let (ctx, k, u) = (&self.ctx, &self.kernels, &self.uniforms);
        let bg = self.bind_groups.as_ref().expect("just built");
        let table = &mut self.deform_nodes;
        let profiler = &mut self.profiler;
        ctx.scoped(call.name(), || {
            u.deform.write(ctx, &params);
            table.upload(ctx, nodes)?;
            let passes = grid.generic(k, bg, call);
            submit_single(ctx, profiler, call, &passes, |_| {}, |_| {})
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
