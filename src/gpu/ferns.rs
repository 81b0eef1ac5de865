//! The GPU side of the relocalisation keyframe database's encoding: `fern_encode`'s
//! buffers (made at the first call, grown when more ferns are asked for) and its dispatch
//! and read-back of one `u32` code per fern (2 KB for the default 500 ferns).
//!
//! Fern codes read only the frame's maps, not the surfel map, so `fuse` records the
//! encoding with the last call's parameters into its own submission ([`record_ahead`]);
//! the pipeline's `encode_ferns` after it then only reads the codes back, one round trip
//! less per frame. `preprocess` drops codes recorded ahead (they belong to the last frame).

use super::backend::GpuBackend;
use super::buffers::{GpuArray, ParamBuffer, Readback};
use super::context::GpuContext;
use super::recording::{record_passes, submit_profiled};
use crate::layout::{Fern, FernParams};
use crate::Result;

/// `fern_encode`'s parameters, ferns, codes and the codes' read-back.
pub(super) struct FernBuffers {
    params: ParamBuffer<FernParams>,
    ferns: GpuArray<Fern>,
    codes: GpuArray<u32>,
    readback: Readback<u32>,
    /// The ferns last uploaded (a run's are fixed: uploaded once, not every frame).
    uploaded: Vec<Fern>,
    /// The parameters of the last encoding, which [`record_ahead`] repeats.
    last: Option<FernParams>,
    /// Set when the codes of the frame now in the frame buffers, with these parameters,
    /// were recorded ahead into a submission and copied to `readback`.
    pub(super) ahead: Option<FernParams>,
}

impl FernBuffers {
    fn new(ctx: &GpuContext, params: &FernParams, count: usize) -> Result<Self> {
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
}

impl GpuBackend {
    /// `fern_encode` over the frame's level-0 maps; see `Backend::encode_ferns`.
    pub(super) fn encode_ferns_on_gpu(
        &mut self,
        params: &FernParams,
        ferns: &[Fern],
    ) -> Result<Vec<u32>> {
        let n = params.fern_count as usize;
        assert!(ferns.len() >= n, "{} ferns for fern_count {n}", ferns.len());
        if n == 0 {
            return Ok(vec![]);
        }
        let ctx = &self.ctx;
        if self.ferns.as_ref().is_none_or(|b| b.ferns.capacity() < n) {
            self.ferns = Some(FernBuffers::new(ctx, params, n)?);
        }
        let b = self.ferns.as_mut().expect("just made");
        if b.ahead.take() == Some(*params) && b.uploaded[..] == ferns[..n] {
            // Recorded by this frame's fuse and already done: only the read remains.
            return ctx.scoped("fern_encode", || b.readback.read(ctx));
        }
        b.last = Some(*params);
        let frame = self
            .frame
            .as_ref()
            .expect("preprocess() runs before any other step");
        ctx.scoped("fern_encode", || {
            b.params.write(ctx, params);
            if b.uploaded[..] != ferns[..n] {
                b.ferns.upload(ctx, &ferns[..n])?;
                b.uploaded = ferns[..n].to_vec();
            }
            let group = self.kernels.fern_encode.bind_group(
                ctx,
                &[
                    ("params", b.params.binding()),
                    ("ferns", b.ferns.binding()),
                    ("normal_depth", frame.normal_depth.binding()),
                    ("color", frame.color.binding()),
                    ("codes", b.codes.binding()),
                ],
            );
            let mut enc = ctx.encoder("fern_encode");
            record_passes(
                ctx,
                &mut self.profiler,
                &mut enc,
                &[(&self.kernels.fern_encode, &group, [workgroups(ctx, n), 1])],
            )?;
            b.readback.copy_from(&mut enc, &b.codes, n);
            submit_profiled(ctx, &mut self.profiler, enc)?;
            b.readback.read(ctx)
        })
    }
}

/// `fern_encode`'s workgroups for `n` ferns: one thread per fern, at most the adapter's
/// reduction workgroups.
fn workgroups(ctx: &GpuContext, n: usize) -> u32 {
    (n as u32)
        .div_ceil(64)
        .min(ctx.reduction_workgroups().max(1))
}

/// Records `fern_encode` with the last encoding's parameters (if there was one) over the
/// frame's maps into `enc`, and the codes' copy to the read-back, so the next
/// `encode_ferns` with those parameters reads them without a submission of its own.
pub(super) fn record_ahead(
    ctx: &GpuContext,
    kernel: &super::kernel::Kernel,
    ferns: &mut Option<FernBuffers>,
    frame: &super::resources::FrameBuffers,
    profiler: &mut Option<super::recording::Profiler>,
    enc: &mut wgpu::CommandEncoder,
) -> Result<()> {
    let Some(b) = ferns.as_mut() else {
        return Ok(());
    };
    let Some(params) = b.last else {
        return Ok(());
    };
    let n = params.fern_count as usize;
    let group = kernel.bind_group(
        ctx,
        &[
            ("params", b.params.binding()),
            ("ferns", b.ferns.binding()),
            ("normal_depth", frame.normal_depth.binding()),
            ("color", frame.color.binding()),
            ("codes", b.codes.binding()),
        ],
    );
    record_passes(
        ctx,
        profiler,
        enc,
        &[(kernel, &group, [workgroups(ctx, n), 1])],
    )?;
    b.readback.copy_from(enc, &b.codes, n);
    b.ahead = Some(params);
    Ok(())
}
