//! The GPU backend's steps ([`Backend`] for [`GpuBackend`]): each step writes its
//! parameters, then records one compute pass per kernel of its plan
//! ([`wgslam_core::plan`]; once per map chunk for the kernels that walk the map) in one
//! command buffer, and reads back at most the ICP system or the surfel counter.
//! `preprocess` and `predict` read nothing back: their commands are deferred and go with
//! the first ICP iteration's submission (see `GpuContext::defer`); every other step first
//! submits what is deferred. `fuse` submits and does not wait: the count of surfels it
//! added is mapped when a later wait finds the fusion done (`GpuBackend::settle_count`),
//! and the fern codes were recorded by `preprocess` and read after the ICP waits covered
//! them. So a tracked frame waits once per ICP iteration and once for `count_candidates`
//! (and for `compact` on its frames). `fuse` also uploads the next frame's raw images
//! when the pipeline hands them over, after its submission, so the copy overlaps the
//! fusion rather than following it (`preprocess_staged` then skips the upload).

use super::backend::GpuBackend;
use super::context::GpuContext;
use super::recording::{record_call, submit_profiled};
use super::step_grid::{check_pyramid, StepGrid};
use crate::layout::scan_params;
use crate::layout::{
    CompactParams, DeformNode, Fern, FernParams, FuseParams, IcpParams, Keypoint, KeypointParams,
    PreprocessParams, ProjectParams, ICP_SYSTEM_LEN,
};
use crate::{Error, Result};
use wgslam_core::backend::{
    Backend, Described, NextFrame, Prediction, PreprocessSteps, PyramidLevel, RgbdSystems,
    ToDescribe,
};
use wgslam_core::fused_view::FusedView;
use wgslam_core::plan::{self, Buffer, Call, FuseCall, IntensityCall, PredictCall, SystemCall};
use wgslam_core::registry::System;

