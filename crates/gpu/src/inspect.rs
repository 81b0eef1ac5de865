//! The GPU backend's copies in and out ([`Inspect`], for outputs, `compare` and tests) and
//! the downloads only the parity tests use (index map, compaction flags, block boxes,
//! association keys). The pipeline's steps never call these.

use super::backend::GpuBackend;
use super::context::GpuContext;
use super::images::GpuImage;
use crate::layout::map::SurfelMap;
use crate::layout::BLOCK_SURFELS;
use crate::Result;
use wgslam_core::backend::{
    BackendCounters, FrameLevel, FrameMaps, FusionBuffers, Inspect, Prediction,
};

/// A per-pixel `[f32; 4]` map read back row-major.
fn read_map(ctx: &GpuContext, image: &GpuImage) -> Result<Vec<[f32; 4]>> {
    image.read_back(ctx)
}

impl Inspect for GpuBackend {
    fn download_map(&mut self) -> Result<SurfelMap> {
        self.settle_count()?;
        let (ctx, m) = (&self.ctx, &self.map);
        ctx.scoped("download map", || {
            let map = m.download(ctx, self.count)?;
            map.assert_consistent();
            Ok(map)
        })
    }

    /// Writes `map` into the live map chunks (growing them first if needed) and sets
    /// the count; the spare map set is untouched (compaction overwrites it).
    fn upload_map(&mut self, map: &SurfelMap) -> Result<()> {
        map.assert_consistent();
        // The writes below would land before a deferred step (see `GpuContext::defer`).
        self.ctx.flush();
        // A fusion's pending count is read (and replaced below) before the map changes.
        self.settle_count()?;
        let n = map.len();
        self.ensure_capacity(n)?;
        let (ctx, m) = (&self.ctx, &mut self.map);
        ctx.scoped("upload map", || m.upload(ctx, map))?;
        self.count = n;
        self.bounds_dirty_from = 0;
        self.fused_view = None;
        Ok(())
    }

    fn download_frame(&mut self) -> Result<FrameMaps> {
        // Before the first frame there is nothing to download (as on the CPU).
        let Some(f) = self.frame.as_ref() else {
            return Ok(FrameMaps::default());
        };
        let ctx = &self.ctx;
        ctx.scoped("download frame", || {
            Ok(FrameMaps {
                vertex: read_map(ctx, &f.vertex)?,
                filtered_vertex: if f.filtered {
                    read_map(ctx, &f.filtered_vertex)?
                } else {
                    Vec::new()
                },
                normal_depth: read_map(ctx, &f.normal_depth)?,
                color: read_map(ctx, &f.color)?,
                pyramid: f
                    .levels
                    .iter()
                    .map(|l| {
                        Ok(FrameLevel {
                            vertex: read_map(ctx, &l.vertex)?,
                            normal_depth: read_map(ctx, &l.normal_depth)?,
                        })
                    })
                    .collect::<Result<_>>()?,
            })
        })
    }

    fn download_prediction(&mut self, level: usize) -> Result<Prediction> {
        let Some(f) = self.frame.as_ref() else {
            return Ok(Prediction::default());
        };
        let (vertex, normal) = match level {
            0 => (&f.pred_vertex, &f.pred_normal),
            l => match f.levels.get(l - 1) {
                Some(level) => (&level.pred_vertex, &level.pred_normal),
                None => return Ok(Prediction::default()),
            },
        };
        let ctx = &self.ctx;
        ctx.scoped("download prediction", || {
            Ok((read_map(ctx, vertex)?, read_map(ctx, normal)?))
        })
    }

    fn download_fusion(&mut self) -> Result<FusionBuffers> {
        // Before the first frame there is nothing to download (as on the CPU).
        let (ctx, Some(f)) = (&self.ctx, self.frame.as_ref()) else {
            return Ok(FusionBuffers::default());
        };
        ctx.scoped("download fusion buffers", || {
            Ok(FusionBuffers {
                assoc: f.assoc.read_back_range(ctx, 0..f.pixels())?,
                merged: f.merged.read_back(ctx)?,
                flags: f.add_flags.read_back(ctx)?,
                offsets: f.add_offsets.read_back(ctx)?,
            })
        })
    }

    fn counters(&self) -> BackendCounters {
        let s = self.ctx.stats();
        BackendCounters {
            readback_bytes: s.readback_bytes,
            submissions: s.submissions,
            device_submissions: s.device_submissions,
            waits: s.waits,
            shared_waits: s.shared_waits,
        }
    }
}

impl GpuBackend {
    /// The raw index map of the last `predict` (u64 keys, see `cpu::project_model`), for
    /// parity tests.
    pub fn download_index_map(&mut self) -> Result<Vec<u64>> {
        let (ctx, f) = (&self.ctx, self.frame());
        ctx.scoped("download index map", || f.index_map.read_back(ctx))
    }

    /// `predict_model`'s predicted intensity of the last `predict` (0..1 per pixel, see
    /// `cpu::photo_reduce`), for parity tests.
    pub fn download_pred_intensity(&mut self) -> Result<Vec<f32>> {
        let (ctx, f) = (&self.ctx, self.frame());
        ctx.scoped("download predicted intensity", || {
            f.pred_intensity.read_back(ctx)
        })
    }

    /// The frame's intensity patches at every level, level 0 first (`intensity_pyramid`'s
    /// outputs, made by the frame's `rgbd_system` calls: a level never asked for holds an
    /// earlier frame's, or zeros), for parity tests.
    pub fn download_intensity_patches(&mut self) -> Result<Vec<Vec<[f32; 4]>>> {
        self.ctx.flush();
        let (ctx, f) = (&self.ctx, self.frame());
        ctx.scoped("download intensity patches", || {
            std::iter::once(&f.intensity)
                .chain(f.levels.iter().map(|l| &l.intensity))
                .map(|l| read_map(ctx, &l.patch))
                .collect()
        })
    }
}

impl GpuBackend {
    /// The first `n` keep flags and offsets of the last `compact` (`compact_flags`' and
    /// `prefix_sum`'s outputs), for parity tests; empty before the first `compact`.
    pub fn download_compaction(&mut self, n: usize) -> Result<(Vec<u32>, Vec<u32>)> {
        let Some(c) = self.compaction.as_ref() else {
            return Ok((Vec::new(), Vec::new()));
        };
        let ctx = &self.ctx;
        ctx.scoped("download compaction", || {
            Ok((
                c.flags.read_back_range(ctx, 0..n)?,
                c.offsets.read_back_range(ctx, 0..n)?,
            ))
        })
    }
}

impl GpuBackend {
    /// The culling blocks' boxes of the live map (entries `2b` min, `2b + 1` max,
    /// ordered-encoded), for tests; boxes of blocks fusion appended to since the last
    /// `predict` or `fuse` are stale until the next one.
    pub fn download_block_bounds(&mut self) -> Result<Vec<[u32; 4]>> {
        let (ctx, b) = (&self.ctx, &self.block_boxes);
        let n = 2 * self.count.div_ceil(BLOCK_SURFELS as usize);
        ctx.scoped("download block bounds", || b.read_back_range(ctx, 0..n))
    }
}

impl GpuBackend {
    /// The last `fuse`'s per-pixel association keys (for the parity test of
    /// `fuse_select`); empty before the first frame.
    pub fn download_assoc(&mut self) -> Result<Vec<u64>> {
        let (ctx, Some(f)) = (&self.ctx, self.frame.as_ref()) else {
            return Ok(Vec::new());
        };
        ctx.scoped("download assoc", || {
            f.assoc.read_back_range(ctx, 0..f.pixels())
        })
    }
}
