//! The GPU side of the relocalisation keyframe database's encoding: `fern_encode`'s
//! buffers (made at the first call, grown when more ferns are asked for; the kernel is
//! bound by its registry row over [`bindings`]) and the read-back of one `u32` code per
//! fern (2 KB for the default 500 ferns). The step itself is in `super::single_steps`.
//!
//! Fern codes read only the frame's maps, not the surfel map, so `preprocess` records the
//! encoding with the last call's parameters after its own kernels ([`record_ahead`]),
//! and the codes' copy goes with the first ICP iteration's submission. The pipeline's
//! `encode_ferns` after the fusion then only takes the codes (`Readback::take`): the ICP
//! read-backs' waits covered them, so it waits for nothing, not even the fusion.

use super::bind_groups::{BindGroups, OnDemand};
use super::buffers::{GpuArray, Readback};
use super::context::GpuContext;
use super::pipelines::Kernels;
use super::recording::{record_call, Profiler};
use super::step_grid::StepGrid;
use crate::layout::{Fern, FernParams};
use crate::Result;
use wgslam_core::plan::{self, Call};

/// `fern_encode`'s ferns, codes and the codes' read-back (its parameters are the
/// backend's `Uniforms::ferns`).
pub(super) struct FernBuffers {
    /// The fern table, at least `fern_count` ferns.
    pub ferns: GpuArray<Fern>,
    /// One code per fern, written by the kernel.
    pub codes: GpuArray<u32>,
    /// The codes' read-back.
    pub readback: Readback<u32>,
    /// The ferns last uploaded (a run's are fixed: uploaded once, not every frame).
    pub uploaded: Vec<Fern>,
    /// The parameters of the last encoding, which [`record_ahead`] repeats.
    pub last: Option<FernParams>,
    /// Set when the codes of the frame now in the frame buffers, with these parameters,
    /// were recorded ahead (by its `preprocess`) and copied to `readback`.
    pub(super) ahead: Option<FernParams>,
}

impl FernBuffers {
    pub fn new(ctx: &GpuContext, count: usize) -> Result<Self> {
        let mut ferns = GpuArray::new(ctx, "ferns", count)?;
        ferns.set_len(count);
        let mut codes = GpuArray::new(ctx, "fern codes", count)?;
        codes.set_len(count);
        Ok(FernBuffers {
            ferns,
            codes,
            readback: Readback::new(ctx, "fern codes read-back", count),
            uploaded: Vec::new(),
            last: None,
            ahead: None,
        })
    }
}

/// `fern_encode`'s buffers by the names it declares them with, `None` before the first
/// `encode_ferns`.
pub(super) fn bindings(b: Option<&FernBuffers>) -> OnDemand<'_> {
    vec![
        ("ferns", b.map(|b| b.ferns.binding())),
        ("codes", b.map(|b| b.codes.binding())),
    ]
}

/// Records `fern_encode` with the last encoding's parameters (if there was one: still in
/// `Uniforms::ferns`) over the frame's maps, `frame` `[width, height]` pixels, into `enc`,
/// and the codes' copy to the read-back, so the next `encode_ferns` with those parameters
/// reads them without a submission of its own. Codes recorded for an earlier frame are
/// forgotten either way.
pub(super) fn record_ahead(
    ctx: &GpuContext,
    (k, bg): (&Kernels, &BindGroups),
    ferns: &mut Option<FernBuffers>,
    frame: [u32; 2],
    profiler: &mut Option<Profiler>,
    enc: &mut wgpu::CommandEncoder,
) -> Result<()> {
    let Some(b) = ferns.as_mut() else {
        return Ok(());
    };
    b.ahead = None;
    let Some(params) = b.last else {
        return Ok(());
    };
    let n = params.fern_count as usize;
    let call = plan::encode_ferns();
    let mut grid = StepGrid::new(ctx, frame, Vec::new());
    grid.items = n;
    record_call(ctx, profiler, enc, call.name(), &grid.generic(k, bg, call))?;
    b.readback.copy_from(enc, &b.codes, n);
    b.ahead = Some(params);
    Ok(())
}