impl Backend for GpuBackend {
    fn name(&self) -> &'static str {
        "gpu"
    }

    fn preprocess(&mut self, steps: &PreprocessSteps, depth: &[u16], rgba: &[u32]) -> Result<()> {
        check_frame_size(&steps.params, depth, rgba)?;
        self.preprocess_images(steps, Some((depth, rgba)))
    }

    fn preprocess_staged(&mut self, steps: &PreprocessSteps, frame_id: u32) -> Result<bool> {
        let staged = self.staged_frame.take();
        // Frame buffers that fit stay as they are (`ensure_frame`), images included.
        let kept = (self.frame.as_ref()).is_some_and(|f| f.fits(&steps.params, &steps.pyramid));
        if staged != Some(frame_id) || !kept {
            return Ok(false);
        }
        self.preprocess_images(steps, None)?;
        Ok(true)
    }

    fn predict(&mut self, params: &ProjectParams, pyramid: &[PyramidLevel]) -> Result<()> {
        if self.ctx.has_deferred("predict") {
            // Its uniforms are about to be written again (see `GpuContext::defer`).
            self.ctx.flush();
        }
        let mut params = *params;
        let project = !self.fused_view.is_some_and(|v| v.is_view_of(&params));
        if project {
            // The index map is about to hold another view (a relocalisation attempt
            // predicts at a keyframe's pose): the fused one is gone. Projecting the map
            // needs its size, which may wait for the last fusion (`settle_count`); at the
            // fused view `predict_model` reads the fusion's index map and no count.
            self.fused_view = None;
            self.settle_count()?;
        }
        params.surfel_count = self.count as u32;
        let f = self.frame();
        let made: Vec<(u32, u32)> = f.levels.iter().map(|l| (l.width, l.height)).collect();
        let asked: Vec<(u32, u32)> = pyramid
            .iter()
            .map(|l| (l.down.camera.width, l.down.camera.height))
            .collect();
        if made != asked {
            return Err(Error::Argument(format!(
                "predict() asked for pyramid levels {asked:?} but preprocess() made {made:?}"
            )));
        }
        let plan = plan::predict(project, pyramid.len());
        let levels = f.levels.iter().map(|l| [l.width, l.height]).collect();
        let mut grid = StepGrid::new(&self.ctx, [f.width, f.height], levels);
        if project {
            grid.chunks = self.chunk_blocks();
            grid.bounds = self.stale_bounds_passes();
        }
        let (ctx, k, bg, profiler, f, u) = encoding_parts!(self);
        ctx.scoped("predict", || {
            u.project.write(ctx, &params);
            let mut enc = ctx.encoder("predict");
            for call in plan {
                let passes = match call {
                    PredictCall::ClearIndexMap => {
                        f.index_map.clear(&mut enc);
                        Vec::new()
                    }
                    // The stale boxes' `block_bounds`, `project_model`, `predict_model`,
                    // and per coarser level the model's maps: bound and dispatched by
                    // their registry rows.
                    generic => grid.generic(k, bg, generic),
                };
                record_call(ctx, profiler, &mut enc, call.name(), &passes)?;
            }
            defer_profiled(ctx, profiler, "predict", enc)
        })
    }

    fn icp_system(&mut self, level: usize, params: &IcpParams) -> Result<[f64; ICP_SYSTEM_LEN]> {
        self.check_system_level(level, "ICP")?;
        let [geometric] = self.run_systems(Vec::new(), plan::icp_system(level), params)?;
        Ok(geometric)
    }

    fn rgbd_system(&mut self, level: usize, params: &IcpParams) -> Result<RgbdSystems> {
        self.check_system_level(level, "RGB-D ICP")?;
        let made = self.systems.intensity_made;
        self.systems.intensity_made = made.max(level + 1);
        let intensity = plan::intensity_levels(made, level);
        self.run_systems(intensity, plan::rgbd_system(level), params)
    }

    fn encode_ferns(&mut self, params: &FernParams, ferns: &[Fern]) -> Result<Vec<u32>> {
        self.ctx.flush();
        self.encode_ferns_on_gpu(params, ferns)
    }

    fn count_candidates(&mut self, params: &IcpParams) -> Result<u64> {
        self.ctx.flush();
        self.count_candidates_on_gpu(params)
    }

    fn detect_keypoints(&mut self, params: &KeypointParams) -> Result<(Vec<Keypoint>, u32)> {
        self.ctx.flush();
        self.detect_keypoints_on_gpu(params)
    }

    fn describe_keypoints(&mut self, what: ToDescribe) -> Result<Described> {
        self.ctx.flush();
        self.describe_keypoints_on_gpu(what.params, what.keypoints, what.pattern)
    }

    fn fuse(&mut self, params: &FuseParams, next: Option<NextFrame<'_>>) -> Result<()> {
        self.ctx.flush();
        self.settle_count()?;
        let n = self.frame().pixels();
        self.fused_view = None;
        self.ensure_capacity(self.count + n)?;
        let mut params = *params;
        params.surfel_count = self.count as u32;
        params.capacity = self.capacity() as u32;
        let plan = plan::fuse(&params);
        let f = self.frame();
        let mut grid = StepGrid::new(&self.ctx, [f.width, f.height], Vec::new());
        grid.chunks = self.chunk_blocks();
        grid.flags = f.add_flags.len();
        if plan.contains(&FuseCall::BlockBounds) {
            grid.bounds = self.stale_bounds_passes();
        }
        let (ctx, k, bg, profiler, f, u) = encoding_parts!(self);
        let staged = ctx.scoped("fuse", || {
            u.fuse.write(ctx, &params);
            u.scan.write(ctx, &scan_params(f.add_flags.len()));
            let mut enc = ctx.encoder("fuse");
            for call in plan {
                let passes = match call {
                    FuseCall::Clear(Buffer::Assoc) => {
                        f.assoc.clear(&mut enc);
                        Vec::new()
                    }
                    FuseCall::Clear(Buffer::Merged) => {
                        f.merged.clear(&mut enc);
                        Vec::new()
                    }
                    FuseCall::Clear(Buffer::IndexMap) => {
                        f.index_map.clear(&mut enc);
                        Vec::new()
                    }
                    // The stale boxes' `block_bounds`, `fuse_select` (surfels pick
                    // pixels, then each picked surfel merges from its pixel:
                    // `fuse_merge_chosen`), `fuse_prune`, `fuse_merge`, `fuse_flags`, the
                    // scan over its flags, `fuse_add` (its passes as the call says): bound
                    // and dispatched by their registry rows.
                    generic => grid.generic(k, bg, generic),
                };
                record_call(ctx, profiler, &mut enc, call.name(), &passes)?;
            }
            self.counter_readback.copy_from(&mut enc, &self.counter, 1);
            submit_profiled(ctx, profiler, enc)?;
            // No wait: the count of surfels added is mapped when a later wait (the next
            // frame's first ICP iteration's) finds the fusion done (`settle_count`).
            self.counter_readback.request(ctx);
            // While the fusion runs: the next frame's images.
            stage_next(ctx, f, next)
        })?;
        self.staged_frame = staged;
        // The blocks from the one that held the old last surfel on have new surfels.
        self.bounds_dirty_from = self.bounds_dirty_from.min(self.count);
        self.fused_view = FusedView::of_fuse(&params);
        Ok(())
    }

    fn compact(&mut self, params: &CompactParams) -> Result<usize> {
        self.ctx.flush();
        let n = self.settle_count()?;
        if n == 0 {
            return Ok(0);
        }
        self.ensure_compaction()?;
        let mut params = *params;
        params.surfel_count = n as u32;
        // The map alone: no frame's pixels.
        let mut grid = StepGrid::new(&self.ctx, [0, 0], Vec::new());
        grid.live = self.chunk_live();
        grid.flags = n;
        self.bind_groups();
        let bg = self.bind_groups.as_ref().expect("just built");
        let (ctx, k, u) = (&self.ctx, &self.kernels, &self.uniforms);
        let profiler = &mut self.profiler;
        let kept = ctx.scoped("compact", || {
            u.compact.write(ctx, &params);
            u.scan.write(ctx, &scan_params(n));
            let mut enc = ctx.encoder("compact");
            // The keep flags, their scan and the copy of the survivors into the spare map:
            // each bound and dispatched by its registry row.
            for call in plan::compact() {
                let passes = grid.generic(k, bg, call);
                record_call(ctx, profiler, &mut enc, call.name(), &passes)?;
            }
            self.counter_readback.copy_from(&mut enc, &self.counter, 1);
            submit_profiled(ctx, profiler, enc)?;
            self.counter_readback.read(ctx)
        })?[0] as usize;
        if kept > n {
            return Err(Error::Gpu(format!(
                "the scan kept {kept} of {n} surfels (an internal contract)"
            )));
        }
        let c = self.compaction.as_mut().expect("ensure_compaction made it");
        std::mem::swap(&mut self.map, &mut c.spare);
        std::mem::swap(&mut self.bind_groups, &mut self.spare_bind_groups);
        self.count = kept;
        // Every surfel may have moved to another block, and to another index.
        self.bounds_dirty_from = 0;
        self.fused_view = None;
        Ok(kept)
    }

    fn deform(&mut self, nodes: &[DeformNode]) -> Result<()> {
        self.ctx.flush();
        self.settle_count()?;
        self.deform_on_gpu(nodes)
    }

    fn frame_level(&mut self, level: usize) -> Result<Prediction> {
        self.ctx.flush();
        self.frame_level_on_gpu(level)
    }

    fn set_prediction(&mut self, level: usize, (vertex, normal): &Prediction) -> Result<()> {
        self.ctx.flush();
        self.set_prediction_on_gpu(level, vertex, normal)
    }

    fn surfel_count(&mut self) -> Result<usize> {
        self.settle_count()
    }

    fn finish(&mut self) -> Result<()> {
        self.ctx.wait_idle()
    }
}

