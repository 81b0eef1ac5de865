//! GPU correspondence search and reduction for scan ICP: nearest neighbours by brute force
//! (`shaders/nn_brute.wgsl`) or through a hashed voxel grid (`shaders/nn_grid.wgsl`), and
//! the inlier cross-covariance (`shaders/cross_covariance.wgsl`). Plugs into
//! [`register_with`](super::icp::register_with) through [`NearestNeighbours`].
//!
//! Per ICP iteration the host uploads the transformed sample (16 bytes a point), runs the
//! NN kernel and the reduction in one submission and reads back one 96-byte partial per
//! workgroup; the SVD stays on the host in f64. The sampling, convergence test and status
//! logic are the CPU code's. Not a KD-tree: the grid answers radius-limited queries only
//! (exactly the pairs ICP keeps), built on the CPU once per target.

use std::sync::Mutex;

use glam::DVec3;

use super::nn::NearestNeighbours;
use crate::cpu::cross_covariance::decode;
use crate::cpu::nn_grid::HashGrid;
use crate::geometry::align::CrossCovariance;
use crate::gpu::{GpuArray, GpuContext, Kernel, ParamBuffer};
use crate::layout::scan::{
    ScanCovParams, ScanCovPartial, ScanNnParams, ScanNnResult, SCAN_BRUTE_CHUNK, SCAN_NN_NONE,
};
use crate::{Error, Result};
use wgslam_core::registry::KernelId;

/// Which nearest-neighbour kernel to run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NnMethod {
    /// Every query against every target point: O(queries x targets).
    Brute,
    /// Hashed uniform grid with cells of the rejection radius: the 27 cells around a query.
    Grid,
}

/// The three scan kernels, created once per context (pipeline creation is slow).
#[derive(Debug)]
pub struct ScanKernels {
    pub nn_brute: Kernel,
    pub nn_grid: Kernel,
    pub cross_covariance: Kernel,
}

impl ScanKernels {
    /// Builds the pipelines.
    pub fn new(ctx: &GpuContext) -> Result<ScanKernels> {
        Ok(ScanKernels {
            nn_brute: Kernel::of(ctx, KernelId::nn_brute)?,
            nn_grid: Kernel::of(ctx, KernelId::nn_grid)?,
            cross_covariance: Kernel::of(ctx, KernelId::cross_covariance)?,
        })
    }
}

/// Per-call buffers (queries, results, partials), behind a mutex because
/// [`NearestNeighbours`] takes `&self`.
struct Scratch {
    queries: GpuArray<[f32; 4]>,
    results: GpuArray<ScanNnResult>,
    partials: GpuArray<ScanCovPartial>,
}

/// The most grid cells between the origin and a target point along an axis: 2^20, so the
/// f32 quotient `p / cell` keeps 3 bits below the cell (see [`GpuTarget::new`]).
pub const GRID_MAX_CELLS_FROM_ORIGIN: f32 = (1u32 << 20) as f32;

/// A target cloud resident on the GPU, answering nearest-neighbour queries (radius-limited
/// to `radius` metres) and reducing inlier pairs, with the kernel chosen by [`NnMethod`].
pub struct GpuTarget<'a> {
    ctx: &'a GpuContext,
    kernels: &'a ScanKernels,
    method: NnMethod,
    points: &'a [[f32; 3]],
    radius: f32,
    targets: GpuArray<[f32; 4]>,
    grid: Option<(HashGrid, GpuArray<[f32; 4]>, GpuArray<u32>)>,
    workgroups: u32,
    scratch: Mutex<Scratch>,
}

