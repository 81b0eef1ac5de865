//! The CPU backend's kernel engine: runs a plan call's kernel by its registry row
//! ([`KernelId::twin`](crate::registry::KernelId::twin)), its bindings taken from a
//! [`Pool`] of the backend's buffers by the names the WGSL declares them with, as the GPU
//! engine's bind groups take them (`wgslam_gpu`'s `bind_groups.rs`: `frame_pool`,
//! `level_pool`, `chunk_pool`, `map_row_groups`, `scan_groups`, `system_pool`). Rows of
//! every [`Shape`] of the SLAM pipeline bind here: `OverFrame`, `PerItem`, `PerCount`,
//! `PerLevel`, `Reduce`, `PerSystem`, `PerScanBlock`, `OneWorkgroup` and the map's
//! (`PerChunk`, `PerBlock`, `PerStaleBlock`, `PerSurfel`, `PerChunkPair`).
//!
//! The map is one chunk: the CPU map is one array per attribute, grown without a cap, so
//! a map row's pool binds it whole as the GPU binds each of its chunks (`chunk` is
//! `MapChunk::whole` of the map's length, `position_weight`, `normal_frame` and `color`
//! the map's arrays), and the kernel runs once where the GPU runs it once per chunk. The
//! twins walk `chunk` as the shaders do, so the outputs are the GPU's whatever its
//! chunking (the key kernels keep the same key per pixel in any order: see
//! `cpu::key_writer`). A key map binds as the 64-bit kernel's (`u64` keys: the CPU has
//! 64-bit integers); the portable variant's passes are for tests to bind
//! (`Binding::key_pass`).
//!
//! The rows of the kernels outside the dense pipeline (the renderer's and scan
//! registration's: [`Shape::bound_by_caller`]) bind from their callers' pools alone, through
//! [`run_call`], in the order of their plans.
//!
//! Not here: the buffers' sizes (each step sizes what its kernels write before its plan
//! runs, as the GPU backend allocates its frame's buffers), and the order of the kernels
//! (`crate::plan`).

use super::CpuBackend;
use crate::cpu::binding::{Pool, Twin};
use crate::layout::map::SurfelMap;
use crate::layout::MapChunk;
use crate::plan::Call;
use crate::registry::{At, Scanned, Shape};

impl CpuBackend {
    /// Runs `call`'s kernel through its row: its twin over the bindings it names, from
    /// `step` (the step's own uniforms and buffers: the kernel's `params` is the uniform
    /// its row names) and the frame's pool (an `OverFrame`, `PerItem` or `PerCount` row),
    /// the pool of the pyramid level the call gives (a `PerLevel` or `Reduce` row), the
    /// pool of the flags it scans (a scan's row), the map's one chunk's pool with the
    /// frame's (a `PerChunk`, `PerBlock` or `PerStaleBlock` row) or without it (a
    /// `PerSurfel` row; a `PerChunkPair` row's, once per surfel array, with the spare map
    /// as its output chunk: see [`CpuBackend::map_pool`]). A `PerSystem` row binds the
    /// step's alone (a system's `partials` and `system`, which the step owns). Panics on a
    /// call with no kernel or a kernel whose row names no twin or uniform ([`row`]).
    pub(super) fn dispatch(&mut self, call: impl Call, step: Pool<'_>) {
        let (twin, shape, uniform) = row(call);
        // The map as its one chunk (see the module notes), and the spare map as compaction's
        // output chunk.
        let chunk = MapChunk::whole(self.map.len());
        let out_chunk = MapChunk::whole(self.spare.len());
        let mut pool = match shape {
            Shape::OverFrame | Shape::PerItem | Shape::PerCount => self.frame_pool(step, None),
            Shape::PerLevel | Shape::Reduce => self.level_pool(step, call.at().choice()),
            Shape::PerSystem => step,
            // Bound by their callers (`run_call`), as the GPU's `StepGrid` refuses them.
            Shape::PerPoint | Shape::PerPartial => {
                panic!(
                    "`{}` is bound by its caller: run it with run_call",
                    call.name()
                )
            }
            Shape::PerScanBlock | Shape::OneWorkgroup => self.scan_pool(step, call.at().scanned),
            Shape::PerChunk | Shape::PerBlock | Shape::PerStaleBlock => {
                self.frame_pool(step, Some(&chunk))
            }
            Shape::PerSurfel => self.map_pool(step, &chunk, None).0,
            Shape::PerChunkPair => {
                let (pool, pairs) = self.map_pool(step, &chunk, Some(&out_chunk));
                return scatter_pairs(pool, pairs, twin, uniform);
            }
        };
        (twin.run)(&mut pool.bind(twin.bindings, uniform));
    }