impl GpuBackend {
    /// [`Backend::preprocess`] with `images` uploaded first, or, for `None`, on the raw
    /// images a `fuse` staged (`stage_next`).
    fn preprocess_images(
        &mut self,
        steps: &PreprocessSteps,
        images: Option<(&[u16], &[u32])>,
    ) -> Result<()> {
        let (w, h) = (steps.params.camera.width, steps.params.camera.height);
        check_pyramid(w, h, &steps.pyramid)?;
        // The uploads below would land before a deferred step (see `GpuContext::defer`).
        self.ctx.flush();
        // Whatever was staged is overwritten now, or read by this very step.
        self.staged_frame = None;
        self.ensure_frame(&steps.params, &steps.pyramid)?;
        // A new frame: its intensity pyramid is made by the first `rgbd_system`.
        self.systems.intensity_made = 0;
        let ctx = &self.ctx;
        let u = &self.uniforms;
        ctx.scoped("preprocess", || {
            let f = self.frame.as_mut().expect("ensure_frame made it");
            if let Some((depth, rgba)) = images {
                f.raw_depth.upload(ctx, depth)?;
                f.raw_rgba.upload(ctx, rgba)?;
            }
            f.filtered = steps.bilateral.is_some();
            u.preprocess.write(ctx, &steps.params);
            if let Some(b) = &steps.bilateral {
                u.bilateral.write(ctx, b);
            }
            u.normal.write(ctx, &steps.normal);
            for (level, p) in f.levels.iter().zip(&steps.pyramid) {
                level.u_pyramid.write(ctx, &p.down);
                level.u_normal.write(ctx, &p.normal);
            }
            Ok(())
        })?;
        let levels = steps.pyramid.iter().map(|p| size(&p.down.camera)).collect();
        let grid = StepGrid::new(&self.ctx, [w, h], levels);
        let plan = plan::preprocess(steps.bilateral.as_ref(), steps.pyramid.len());
        let (ctx, k, bg, profiler, _, _) = encoding_parts!(self);
        ctx.scoped("preprocess", || {
            let mut enc = ctx.encoder("preprocess");
            for call in plan {
                // Every kernel of `preprocess` is bound and dispatched by its registry row.
                let passes = grid.generic(k, bg, call);
                record_call(ctx, profiler, &mut enc, call.name(), &passes)?;
            }
            // The frame's fern codes, read after its fusion (`encode_ferns`) once the ICP
            // read-backs' waits have covered them.
            let ferns = &mut self.ferns;
            super::ferns::record_ahead(ctx, (k, bg), ferns, [w, h], profiler, &mut enc)?;
            defer_profiled(ctx, profiler, "preprocess", enc)
        })
    }