fn to_vec4(p: &[[f32; 3]]) -> Vec<[f32; 4]> {
    p.iter().map(|q| [q[0], q[1], q[2], 0.0]).collect()
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
        if target.is_empty() {
            return Err(Error::Argument("target cloud is empty".into()));
        }
        if !radius.is_finite() || radius <= 0.0 {
            return Err(Error::Argument(format!(
                "rejection radius must be a positive number of metres, got {radius}"
            )));
        }
        if method == NnMethod::Grid {
            // Cell indices are `floor(p / cell)` in f32 on the GPU and on the CPU that built
            // the grid: past 2^20 cells from the origin the quotient's rounding (a GPU
            // division may be 1 ulp off) moves points across many cells, and exact matches
            // were lost (577 of 1000 at a 1e-9 m radius).
            let reach = target
                .iter()
                .flat_map(|p| p.iter())
                .fold(0.0f32, |m, c| m.max(c.abs()));
            let min_radius = reach / GRID_MAX_CELLS_FROM_ORIGIN;
            if radius < min_radius {
                return Err(Error::Argument(format!(
                    "radius {radius} m is too small for the GPU grid over coordinates up to \
                     {reach} m (f32 cell indices): at least {min_radius:.3e} m, or use \
                     --nn kdtree or gpu-brute"
                )));
            }
        }
        let targets = GpuArray::from_slice(ctx, "scan targets", &to_vec4(target))?;
        let grid = match method {
            NnMethod::Brute => None,
            NnMethod::Grid => {
                let g = HashGrid::build(target, radius);
                let pts = GpuArray::from_slice(ctx, "scan grid points", &g.points)?;
                let starts = GpuArray::from_slice(ctx, "scan grid bucket starts", &g.bucket_start)?;
                Some((g, pts, starts))
            }
        };
        let workgroups = ctx.reduction_workgroups();
        let scratch = Scratch {
            queries: GpuArray::new(ctx, "scan queries", 1024)?,
            results: GpuArray::new(ctx, "scan nn results", 1024)?,
            partials: GpuArray::new(ctx, "scan partials", workgroups as usize)?,
        };
        Ok(GpuTarget {
            ctx,
            kernels,
            method,
            points: target,
            radius,
            targets,
            grid,
            workgroups,
            scratch: Mutex::new(scratch),
        })
    }

    /// Workgroups for the NN kernels: one query per thread (capped by the device limit,
    /// beyond which the grid stride takes over).
    fn nn_workgroups(&self, n_queries: usize) -> u32 {
        let max = self.ctx.limits().max_compute_workgroups_per_dimension;
        (n_queries.div_ceil(crate::layout::scan::SCAN_WORKGROUP_SIZE as usize) as u32).clamp(1, max)
    }

    fn nn_params(&self, n_queries: usize) -> ScanNnParams {
        let (n_targets, cell_size, table_mask) = match &self.grid {
            Some((g, _, _)) => (g.points.len() as u32, g.cell_size, g.table_mask),
            None => (self.points.len() as u32, 0.0, 0),
        };
        ScanNnParams {
            n_queries: n_queries as u32,
            n_targets,
            radius_sq: self.radius * self.radius,
            n_threads: self.nn_workgroups(n_queries) * crate::layout::scan::SCAN_WORKGROUP_SIZE,
            cell_size,
            table_mask,
            target_begin: 0,
            target_end: n_targets,
        }
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
        let base = self.nn_params(queries.len());
        // Brute force: one dispatch per chunk of targets (see `ScanNnParams::target_begin`).
        let ranges: Vec<(u32, u32)> = match self.method {
            NnMethod::Grid => vec![(0, base.n_targets)],
            NnMethod::Brute => (0..base.n_targets)
                .step_by(SCAN_BRUTE_CHUNK as usize)
                .map(|b| (b, (b + SCAN_BRUTE_CHUNK).min(base.n_targets)))
                .collect(),
        };
        let nn_params: Vec<ParamBuffer<ScanNnParams>> = ranges
            .iter()
            .map(|&(target_begin, target_end)| {
                let p = ScanNnParams {
                    target_begin,
                    target_end,
                    ..base
                };
                ParamBuffer::new(ctx, "ScanNnParams", &p)
            })
            .collect();
        let cov_params = cov.map(|c| ParamBuffer::new(ctx, "ScanCovParams", c));
        ctx.scoped("scan correspondences", || {
            let nn_groups: Vec<wgpu::BindGroup> = nn_params
                .iter()
                .map(|u| match (&self.method, &self.grid) {
                    (NnMethod::Grid, Some((_, pts, starts))) => self.kernels.nn_grid.bind_group(
                        ctx,
                        &[
                            ("params", u.binding()),
                            ("queries", s.queries.binding()),
                            ("grid_points", pts.binding()),
                            ("bucket_start", starts.binding()),
                            ("results", s.results.binding()),
                        ],
                    ),
                    _ => self.kernels.nn_brute.bind_group(
                        ctx,
                        &[
                            ("params", u.binding()),
                            ("queries", s.queries.binding()),
                            ("targets", self.targets.binding()),
                            ("results", s.results.binding()),
                        ],
                    ),
                })
                .collect();
            let nn_kernel = match self.method {
                NnMethod::Grid => &self.kernels.nn_grid,
                NnMethod::Brute => &self.kernels.nn_brute,
            };
            let cov_group = cov_params.as_ref().map(|p| {
                self.kernels.cross_covariance.bind_group(
                    ctx,
                    &[
                        ("params", p.binding()),
                        ("queries", s.queries.binding()),
                        ("targets", self.targets.binding()),
                        ("nn", s.results.binding()),
                        ("partials", s.partials.binding()),
                    ],
                )
            });
            let mut enc = ctx.encoder("scan correspondences");
            {
                let mut pass = enc.begin_compute_pass(&Default::default());
                // Dispatches in one pass are ordered: each chunk sees the previous results.
                for g in &nn_groups {
                    nn_kernel.dispatch(ctx, &mut pass, g, self.nn_workgroups(queries.len()))?;
                }
                if let Some(g) = &cov_group {
                    self.kernels
                        .cross_covariance
                        .dispatch(ctx, &mut pass, g, self.workgroups)?;
                }
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

    /// Raw per-workgroup partials of the inlier pairs of `queries` within `radius_sq`,
    /// points shifted by `anchor` (for parity tests).
    pub fn reduce_raw(
        &self,
        queries: &[[f32; 3]],
        anchor: [f32; 4],
        radius_sq: f32,
    ) -> Result<Vec<ScanCovPartial>> {
        let mut s = self.scratch.lock().unwrap_or_else(|p| p.into_inner());
        let cov = ScanCovParams {
            anchor,
            n_pairs: queries.len() as u32,
            n_threads: self.workgroups * crate::layout::scan::SCAN_WORKGROUP_SIZE,
            radius_sq,
            _pad0: 0,
        };
        self.run(&mut s, &to_vec4(queries), Some(&cov))?;
        s.partials.read_back(self.ctx)
    }
}

impl NearestNeighbours for GpuTarget<'_> {
    fn points(&self) -> &[[f32; 3]] {
        self.points
    }

    fn nearest(&self, queries: &[[f32; 3]], out: &mut [(u32, f32)]) -> Result<()> {
        let r = self.nearest_raw(queries)?;
        for (o, n) in out.iter_mut().zip(r) {
            // No neighbour within the radius: an infinite distance that every radius rejects.
            *o = if n.index == SCAN_NN_NONE {
                (0, f32::INFINITY)
            } else {
                (n.index, n.dist_sq)
            };
        }
        Ok(())
    }

    fn reduce_pairs(
        &self,
        queries: &[[f32; 3]],
        radius_sq: f64,
    ) -> Result<Option<CrossCovariance>> {
        if queries.is_empty() {
            return Ok(Some(CrossCovariance::default()));
        }
        let c = queries.iter().fold(DVec3::ZERO, |a, q| {
            a + DVec3::new(q[0] as f64, q[1] as f64, q[2] as f64)
        }) / queries.len() as f64;
        let anchor = [c.x as f32, c.y as f32, c.z as f32, 0.0];
        let partials = self.reduce_raw(queries, anchor, radius_sq as f32)?;
        Ok(Some(decode(&partials).unshifted(DVec3::new(
            anchor[0] as f64,
            anchor[1] as f64,
            anchor[2] as f64,
        ))))
    }
}
