//! The CPU backend's `fuse` step: `plan::fuse`'s kernels in order over the frame's maps
//! and the surfel map (the twins of `block_bounds`, `fuse_select`, `fuse_merge_chosen`,
//! `fuse_prune`, `fuse_merge`, `fuse_flags` and `fuse_add` through their rows, `engine.rs`;
//! the scan's by hand, `scan_twin`).

use super::CpuBackend;
use crate::cpu;
use crate::cpu::binding::Pool;
use crate::fused_view::FusedView;
use crate::layout::{append_slots, scan_blocks, scan_params, FuseParams};
use crate::plan::{self, Buffer, Call, FuseCall};
use crate::registry::KernelId;

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
        let mut added = 0u32;
        for call in plan::fuse(&params) {
            self.fuse_call(call, &params, &mut added);
        }
        let new_len = count + added as usize;
        self.map.resize(new_len);
        // The blocks from the one that held the old last surfel on have new surfels.
        self.bounds_dirty_from = self.bounds_dirty_from.min(count);
        self.fused_view = FusedView::of_fuse(&params);
        new_len
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
                let offsets = &mut self.add_offsets;
                let (flags, block_sums) = (&self.add_flags, &mut self.block_sums);
                scan_twin(call.kernel(), n_slots, flags, block_sums, offsets, added);
            }
            FuseCall::FuseAdd { .. } => {
                // Room for every pixel, as the GPU backend guarantees before its dispatch: the
                // map's one chunk is then `params.capacity` slots.
                self.map.resize(params.capacity as usize);
                self.dispatch(call, step);
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

/// The twin of a scan call's `kernel` (one of the scan's three, run in plan order) over
/// `n` `flags`, fusion's or compaction's: the sums of the blocks of flags into
/// `block_sums`, then the blocks' offsets in place and the total into `counter`, then each
/// flag's offset into `offsets`.
pub(super) fn scan_twin(
    kernel: Option<KernelId>,
    n: usize,
    flags: &[u32],
    block_sums: &mut Vec<u32>,
    offsets: &mut Vec<u32>,
    counter: &mut u32,
) {
    let params = scan_params(n);
    match kernel {
        Some(KernelId::prefix_sum_reduce) => {
            block_sums.resize(scan_blocks(n), 0);
            cpu::prefix_sum_reduce::prefix_sum_reduce(&params, flags, block_sums);
        }
        Some(KernelId::prefix_sum_blocks) => {
            cpu::prefix_sum_blocks::prefix_sum_blocks(&params, block_sums, counter);
        }
        Some(KernelId::prefix_sum) => {
            offsets.resize(n, 0);
            cpu::prefix_sum::prefix_sum(&params, flags, block_sums, offsets);
        }
        other => panic!("{other:?} is not one of the scan's kernels"),
    }
}