    /// [`Error::Argument`] unless pyramid level `level` was preprocessed (`what`: the step,
    /// for the message).
    fn check_system_level(&self, level: usize, what: &str) -> Result<()> {
        let levels = 1 + self.frame().levels.len();
        if level >= levels {
            return Err(Error::Argument(format!(
                "{what} at pyramid level {level}, but preprocess() made {levels} level(s)"
            )));
        }
        Ok(())
    }

    /// One ICP iteration's submission: the intensity pyramid's levels `intensity` (those
    /// the systems' photometric term reads and the frame has not made yet), then the
    /// systems' `plan` at `params`; reads back the sum of each system the plan sums, in
    /// its order (`N` of them).
    fn run_systems<const N: usize>(
        &mut self,
        intensity: Vec<IntensityCall>,
        plan: Vec<SystemCall>,
        params: &IcpParams,
    ) -> Result<[[f64; ICP_SYSTEM_LEN]; N]> {
        let summed: Vec<System> = plan
            .iter()
            .filter_map(|call| match call {
                SystemCall::SumPartials(system) => Some(*system),
                SystemCall::IcpReduce { .. } | SystemCall::PhotoReduce { .. } => None,
            })
            .collect();
        assert_eq!(summed.len(), N, "a systems plan sums {N} system(s)");
        let f = self.frame();
        let levels = f.levels.iter().map(|l| [l.width, l.height]).collect();
        let grid = StepGrid::new(&self.ctx, [f.width, f.height], levels);
        let (ctx, k, bg, profiler, _, u) = encoding_parts!(self);
        let systems = &mut self.systems;
        let sums = ctx.scoped("icp_system", || {
            u.icp.write(ctx, params);
            let mut enc = ctx.encoder("icp_system");
            // The intensity pyramid's levels, the reductions and their sums: each bound and
            // dispatched by its registry row, in this iteration's submission.
            for call in intensity {
                let passes = grid.generic(k, bg, call);
                record_call(ctx, profiler, &mut enc, call.name(), &passes)?;
            }
            for call in plan {
                let passes = grid.generic(k, bg, call);
                record_call(ctx, profiler, &mut enc, call.name(), &passes)?;
            }
            let srcs: Vec<_> = summed
                .iter()
                .map(|&s| &systems.buffers[s as usize].sum)
                .collect();
            systems
                .readback
                .copy_from_each(&mut enc, &srcs, ICP_SYSTEM_LEN);
            submit_profiled(ctx, profiler, enc)?;
            systems.readback.read(ctx)
        })?;
        let mut out = [[0.0f64; ICP_SYSTEM_LEN]; N];
        for (s, &x) in out.iter_mut().flatten().zip(&sums) {
            *s = x as f64;
        }
        Ok(out)
    }
}

