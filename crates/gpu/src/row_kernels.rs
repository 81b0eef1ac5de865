//! The GPU engine for the registry's rows that their callers bind
//! (`wgslam_core::registry::Shape::bound_by_caller`: the renderer's and scan
//! registration's kernels, outside the dense pipeline, over buffers of their own): each
//! kernel built from its row by its typed id, each plan call bound over the caller's pool
//! of named resources (its `params` the pool's resource of the name its row gives) and
//! recorded with the passes its [`Shape`] gives, through the engine's `record_call`. The
//! CPU engine's counterpart is `wgslam_core::cpu_backend::run_call`; both walk the same
//! plans (`wgslam_core::plan::render`, `wgslam_core::plan::scan_correspondences`).
//!
//! Not here: the buffers (the caller's), and the order of the calls (the plan's).

use super::context::GpuContext;
use super::kernel::{Kernel, KeyKernel};
use super::recording::{record_call, Pass};
use crate::Result;
use wgslam_core::plan::Call;
use wgslam_core::registry::{KernelId, Shape};

/// The kernels of the rows a plan's calls run, built once (pipeline creation is slow).
#[derive(Debug)]
pub struct RowKernels {
    /// Per kernel its passes: one, or a key kernel's in order (the first's layout makes
    /// the bind group).
    rows: Vec<(KernelId, Vec<Kernel>)>,
}

impl RowKernels {
    /// The kernels of every call of `plan` (a clear has none): a key kernel's as
    /// `KeyKernel` builds it (its portable variant's passes on a device without 64-bit
    /// atomics).
    pub fn of_plan<C: Call>(ctx: &GpuContext, plan: &[C]) -> Result<RowKernels> {
        let mut rows: Vec<(KernelId, Vec<Kernel>)> = Vec::new();
        for id in plan.iter().filter_map(|call| call.kernel()) {
            if rows.iter().any(|(k, _)| *k == id) {
                continue;
            }
            let passes = match id.is_key() {
                true => KeyKernel::of(ctx, id)?.passes,
                false => vec![Kernel::of(ctx, id)?],
            };
            rows.push((id, passes));
        }
        Ok(RowKernels { rows })
    }

    /// `call`'s passes, [`Shape`] and uniform. Panics (internal contracts) on a call with
    /// no kernel, or one not built here, or whose row its caller does not bind.
    fn row(&self, call: impl Call) -> (&[Kernel], Shape, &'static str) {
        let found = call.kernel().and_then(|id| {
            let (_, passes) = self.rows.iter().find(|(k, _)| *k == id)?;
            Some((&passes[..], id.shape()?, id.uniform()?))
        });
        let Some((passes, shape, uniform)) = found else {
            panic!("`{}` has no kernel among these rows", call.name())
        };
        assert!(
            shape.bound_by_caller(),
            "`{}` is a {shape:?} row: the dense pipeline's engine binds it",
            call.name()
        );
        (passes, shape, uniform)
    }

    /// The workgroups of `call`'s pass over `points` points, as its row's [`Shape`] says:
    /// one thread per point, at least one workgroup and at most the device's per-dimension
    /// limit (`PerPoint`), or the adapter's reduction workgroups (`PerPartial`). A kernel
    /// whose params give its thread count (a grid-stride loop's stride) is given this
    /// times its workgroup size.
    pub fn workgroups(&self, ctx: &GpuContext, call: impl Call, points: usize) -> u32 {
        let (passes, shape, _) = self.row(call);
        match shape {
            Shape::PerPartial => ctx.reduction_workgroups(),
            _ => {
                let max = ctx.limits().max_compute_workgroups_per_dimension;
                passes[0].workgroups_for(points).clamp(1, max)
            }
        }
    }

    /// Records `call`'s passes over `points` points ([`RowKernels::workgroups`]) into
    /// `enc`, bound over `pool`: each binding the pool's resource of its WGSL name, `params`
    /// the one of the name the row gives (a pool may hold other kernels' resources and
    /// uniforms too). A key kernel's passes run in turn (its first alone where the call
    /// says so). Panics as [`Kernel::bind_group_from`] does on a binding the pool lacks.
    pub fn record(
        &self,
        ctx: &GpuContext,
        enc: &mut wgpu::CommandEncoder,
        call: impl Call,
        pool: &[(&str, wgpu::BindingResource<'_>)],
        points: usize,
    ) -> Result<()> {
        let (passes, _, uniform) = self.row(call);
        let params = pool.iter().find(|(name, _)| *name == uniform);
        let Some((_, params)) = params else {
            panic!("`{}`: no uniform `{uniform}` in the pool", call.name())
        };
        let mut bound = vec![("params", params.clone())];
        bound.extend(pool.iter().cloned());
        let group = passes[0].bind_group_from(ctx, &bound);
        let wg = self.workgroups(ctx, call, points);
        let passes = match call.every_key_pass() {
            true => passes,
            false => &passes[..1],
        };
        let passes: Vec<Pass> = passes.iter().map(|k| (k, &group, [wg, 1])).collect();
        record_call(ctx, &mut None, enc, call.name(), &passes)
    }
}
