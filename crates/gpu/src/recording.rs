//! Recording and submitting the GPU backend's compute passes: one pass per kernel
//! dispatch, timed per kernel when profiling ([`Profiler`]).

use std::collections::BTreeMap;

use super::context::GpuContext;
use super::kernel::Kernel;
use super::timing::StageTimer;
use crate::Result;

/// Passes one submission may time when profiling (a few per map chunk and pyramid level).
pub(super) const PROFILED_PASSES_MAX: u32 = 64;

/// Per-kernel GPU times: timestamps around each kernel's pass (or wall time without the
/// feature), totalled by kernel name. Reading them waits for the GPU after every step, so
/// it is for profiling runs only.
pub(super) struct Profiler {
    pub timer: StageTimer,
    pub totals: BTreeMap<String, (u64, f64)>,
}

/// One dispatch: a kernel, its bind group and its `[x, y]` workgroups.
pub(super) type Pass<'a> = (&'a Kernel, &'a wgpu::BindGroup, [u32; 2]);

/// Records one compute pass per dispatch, timed when profiling.
fn record_passes(
    ctx: &GpuContext,
    profiler: &mut Option<Profiler>,
    enc: &mut wgpu::CommandEncoder,
    dispatches: &[Pass],
) -> Result<()> {
    for (kernel, bind_group, workgroups) in dispatches {
        let mut pass = match profiler {
            Some(p) => p.timer.begin_pass(enc, &kernel.name),
            None => enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some(&kernel.name),
                timestamp_writes: None,
            }),
        };
        kernel.dispatch_grid(ctx, &mut pass, bind_group, *workgroups)?;
    }
    Ok(())
}

/// Submits `enc`; when profiling, resolves the timestamps first and adds them to the totals.
pub(super) fn submit_profiled(
    ctx: &GpuContext,
    profiler: &mut Option<Profiler>,
    mut enc: wgpu::CommandEncoder,
) -> Result<()> {
    match profiler {
        None => {
            ctx.submit(enc);
        }
        Some(p) => {
            p.timer.resolve(&mut enc);
            ctx.submit(enc);
            for t in p.timer.read(ctx)? {
                let e = p.totals.entry(t.name).or_insert((0, 0.0));
                e.0 += 1;
                e.1 += t.ms;
            }
        }
    }
    Ok(())
}

/// Records the passes of one call of a step's plan (`wgslam_core::plan`), `kernel` being
/// the call's `kernel()`: each pass runs that kernel, a variant of it or one of its
/// sub-kernels (a key kernel's portable passes, the scan's `prefix_sum_*`), all named
/// `<kernel>...`; the check ties what the GPU records to what the plan says.
pub(super) fn record_call(
    ctx: &GpuContext,
    profiler: &mut Option<Profiler>,
    enc: &mut wgpu::CommandEncoder,
    kernel: &str,
    passes: &[Pass],
) -> Result<()> {
    debug_assert!(
        passes.iter().all(|(k, ..)| k.name.starts_with(kernel)),
        "the plan's `{kernel}` recorded {:?}",
        passes.iter().map(|(k, ..)| &k.name).collect::<Vec<_>>()
    );
    record_passes(ctx, profiler, enc, passes)
}
