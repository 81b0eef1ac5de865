//! The GPU side of `icp_candidates`: one count per `icp_reduce` workgroup, read back and
//! summed on the host, once per tracked frame (the tracking-health inlier fraction).

use super::backend::GpuBackend;
use super::buffers::{GpuArray, Readback};
use super::recording::{record_passes, submit_profiled};
use crate::layout::IcpParams;
use crate::Result;

/// Most `icp_candidates` workgroups (a grid-stride loop: fewer only means more pixels per
/// thread): 256 x 64 threads still cover a 640x480 frame in 19 pixels each, and the
/// counts read back stay at 1 KB (a GPU's 1024 reduction workgroups would read back 4 KB
/// a frame, half of the 8 KB budget of a frame that is not a keyframe).
const CANDIDATE_WORKGROUPS_MAX: u32 = 256;

/// `icp_candidates`' per-workgroup counts and their read-back.
pub(super) struct CandidateBuffers {
    counts: GpuArray<u32>,
    readback: Readback<u32>,
}

impl GpuBackend {
    /// `icp_candidates` at level 0; see `Backend::icp_candidates`.
    pub(super) fn icp_candidates_on_gpu(&mut self, params: &IcpParams) -> Result<u64> {
        let ctx = &self.ctx;
        let wg = self.reduction_workgroups.min(CANDIDATE_WORKGROUPS_MAX);
        if self.candidates.is_none() {
            let mut counts = GpuArray::new(ctx, "icp candidate counts", wg as usize)?;
            counts.set_len(wg as usize);
            let readback = Readback::new(ctx, "icp candidate counts read-back", wg as usize);
            self.candidates = Some(CandidateBuffers { counts, readback });
        }
        let b = self.candidates.as_mut().expect("just made");
        let frame = self
            .frame
            .as_ref()
            .expect("preprocess() runs before any other step");
        let u = &self.uniforms;
        ctx.scoped("icp_candidates", || {
            u.icp.write(ctx, params);
            let group = self.kernels.icp_candidates.bind_group(
                ctx,
                &[
                    ("params", u.icp.binding()),
                    ("pred_vertex", frame.pred_vertex.binding()),
                    ("normal_depth", frame.normal_depth.binding()),
                    ("counts", b.counts.binding()),
                ],
            );
            let mut enc = ctx.encoder("icp_candidates");
            record_passes(
                ctx,
                &mut self.profiler,
                &mut enc,
                &[(&self.kernels.icp_candidates, &group, [wg, 1])],
            )?;
            b.readback.copy_from(&mut enc, &b.counts, wg as usize);
            submit_profiled(ctx, &mut self.profiler, enc)?;
            Ok(b.readback.read(ctx)?.iter().map(|&c| c as u64).sum())
        })
    }
}
