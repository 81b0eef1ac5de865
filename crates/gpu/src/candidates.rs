//! The GPU side of the candidate count: one count per workgroup, read back and summed on
//! the host, once per tracked frame (the tracking-health inlier fraction). The step itself
//! is in `super::single_steps`; its kernel is bound by its registry row, over
//! [`bindings`].

use super::bind_groups::OnDemand;
use super::buffers::{GpuArray, Readback};
use super::context::GpuContext;
use crate::Result;

/// Most `icp_candidates` workgroups (a grid-stride loop: fewer only means more pixels per
/// thread): 256 x 64 threads still cover a 640x480 frame in 19 pixels each, and the
/// counts read back stay at 1 KB (a GPU's 1024 reduction workgroups would read back 4 KB
/// a frame, half of the 8 KB budget of a frame that is not a keyframe).
pub(super) const CANDIDATE_WORKGROUPS_MAX: u32 = 256;

/// `icp_candidates`' per-workgroup counts and their read-back.
pub(super) struct CandidateBuffers {
    pub counts: GpuArray<u32>,
    pub readback: Readback<u32>,
}

impl CandidateBuffers {
    /// Counts for `workgroups` workgroups.
    pub fn new(ctx: &GpuContext, workgroups: u32) -> Result<Self> {
        let n = workgroups as usize;
        let mut counts = GpuArray::new(ctx, "icp candidate counts", n)?;
        counts.set_len(n);
        let readback = Readback::new(ctx, "icp candidate counts read-back", n);
        Ok(CandidateBuffers { counts, readback })
    }
}

/// The counts by the name the kernel declares them with, `None` before the first count
/// (see `super::bind_groups::OnDemand`).
pub(super) fn bindings(b: Option<&CandidateBuffers>) -> OnDemand<'_> {
    vec![("counts", b.map(|b| b.counts.binding()))]
}
