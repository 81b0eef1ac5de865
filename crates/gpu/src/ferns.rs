//! The GPU side of the relocalisation keyframe database's encoding: `fern_encode`'s
//! buffers (made at the first call, grown when more ferns are asked for), its bind group
//! and the read-back of one `u32` code per fern (2 KB for the default 500 ferns). The step
//! itself is in `super::single_steps`.
//!
//! Fern codes read only the frame's maps, not the surfel map, so `fuse` records the
//! encoding with the last call's parameters into its own submission ([`record_ahead`]);
//! the pipeline's `encode_ferns` after it then only reads the codes back, one round trip
//! less per frame. `preprocess` drops codes recorded ahead (they belong to the last frame).

use super::buffers::{GpuArray, ParamBuffer, Readback};
use super::context::GpuContext;
use super::kernel::Kernel;
use super::recording::{record_call, Profiler};
use super::resources::FrameBuffers;
use crate::layout::{Fern, FernParams};
use crate::Result;
use wgslam_core::plan::{self, Call};

/// `fern_encode`'s parameters, ferns, codes and the codes' read-back.
pub(super) struct FernBuffers {
    /// The kernel's `params` (uniform).
    pub params: ParamBuffer<FernParams>,
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
    /// were recorded ahead into a submission and copied to `readback`.
    pub(super) ahead: Option<FernParams>,
}

impl FernBuffers {
    pub fn new(ctx: &GpuContext, params: &FernParams, count: usize) -> Result<Self> {
        let mut ferns = GpuArray::new(ctx, "ferns", count)?;
        ferns.set_len(count);
        let mut codes = GpuArray::new(ctx, "fern codes", count)?;
        codes.set_len(count);
        Ok(FernBuffers {
            params: ParamBuffer::new(ctx, "FernParams", params),
            ferns,
            codes,
            readback: Readback::new(ctx, "fern codes read-back", count),
            uploaded: Vec::new(),
            last: None,
            ahead: None,
        })
    }

    /// `fern_encode`'s resources besides the frame's maps.
    pub fn pool(&self) -> Vec<(&'static str, wgpu::BindingResource<'_>)> {
        vec![
            ("params", self.params.binding()),
            ("ferns", self.ferns.binding()),
            ("codes", self.codes.binding()),
        ]
    }
}

/// `fern_encode`'s workgroups for `n` ferns: one thread per fern, at most the adapter's
/// reduction workgroups.
pub(super) fn workgroups(ctx: &GpuContext, n: usize) -> u32 {
    (n as u32)
        .div_ceil(64)
        .min(ctx.reduction_workgroups().max(1))
}

/// Records `fern_encode` with the last encoding's parameters (if there was one) over the
/// frame's maps into `enc`, and the codes' copy to the read-back, so the next
/// `encode_ferns` with those parameters reads them without a submission of its own.
pub(super) fn record_ahead(
    ctx: &GpuContext,
    kernel: &Kernel,
    ferns: &mut Option<FernBuffers>,
    frame: &FrameBuffers,
    profiler: &mut Option<Profiler>,
    enc: &mut wgpu::CommandEncoder,
) -> Result<()> {
    let Some(b) = ferns.as_mut() else {
        return Ok(());
    };
    let Some(params) = b.last else {
        return Ok(());
    };
    let n = params.fern_count as usize;
    let group = frame.bind_level0(ctx, kernel, b.pool());
    let call = plan::encode_ferns().name();
    record_call(
        ctx,
        profiler,
        enc,
        call,
        &[(kernel, &group, [workgroups(ctx, n), 1])],
    )?;
    b.readback.copy_from(enc, &b.codes, n);
    b.ahead = Some(params);
    Ok(())
}
