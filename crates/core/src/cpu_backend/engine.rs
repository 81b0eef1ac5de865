//! The CPU backend's kernel engine: runs a plan call's kernel by its registry row
//! ([`KernelId::twin`](crate::registry::KernelId::twin)), its bindings taken from a
//! [`Pool`] of the backend's buffers by the names the WGSL declares them with, as the GPU
//! engine's bind groups take them (`wgslam_gpu`'s `bind_groups.rs`: `frame_pool`,
//! `level_pool`, `scan_groups`, `system_pool`). Rows of the `OverFrame`, `PerItem`,
//! `PerCount`, `PerLevel`, `Reduce`, `PerSystem`, `PerScanBlock` and `OneWorkgroup`
//! [`Shape`]s bind here; a step runs the kernels of the map's rows through arms of its own.
//!
//! Not here: the buffers' sizes (each step sizes what its kernels write before its plan
//! runs, as the GPU backend allocates its frame's buffers), and the order of the kernels
//! (`crate::plan`).

use super::CpuBackend;
use crate::cpu::binding::Pool;
use crate::plan::Call;
use crate::registry::{At, Scanned, Shape};

impl CpuBackend {
    /// Runs `call`'s kernel through its row: its twin over the bindings it names, from
    /// `step` (the step's own uniforms and buffers: the kernel's `params` is the uniform
    /// its row names) and the frame's pool (an `OverFrame`, `PerItem` or `PerCount` row),
    /// the pool of the pyramid level the call gives (a `PerLevel` or `Reduce` row), or the
    /// pool of the flags it scans (a scan's row). A `PerSystem` row binds the step's alone
    /// (a system's `partials` and `system`, which the step owns). Panics on a call whose
    /// kernel has no twin in the one call shape, or a row of another shape (internal
    /// contracts: such a call has an arm in its step).
    pub(super) fn dispatch(&mut self, call: impl Call, step: Pool<'_>) {
        let kernel = call.kernel();
        let row = kernel.and_then(|k| Some((k.twin()?, k.shape()?, k.uniform()?)));
        let Some((twin, shape, uniform)) = row else {
            panic!("`{}` has no twin in the one call shape", call.name())
        };
        let mut pool = match shape {
            Shape::OverFrame | Shape::PerItem | Shape::PerCount => self.frame_pool(step),
            Shape::PerLevel | Shape::Reduce => self.level_pool(step, call.at().choice()),
            Shape::PerSystem => step,
            Shape::PerScanBlock | Shape::OneWorkgroup => self.scan_pool(step, call.at().scanned),
            other => panic!("`{}`: the CPU engine binds no {other:?} row", call.name()),
        };
        (twin.run)(&mut pool.bind(twin.bindings, uniform));
    }

    /// `pool` with the frame's maps and per-pixel buffers, by the names the kernels
    /// declare them with (the GPU's `frame_pool`): `vertex_map` the unfiltered vertex map,
    /// as `depth_to_vertex` writes it and `bilateral_filter` reads it.
    fn frame_pool<'a>(&'a mut self, mut pool: Pool<'a>) -> Pool<'a> {
        let f = &mut self.frame;
        pool.write("vertex_map", &mut f.vertex);
        pool.write("filtered_vertex", &mut f.filtered_vertex);
        pool.write("normal_depth", &mut f.normal_depth);
        pool.write("color_map", &mut f.color);
        pool.write("index_map", &mut self.index_map);
        if let Some((pred_vertex, pred_normal)) = self.prediction.first_mut() {
            pool.write("pred_vertex", pred_vertex);
            pool.write("pred_normal", pred_normal);
        }
        pool.write("pred_intensity", &mut self.pred_intensity);
        pool.write("assoc", &mut self.assoc);
        pool.write("merged", &mut self.merged);
        // Fusion's new-surfel flags and their prefix sum (compaction binds its own).
        pool.write("flags", &mut self.add_flags);
        pool.write("offsets", &mut self.add_offsets);
        pool
    }

