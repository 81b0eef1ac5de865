//! The CPU backend's `fuse` step: `plan::fuse`'s kernels in order over the frame's maps
//! and the surfel map (the twins of `block_bounds`, `fuse_select`, `fuse_merge_chosen`,
//! `fuse_prune`, `fuse_merge`, `fuse_flags`, the scan's three and `fuse_add`, each through
//! its row, `engine.rs`), and the scan's calls, fusion's and compaction's (`scan_call`).

use super::CpuBackend;
use crate::cpu::binding::Pool;
use crate::cpu::invocations::par_fill;
use crate::fused_view::FusedView;
use crate::layout::{append_slots, scan_blocks, scan_params, FuseParams};
use crate::plan::{self, Buffer, Call, FuseCall};
use crate::registry::{KernelId, Scanned};

impl CpuBackend {
    /// `Backend::fuse` on the CPU: the plan's kernels over the frame's maps and the map.
    pub(super) fn fuse_step(&mut self, params: &FuseParams) {
        let n_pix = (params.camera.width * params.camera.height) as usize;
        let count = self.map.len();
        let mut params = *params;
        params.surfel_count = count as u32;
        params.capacity = (count + n_pix) as u32;
        self.fused_view = None;
        let mut added = 0u32;
        for call in plan::fuse(&params) {
            self.fuse_call(call, &params, &mut added);
        }
        let new_len = count + added as usize;
        self.map.resize(new_len);
        // The blocks from the one that held the old last surfel on have new surfels.
        self.bounds_dirty_from = self.bounds_dirty_from.min(count);
        self.fused_view = FusedView::of_fuse(&params);
    }

    /// One call of `fuse`'s plan: a buffer cleared, or a kernel's twin run over the frame's
    /// maps and the map (through its row, with `params` as the `fuse` uniform, but for the
    /// scan's). `added` receives the prefix sum's total, the number of surfels `fuse_add`
    /// appends.
    fn fuse_call(&mut self, call: FuseCall, params: &FuseParams, added: &mut u32) {
        let n_pix = (params.camera.width * params.camera.height) as usize;
        // Flags and offsets in append order (holes for tiles outside the image stay 0).
        let n_slots = append_slots(params.camera.width, params.camera.height);
        let mut step = Pool::new();
        step.uniform("fuse", params);
        match call {
            FuseCall::Clear(buffer) => self.clear_fuse_buffer(buffer, n_pix),
            FuseCall::BlockBounds => self.refresh_bounds(call),
            FuseCall::FuseSelect
            | FuseCall::FuseMergeChosen
            | FuseCall::FusePrune
            | FuseCall::FuseMerge => self.dispatch(call, step),
            FuseCall::FuseFlags => {
                self.add_flags.resize(n_slots, 0);
                self.dispatch(call, step);
            }
            FuseCall::FuseScanReduce | FuseCall::FuseScanBlocks | FuseCall::FuseScan => {
                self.scan_call(call, n_slots, added);
            }
            FuseCall::FuseAdd { .. } => {
                // Room for the new surfels the scan counted, each at its slot (the GPU's
                // map has room for every pixel, `params.capacity`; the same surfels land
                // in it). Not `capacity` slots: zeroing a frame's worth of slots that the
                // map then drops cost 1.5 ms a frame at 640x480, on one thread.
                let len = params.surfel_count as usize + *added as usize;
                assert!(
                    len <= params.capacity as usize,
                    "more new surfels than pixels"
                );
                self.map.resize(len);
                self.dispatch(call, step);
            }
        }
    }

    /// Empties one of fusion's per-pixel buffers to its size at `n_pix` pixels, all zero.
    fn clear_fuse_buffer(&mut self, buffer: Buffer, n_pix: usize) {
        match buffer {
            Buffer::Assoc => par_fill(&mut self.assoc, n_pix, 0),
            Buffer::Merged => par_fill(&mut self.merged, 2 * n_pix, [0.0; 4]),
            Buffer::IndexMap => par_fill(&mut self.index_map, n_pix, 0),
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