/// Submits `enc` when profiling (the timestamps are read per submission), else defers it to
/// the next submission (see `GpuContext::defer`): a step whose results the host does not
/// wait for costs no round trip of its own.
fn defer_profiled(
    ctx: &GpuContext,
    profiler: &mut Option<super::recording::Profiler>,
    step: &'static str,
    enc: wgpu::CommandEncoder,
) -> Result<()> {
    match profiler {
        Some(_) => submit_profiled(ctx, profiler, enc),
        None => {
            ctx.defer(step, enc);
            Ok(())
        }
    }
}

/// Checks that the raw frame has `raw_width x raw_height` depth and colour values and that
/// the map, `stride` raw pixels per map pixel, fits in it.
/// Uploads `next`'s raw images into the frame's raw textures for its
/// [`Backend::preprocess_staged`], where they fit (else the frame's `preprocess` uploads or
/// reports them); returns the frame staged. Only `depth_to_vertex` reads these textures, and
/// this frame's has run (`fuse` submits after every deferred step).
fn stage_next(
    ctx: &GpuContext,
    f: &crate::resources::FrameBuffers,
    next: Option<NextFrame<'_>>,
) -> Result<Option<u32>> {
    let Some(next) = next else {
        return Ok(None);
    };
    let texels = f.raw_depth.texels();
    if next.depth.len() != texels || next.rgba.len() != texels {
        return Ok(None);
    }
    f.raw_depth.upload(ctx, next.depth)?;
    f.raw_rgba.upload(ctx, next.rgba)?;
    Ok(Some(next.frame_id))
}

fn check_frame_size(params: &PreprocessParams, raw_depth: &[u16], raw_rgba: &[u32]) -> Result<()> {
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
        || params.camera.width * params.stride > params.raw_width
        || params.camera.height * params.stride > params.raw_height
    {
        return Err(Error::Argument(format!(
            "a {}x{} map with stride {} does not fit a {}x{} frame",
            params.camera.width,
            params.camera.height,
            params.stride,
            params.raw_width,
            params.raw_height
        )));
    }
    Ok(())
}

/// A camera's image size, `[width, height]` in pixels.
fn size(camera: &crate::layout::Camera) -> [u32; 2] {
    [camera.width, camera.height]
}
