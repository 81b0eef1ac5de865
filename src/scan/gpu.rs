//! GPU correspondence search and reduction for scan ICP: nearest neighbours by brute force
//! (`shaders/nn_brute.wgsl`) or through a hashed voxel grid (`shaders/nn_grid.wgsl`), and
//! the inlier cross-covariance (`shaders/cross_covariance.wgsl`). Plugs into
//! [`register_with`](super::icp::register_with) through
//! [`NearestNeighbours`](super::NearestNeighbours).
//!
//! The kernels run in the order of the correspondence plan (`plan::scan_correspondences`),
//! each bound and dispatched by its registry row (`RowKernels`) over this target's pool
//! of named buffers (see `kernel_target.rs`, whose [`TwinTarget`](super::TwinTarget) runs
//! the same plan through the twins on the CPU).
//!
//! Per ICP iteration the host uploads the transformed sample (16 bytes a point), runs the
//! NN kernel and the reduction in one submission and reads back one 96-byte partial per
//! workgroup; the SVD stays on the host in f64. The sampling, convergence test and status
//! logic are the CPU code's. Not a KD-tree: the grid answers radius-limited queries only
//! (exactly the pairs ICP keeps), built on the CPU once per target.

use std::sync::Mutex;

use super::kernel_target::{kernel_nearest_neighbours, to_vec4, KernelTarget};
use crate::gpu::{GpuArray, GpuContext, ParamBuffer, RowKernels};
use crate::layout::scan::{ScanCovParams, ScanCovPartial, ScanNnResult, SCAN_WORKGROUP_SIZE};
use crate::Result;
use wgslam_core::plan::{self, ScanCall};

pub use super::kernel_target::{NnMethod, GRID_MAX_CELLS_FROM_ORIGIN};

/// The three scan kernels, built once per context (pipeline creation is slow) from their
/// registry rows: every kernel a correspondence plan may call.
#[derive(Debug)]
pub struct ScanKernels {
    rows: RowKernels,
}

impl ScanKernels {
    /// Builds the pipelines.
    pub fn new(ctx: &GpuContext) -> Result<ScanKernels> {
        // Both searches' plans with the reduction: every kernel of the rows.
        let mut every = plan::scan_correspondences(true, 1, true);
        every.extend(plan::scan_correspondences(false, 1, false));
        Ok(ScanKernels {
            rows: RowKernels::of_plan(ctx, &every)?,
        })
    }
}

/// Per-call buffers (queries, results, partials), behind a mutex because
/// [`NearestNeighbours`](super::NearestNeighbours) takes `&self`.
struct Scratch {
    queries: GpuArray<[f32; 4]>,
    results: GpuArray<ScanNnResult>,
    partials: GpuArray<ScanCovPartial>,
}

/// A target cloud resident on the GPU, answering nearest-neighbour queries (radius-limited
/// to its radius, metres) and reducing inlier pairs, with the kernel chosen by [`NnMethod`].
pub struct GpuTarget<'a> {
    ctx: &'a GpuContext,
    kernels: &'a ScanKernels,
    target: KernelTarget<'a>,
    targets: GpuArray<[f32; 4]>,
    /// The grid's points and bucket starts, for [`NnMethod::Grid`].
    grid: Option<(GpuArray<[f32; 4]>, GpuArray<u32>)>,
    workgroups: u32,
    scratch: Mutex<Scratch>,
}