    /// `pool` with the flags a scan covers (the GPU's `scan_groups`): fusion's new-surfel
    /// flags or compaction's keep flags as `flags`, their prefix sum as `offsets`, and the
    /// scan's `block_sums` (the step gives the surfel `counter` and the `scan` uniform).
    fn scan_pool<'a>(&'a mut self, mut pool: Pool<'a>, scanned: Scanned) -> Pool<'a> {
        let (flags, offsets) = match scanned {
            Scanned::NewSurfels => (&mut self.add_flags, &mut self.add_offsets),
            Scanned::KeepFlags => (&mut self.flags, &mut self.offsets),
        };
        pool.write("flags", flags);
        pool.write("offsets", offsets);
        pool.write("block_sums", &mut self.block_sums);
        pool
    }

    /// `pool` with pyramid level `at.level`'s maps, named as at level 0, and its finer
    /// level's as `fine_*` (the GPU's `level_pool`): level 0's are the frame's, its
    /// `vertex_map` and `point_map` the vertex maps `at` chooses (see [`At`]), which level
    /// 1's `fine_vertex` is too; its intensity patches are `intensity_patch`, the finer
    /// level's `fine_map` (at level 0 the colour map), with the level's `intensity`
    /// uniform; at every level, the reductions' source, level 0's predicted vertex map
    /// (`level0_pred_vertex`) and intensity (`pred_intensity`). Maps a step has not made yet
    /// (the prediction before the first `predict`) are not in the pool.
    fn level_pool<'a>(&'a mut self, mut pool: Pool<'a>, at: At) -> Pool<'a> {
        let f = &mut self.frame;
        let level0 = [pool.lend(&mut f.vertex), pool.lend(&mut f.filtered_vertex)];
        let level0 = |filtered: bool| level0[filtered as usize];
        match at.level.checked_sub(1) {
            None => {
                pool.alias("vertex_map", level0(at.filtered));
                pool.alias("point_map", level0(at.filtered_points));
                pool.write("normal_depth", &mut f.normal_depth);
            }
            Some(l) if l < f.pyramid.len() => {
                let (finer, this) = f.pyramid.split_at_mut(l);
                let vertex = pool.write("vertex_map", &mut this[0].vertex);
                pool.alias("point_map", vertex);
                pool.write("normal_depth", &mut this[0].normal_depth);
                match finer.last_mut() {
                    Some(fine) => {
                        pool.write("fine_vertex", &mut fine.vertex);
                    }
                    None => pool.alias("fine_vertex", level0(at.filtered)),
                }
            }
            // A level the last `preprocess` did not make (a `predict` of more levels).
            Some(_) => {}
        }
        let pred: Vec<[usize; 2]> = (self.prediction.iter_mut())
            .map(|(vertex, normal)| [pool.lend(vertex), pool.lend(normal)])
            .collect();
        if let Some(&[vertex, normal]) = pred.get(at.level) {
            pool.alias("pred_vertex", vertex);
            pool.alias("pred_normal", normal);
        }
        if let Some(&[vertex, normal]) = at.level.checked_sub(1).and_then(|l| pred.get(l)) {
            pool.alias("fine_pred_vertex", vertex);
            pool.alias("fine_pred_normal", normal);
        }
        // The reductions' source at every level: level 0's prediction.
        if let Some(&[vertex, _]) = pred.first() {
            pool.alias("level0_pred_vertex", vertex);
        }
        pool.write("pred_intensity", &mut self.pred_intensity);
        let intensity = &mut self.intensity;
        if at.level < intensity.patches.len() {
            let (finer, this) = intensity.patches.split_at_mut(at.level);
            pool.write("intensity_patch", &mut this[0]);
            match finer.last_mut() {
                Some(fine) => pool.write("fine_map", fine),
                None => pool.write("fine_map", &mut f.color),
            };
            pool.uniform("intensity", &intensity.params[at.level]);
        }
        pool
    }
}
