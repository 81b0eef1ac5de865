//! The CPU backend's kernel engine: runs a plan call's kernel by its registry row
//! ([`KernelId::twin`](crate::registry::KernelId::twin)), its bindings taken from a
//! [`Pool`] of the backend's buffers by the names the WGSL declares them with, as the GPU
//! engine's bind groups take them (`wgslam_gpu`'s `bind_groups.rs`: `frame_pool`,
//! `level_pool`). Rows of the `OverFrame`, `PerItem` and `PerLevel` [`Shape`]s bind here;
//! a step runs the kernels of other rows through arms of its own.
//!
//! Not here: the buffers' sizes (each step sizes what its kernels write before its plan
//! runs, as the GPU backend allocates its frame's buffers), and the order of the kernels
//! (`crate::plan`).

use super::CpuBackend;
use crate::cpu::binding::Pool;
use crate::plan::Call;
use crate::registry::{At, Shape};

impl CpuBackend {
    /// Runs `call`'s kernel through its row: its twin over the bindings it names, from
    /// `step` (the step's own uniforms and buffers: the kernel's `params` is the uniform
    /// its row names) and the frame's pool (an `OverFrame` or `PerItem` row) or the pool
    /// of the pyramid level the call gives (a `PerLevel` row). Panics on a call whose
    /// kernel has no twin in the one call shape, or a row of another shape (internal
    /// contracts: such a call has an arm in its step).
    pub(super) fn dispatch(&mut self, call: impl Call, step: Pool<'_>) {
        let kernel = call.kernel();
        let row = kernel.and_then(|k| Some((k.twin()?, k.shape()?, k.uniform()?)));
        let Some((twin, shape, uniform)) = row else {
            panic!("`{}` has no twin in the one call shape", call.name())
        };
        let mut pool = match shape {
            Shape::OverFrame | Shape::PerItem => self.frame_pool(step),
            Shape::PerLevel => self.level_pool(step, call.at().choice()),
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

    /// `pool` with pyramid level `at.level`'s maps, named as at level 0, and its finer
    /// level's as `fine_*` (the GPU's `level_pool`): level 0's are the frame's, its
    /// `vertex_map` and `point_map` the vertex maps `at` chooses (see [`At`]), which level
    /// 1's `fine_vertex` is too; its intensity patches are `intensity_patch`, the finer
    /// level's `fine_map` (at level 0 the colour map), with the level's `intensity`
    /// uniform. Maps a step has not made yet (the prediction before the first `predict`)
    /// are not in the pool.
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
        if at.level < self.prediction.len() {
            let (finer, this) = self.prediction.split_at_mut(at.level);
            let (pred_vertex, pred_normal) = &mut this[0];
            pool.write("pred_vertex", pred_vertex);
            pool.write("pred_normal", pred_normal);
            if let Some((fine_vertex, fine_normal)) = finer.last_mut() {
                pool.write("fine_pred_vertex", fine_vertex);
                pool.write("fine_pred_normal", fine_normal);
            }
        }
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