    /// `pool` with the frame's maps and per-pixel buffers, by the names the kernels
    /// declare them with (the GPU's `frame_pool`): `vertex_map` the unfiltered vertex map,
    /// as `depth_to_vertex` writes it and `bilateral_filter` reads it. With a `chunk`, the
    /// map as that chunk too ([`chunk_pool`]), as the GPU binds a `PerChunk`, `PerBlock` or
    /// `PerStaleBlock` row per chunk over the chunk's pool and the frame's.
    fn frame_pool<'a>(&'a mut self, mut pool: Pool<'a>, chunk: Option<&'a MapChunk>) -> Pool<'a> {
        if let Some(chunk) = chunk {
            chunk_pool(&mut pool, chunk, &mut self.map, &mut self.block_boxes);
        }
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

    /// `pool` with the map alone, as the GPU binds a `PerSurfel` or `PerChunkPair` row
    /// (its `map_row_groups`: no frame's maps, so such a kernel also runs before the first
    /// frame): the map as `chunk` ([`chunk_pool`]) and compaction's arrays over every map
    /// slot, `flags` (the keep flags), `offsets` (their prefix sum) and `block_sums`; the
    /// step gives the rest (deformation's `nodes`). With an `out_chunk`, the spare map as
    /// that chunk too, and the pairs of entries a `PerChunkPair` row binds in turn
    /// ([`scatter_pairs`]): each surfel array of the map with the spare map's.
    fn map_pool<'a>(
        &'a mut self,
        mut pool: Pool<'a>,
        chunk: &'a MapChunk,
        out_chunk: Option<&'a MapChunk>,
    ) -> (Pool<'a>, Vec<(usize, usize)>) {
        let arrays = chunk_pool(&mut pool, chunk, &mut self.map, &mut self.block_boxes);
        pool.write("flags", &mut self.flags);
        pool.write("offsets", &mut self.offsets);
        pool.write("block_sums", &mut self.block_sums);
        let Some(out_chunk) = out_chunk else {
            return (pool, Vec::new());
        };
        pool.read("out_chunk", std::slice::from_ref(out_chunk));
        let spare = &mut self.spare;
        let out_arrays = [
            pool.lend(&mut spare.position_weight),
            pool.lend(&mut spare.normal_frame),
            pool.lend(&mut spare.color),
        ];
        (pool, arrays.into_iter().zip(out_arrays).collect())
    }
}

/// Runs `call`'s kernel through its row over its caller's `pool` alone: a row of a
/// [`Shape::bound_by_caller`] (the renderer's, scan registration's, whose callers own
/// every buffer), its bindings taken from `pool` by their WGSL names and its `params` the
/// pool's uniform its row names, as the GPU's `wgslam_gpu::row_kernels` binds it. Walked
/// in the order of the caller's plan (`crate::plan::render`,
/// `crate::plan::scan_correspondences`). Panics as `CpuBackend::dispatch` does, and on
/// a call whose row the dense pipeline's buffers bind.
pub fn run_call(call: impl Call, mut pool: Pool<'_>) {
    let (twin, shape, uniform) = row(call);
    assert!(
        shape.bound_by_caller(),
        "`{}` is a {shape:?} row: the CPU backend binds it",
        call.name()
    );
    (twin.run)(&mut pool.bind(twin.bindings, uniform));
}

/// `call`'s twin, [`Shape`] and uniform, from its registry row. Panics on a call with no
/// kernel, or a kernel whose row names no twin or uniform (internal contracts: every row
/// has all three, which `tests/it/bindings.rs` checks for the twins).
fn row(call: impl Call) -> (Twin, Shape, &'static str) {
    let kernel = call.kernel();
    let row = kernel.and_then(|k| Some((k.twin()?, k.shape()?, k.uniform()?)));
    row.unwrap_or_else(|| panic!("`{}` has no twin in the one call shape", call.name()))
}

/// The map's arrays as map chunk `chunk`, and the culling blocks' boxes, by the names the
/// kernels declare them with (the GPU's `chunk_pool`): `chunk`, `position_weight`,
/// `normal_frame`, `color`, `block_boxes`. Returns the entries of the three surfel arrays
/// in that order (the GPU's `surfel_arrays`).
fn chunk_pool<'a>(
    pool: &mut Pool<'a>,
    chunk: &'a MapChunk,
    map: &'a mut SurfelMap,
    block_boxes: &'a mut [[u32; 4]],
) -> [usize; 3] {
    pool.read("chunk", std::slice::from_ref(chunk));
    pool.write("block_boxes", block_boxes);
    [
        pool.write("position_weight", &mut map.position_weight),
        pool.write("normal_frame", &mut map.normal_frame),
        pool.write("color", &mut map.color),
    ]
}

/// A `PerChunkPair` row's `twin` over `pool` ([`CpuBackend::map_pool`] with its output
/// chunk), once per pair of entries of `pairs`: a surfel array of the map as
/// `surfel_array`, the spare map's as `out_surfel_array`, in the order the GPU's passes
/// take them (`position_weight`, `normal_frame`, `color`), with `uniform` as `params`.
fn scatter_pairs(mut pool: Pool<'_>, pairs: Vec<(usize, usize)>, twin: Twin, uniform: &str) {
    for (array, out_array) in pairs {
        pool.alias("surfel_array", array);
        pool.alias("out_surfel_array", out_array);
        (twin.run)(&mut pool.bind(twin.bindings, uniform));
    }
}
