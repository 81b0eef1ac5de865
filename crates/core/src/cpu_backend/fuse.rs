//! The CPU backend's `fuse` step: `plan::fuse`'s kernels in order over the frame's maps
//! and the surfel map (the twins of `fuse_select`, `fuse_merge_chosen`, `fuse_prune`,
//! `fuse_merge`, `fuse_flags`, `prefix_sum` and `fuse_add`), and the scan's calls, fusion's
//! and compaction's.

use super::CpuBackend;
use crate::cpu;
use crate::cpu::binding::Pool;
use crate::fused_view::FusedView;
use crate::layout::{append_slots, scan_blocks, scan_params, FuseParams, MapChunk};
use crate::plan::{self, Buffer, Call, FuseCall};
use crate::registry::{KernelId, Scanned};

impl CpuBackend {
    /// `Backend::fuse` on the CPU: the plan's kernels over the frame's maps and the map;
    /// the map's new length.
    pub(super) fn fuse_step(&mut self, params: &FuseParams) -> usize {
        let n_pix = (params.camera.width * params.camera.height) as usize;
        let count = self.map.len();
        let mut params = *params;
        params.surfel_count = count as u32;
        params.capacity = (count + n_pix) as u32;
        self.fused_view = None;
        let chunk = MapChunk::whole(count);
        let mut added = 0u32;
        for call in plan::fuse(&params) {
            self.fuse_call(call, &params, &chunk, &mut added);
        }
        let new_len = count + added as usize;
        self.map.resize(new_len);
        // The blocks from the one that held the old last surfel on have new surfels.
        self.bounds_dirty_from = self.bounds_dirty_from.min(count);
        self.fused_view = FusedView::of_fuse(&params);
        new_len
    }

    /// One call of `fuse`'s plan: a buffer cleared, or a kernel's twin run over the frame's
    /// maps and `chunk` of the map. `added` receives the prefix sum's total, the number of
    /// surfels `fuse_add` appends.
    fn fuse_call(
        &mut self,
        call: FuseCall,
        params: &FuseParams,
        chunk: &MapChunk,
        added: &mut u32,
    ) {
        let n_pix = (params.camera.width * params.camera.height) as usize;
        // Flags and offsets in append order (holes for tiles outside the image stay 0).
        let n_slots = append_slots(params.camera.width, params.camera.height);
        let m = &mut self.map;
        match call {
            FuseCall::Clear(buffer) => self.clear_fuse_buffer(buffer, n_pix),
            FuseCall::BlockBounds => self.refresh_bounds(),
            FuseCall::FuseSelect => cpu::fuse_select::fuse_select(
                params,
                &self.frame.normal_depth,
                chunk,
                &self.block_boxes,
                &m.position_weight,
                &m.normal_frame,
                &m.color,
                &mut self.assoc,
                &mut self.index_map,
            ),
            FuseCall::FuseMergeChosen => cpu::fuse_merge_chosen::fuse_merge_chosen(
                params,
                &self.frame.normal_depth,
                &self.frame.color,
                chunk,
                bytemuck::cast_slice_mut(&mut self.block_boxes),
                &mut m.position_weight,
                &mut m.normal_frame,
                &mut m.color,
                &self.assoc,
                &mut self.merged,
            ),
            FuseCall::FusePrune => cpu::fuse_prune::fuse_prune(
                params,
                chunk,
                &self.block_boxes,
                &mut m.position_weight,
                &mut m.normal_frame,
                &m.color,
                &self.merged,
            ),
            FuseCall::FuseMerge => cpu::fuse_merge::fuse_merge(
                params,
                &self.frame.normal_depth,
                &self.frame.color,
                chunk,
                bytemuck::cast_slice_mut(&mut self.block_boxes),
                &mut m.position_weight,
                &mut m.normal_frame,
                &mut m.color,
                &mut self.assoc,
            ),
            FuseCall::FuseFlags => {
                self.add_flags.resize(n_slots, 0);
                let mut step = Pool::new();
                step.uniform("fuse", params);
                self.dispatch(call, step);
            }
            FuseCall::FuseScanReduce | FuseCall::FuseScanBlocks | FuseCall::FuseScan => {
                self.scan_call(call, n_slots, added);
            }
            FuseCall::FuseAdd { .. } => {
                // Room for every pixel, as the GPU backend guarantees before its dispatch.
                m.resize(params.capacity as usize);
                cpu::fuse_add::fuse_add(
                    params,
                    &self.frame.normal_depth,
                    &self.frame.color,
                    &self.add_flags,
                    &self.add_offsets,
                    &MapChunk::whole(params.capacity as usize),
                    &mut m.position_weight,
                    &mut m.normal_frame,
                    &mut m.color,
                    &mut self.index_map,
                );
            }
        }
    }

    /// Empties one of fusion's per-pixel buffers to its size at `n_pix` pixels, all zero.
    fn clear_fuse_buffer(&mut self, buffer: Buffer, n_pix: usize) {
        match buffer {
            Buffer::Assoc => {
                self.assoc.clear();
                self.assoc.resize(n_pix, 0);
            }
            Buffer::Merged => {
                self.merged.clear();
                self.merged.resize(2 * n_pix, [0.0; 4]);
            }
            Buffer::IndexMap => {
                self.index_map.clear();
                self.index_map.resize(n_pix, 0);
            }
        }
    }
}

impl CpuBackend {
    /// One of a scan's three calls over `n` flags, fusion's or compaction's (the call's
    /// [`Scanned`](crate::registry::Scanned)), through the engine: at the first, the scan's
    /// `block_sums` and the flags' `offsets` sized for `n` flags (as the GPU allocates
    /// them); `counter` receives the flags' total (the scan's `counter`, the GPU's surfel
    /// counter).
    pub(super) fn scan_call(&mut self, call: impl Call, n: usize, counter: &mut u32) {
        if call.kernel() == Some(KernelId::prefix_sum_reduce) {
            self.block_sums.resize(scan_blocks(n), 0);
            match call.at().scanned {
                Scanned::NewSurfels => self.add_offsets.resize(n, 0),
                Scanned::KeepFlags => self.offsets.resize(n, 0),
            }
        }
        let params = scan_params(n);
        let mut step = Pool::new();
        step.uniform("scan", &params);
        step.write("counter", std::slice::from_mut(counter));
        self.dispatch(call, step);
    }
}