impl<'a> GpuTarget<'a> {
    /// Uploads `target` (metres) and, for [`NnMethod::Grid`], builds and uploads its grid
    /// with cells of `radius` metres. Queries farther than `radius` from every target point
    /// get no neighbour; use the largest ICP radius.
    pub fn new(
        ctx: &'a GpuContext,
        kernels: &'a ScanKernels,
        target: &'a [[f32; 3]],
        radius: f32,
        method: NnMethod,
    ) -> Result<GpuTarget<'a>> {
        let target = KernelTarget::new(target, radius, method)?;
        let targets = GpuArray::from_slice(ctx, "scan targets", &target.targets)?;
        let grid = match &target.grid {
            None => None,
            Some(g) => {
                let pts = GpuArray::from_slice(ctx, "scan grid points", &g.points)?;
                let starts = GpuArray::from_slice(ctx, "scan grid bucket starts", &g.bucket_start)?;
                Some((pts, starts))
            }
        };
        let workgroups = kernels.rows.workgroups(ctx, ScanCall::CrossCovariance, 0);
        let scratch = Scratch {
            queries: GpuArray::new(ctx, "scan queries", 1024)?,
            results: GpuArray::new(ctx, "scan nn results", 1024)?,
            partials: GpuArray::new(ctx, "scan partials", workgroups as usize)?,
        };
        Ok(GpuTarget {
            ctx,
            kernels,
            target,
            targets,
            grid,
            workgroups,
            scratch: Mutex::new(scratch),
        })
    }

    /// Uploads `queries`, records the NN kernel (and, with `cov`, the reduction) and
    /// submits; returns with the work queued.
    fn run(
        &self,
        s: &mut Scratch,
        queries: &[[f32; 4]],
        cov: Option<&ScanCovParams>,
    ) -> Result<()> {
        let ctx = self.ctx;
        s.queries.upload(ctx, queries)?;
        if s.results.capacity() < queries.len() {
            s.results = GpuArray::new(ctx, "scan nn results", queries.len())?;
        }
        s.results.set_len(queries.len());
        let (rows, n) = (&self.kernels.rows, queries.len());
        let plan = self.target.plan(cov.is_some());
        // Each call's `neighbours` (one per range of targets), made before any is bound.
        let nn_params: Vec<Option<ParamBuffer<_>>> = plan
            .iter()
            .map(|&call| {
                let n_threads = rows.workgroups(ctx, call, n) * SCAN_WORKGROUP_SIZE;
                let p = self.target.nn_params(call, n, n_threads)?;
                Some(ParamBuffer::new(ctx, "ScanNnParams", &p))
            })
            .collect();
        let cov_params = cov.map(|c| ParamBuffer::new(ctx, "ScanCovParams", c));
        ctx.scoped("scan correspondences", || {
            let mut enc = ctx.encoder("scan correspondences");
            // The calls in order: each range of targets sees the previous one's results.
            for (&call, nn) in plan.iter().zip(&nn_params) {
                let mut pool = vec![
                    ("queries", s.queries.binding()),
                    ("targets", self.targets.binding()),
                    ("results", s.results.binding()),
                    ("nn", s.results.binding()),
                    ("partials", s.partials.binding()),
                ];
                if let Some((pts, starts)) = &self.grid {
                    pool.extend([
                        ("grid_points", pts.binding()),
                        ("bucket_start", starts.binding()),
                    ]);
                }
                pool.extend(nn.as_ref().map(|p| ("neighbours", p.binding())));
                pool.extend(cov_params.as_ref().map(|p| ("covariance", p.binding())));
                rows.record(ctx, &mut enc, call, &pool, n)?;
            }
            ctx.submit(enc);
            Ok(())
        })?;
        s.partials.set_len(self.workgroups as usize);
        Ok(())
    }

    /// Raw kernel output for `queries` (metres): one [`ScanNnResult`] per query, index into
    /// the target cloud or `SCAN_NN_NONE` beyond the radius (for parity tests and benches).
    pub fn nearest_raw(&self, queries: &[[f32; 3]]) -> Result<Vec<ScanNnResult>> {
        let mut s = self.scratch.lock().unwrap_or_else(|p| p.into_inner());
        self.run(&mut s, &to_vec4(queries), None)?;
        s.results.read_back(self.ctx)
    }

    /// Raw per-workgroup partials of the pairs of `queries` under `cov` (see `reduce_raw`).
    fn partials(&self, queries: &[[f32; 3]], cov: &ScanCovParams) -> Result<Vec<ScanCovPartial>> {
        let mut s = self.scratch.lock().unwrap_or_else(|p| p.into_inner());
        self.run(&mut s, &to_vec4(queries), Some(cov))?;
        s.partials.read_back(self.ctx)
    }
}

kernel_nearest_neighbours!(GpuTarget);
