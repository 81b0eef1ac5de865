//! A target cloud as scan registration's kernels bind it, shared by both engines: the
//! points (metres) as `vec4` rows, the hashed grid for [`NnMethod::Grid`], the plan of a
//! correspondence step (`plan::scan_correspondences`) and each call's parameters. The GPU
//! target (`gpu.rs`) records that plan through `wgslam_gpu::row_kernels`; [`TwinTarget`]
//! runs it on the CPU through the twins' engine (`cpu_backend::run_call`), over pools of the
//! same names: `queries`, `targets`, `grid_points`, `bucket_start`, `results` (read as
//! `nn` by the reduction), `partials`, and the uniforms `neighbours` and `covariance` the
//! rows name.

use bytemuck::Zeroable;
use glam::DVec3;

use crate::cpu::binding::Pool;
use crate::cpu::{decode_scan_partials, HashGrid};
use crate::geometry::align::CrossCovariance;
use crate::layout::scan::{
    ScanCovParams, ScanCovPartial, ScanNnParams, ScanNnResult, SCAN_NN_NONE, SCAN_WORKGROUP_SIZE,
};
use crate::{Error, Result};
use wgslam_core::cpu_backend::run_call;
use wgslam_core::plan::{self, ScanCall};

/// Which nearest-neighbour kernel to run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NnMethod {
    /// Every query against every target point: O(queries x targets).
    Brute,
    /// Hashed uniform grid with cells of the rejection radius: the 27 cells around a query.
    Grid,
}

/// The most grid cells between the origin and a target point along an axis: 2^20, so the
/// f32 quotient `p / cell` keeps 3 bits below the cell (see `KernelTarget::new`).
pub const GRID_MAX_CELLS_FROM_ORIGIN: f32 = (1u32 << 20) as f32;

/// `[x, y, z, 0]` rows of `p` (metres), as the kernels read points.
pub(crate) fn to_vec4(p: &[[f32; 3]]) -> Vec<[f32; 4]> {
    p.iter().map(|q| [q[0], q[1], q[2], 0.0]).collect()
}

/// A target cloud (metres, target frame) as the scan kernels bind it.
pub(crate) struct KernelTarget<'a> {
    /// The cloud as given: indices of the results point here.
    pub points: &'a [[f32; 3]],
    /// The rejection radius, metres: queries farther from every target get no neighbour.
    pub radius: f32,
    /// The cloud as `vec4` rows (`targets`).
    pub targets: Vec<[f32; 4]>,
    /// For [`NnMethod::Grid`], the hashed grid of cells of `radius` (`grid_points`,
    /// `bucket_start`).
    pub grid: Option<HashGrid>,
}

impl<'a> KernelTarget<'a> {
    /// `target` (metres) with, for [`NnMethod::Grid`], its grid of cells of `radius`
    /// metres. [`Error::Argument`] on an empty target, a radius that is not a positive
    /// number, or one too small for the grid's f32 cell indices.
    pub fn new(target: &'a [[f32; 3]], radius: f32, method: NnMethod) -> Result<Self> {
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
        Ok(KernelTarget {
            points: target,
            radius,
            targets: to_vec4(target),
            grid: (method == NnMethod::Grid).then(|| HashGrid::build(target, radius)),
        })
    }

    /// The target points the nearest-neighbour kernel walks: the grid's, else the cloud's.
    fn n_targets(&self) -> u32 {
        match &self.grid {
            Some(g) => g.points.len() as u32,
            None => self.points.len() as u32,
        }
    }

    /// The plan of one correspondence step: the nearest neighbours, and with `reduce` the
    /// inlier pairs' partials.
    pub fn plan(&self, reduce: bool) -> Vec<ScanCall> {
        plan::scan_correspondences(self.grid.is_some(), self.n_targets(), reduce)
    }

    /// The `neighbours` uniform of a nearest-neighbour `call` over `n_queries` queries,
    /// dispatched as `n_threads` threads (the grid-stride loop's stride); `None` for the
    /// reduction.
    pub fn nn_params(
        &self,
        call: ScanCall,
        n_queries: usize,
        n_threads: u32,
    ) -> Option<ScanNnParams> {
        let (cell_size, table_mask) = match &self.grid {
            Some(g) => (g.cell_size, g.table_mask),
            None => (0.0, 0),
        };
        let n_targets = self.n_targets();
        let (target_begin, target_end) = match call {
            ScanCall::NnBrute { begin, end } => (begin, end),
            ScanCall::NnGrid => (0, n_targets),
            ScanCall::CrossCovariance => return None,
        };
        Some(ScanNnParams {
            n_queries: n_queries as u32,
            n_targets,
            radius_sq: self.radius * self.radius,
            n_threads,
            cell_size,
            table_mask,
            target_begin,
            target_end,
        })
    }
}

/// The `covariance` uniform: the inlier pairs (within `radius_sq`, m^2) of `n_pairs`
/// queries, points shifted by `anchor`, reduced by `workgroups` workgroups.
pub(crate) fn cov_params(
    anchor: [f32; 4],
    n_pairs: usize,
    radius_sq: f32,
    workgroups: u32,
) -> ScanCovParams {
    ScanCovParams {
        anchor,
        n_pairs: n_pairs as u32,
        n_threads: workgroups * SCAN_WORKGROUP_SIZE,
        radius_sq,
        _pad0: 0,
    }
}

/// [`NearestNeighbours::nearest`](super::NearestNeighbours::nearest) from a kernel's
/// results: no neighbour within the radius is an infinite distance that every radius
/// rejects.
pub(crate) fn nearest_from(results: &[ScanNnResult], out: &mut [(u32, f32)]) {
    for (o, n) in out.iter_mut().zip(results) {
        *o = match n.index {
            SCAN_NN_NONE => (0, f32::INFINITY),
            index => (index, n.dist_sq),
        };
    }
}

/// [`NearestNeighbours::reduce_pairs`](super::NearestNeighbours::reduce_pairs) through
/// `reduce_raw` (the partials of the pairs of `queries` within `radius_sq`, shifted by an
/// anchor): the anchor is the queries' mean, so the f32 sums stay small; the partials
/// summed in f64 and shifted back.
pub(crate) fn reduce_with(
    queries: &[[f32; 3]],
    radius_sq: f64,
    reduce_raw: impl FnOnce([f32; 4], f32) -> Result<Vec<ScanCovPartial>>,
) -> Result<Option<CrossCovariance>> {
    if queries.is_empty() {
        return Ok(Some(CrossCovariance::default()));
    }
    let c = queries.iter().fold(DVec3::ZERO, |a, q| {
        a + DVec3::new(q[0] as f64, q[1] as f64, q[2] as f64)
    }) / queries.len() as f64;
    let anchor = [c.x as f32, c.y as f32, c.z as f32, 0.0];
    let partials = reduce_raw(anchor, radius_sq as f32)?;
    Ok(Some(decode_scan_partials(&partials).unshifted(DVec3::new(
        anchor[0] as f64,
        anchor[1] as f64,
        anchor[2] as f64,
    ))))
}

/// A target answering through the scan kernels' twins, run by the CPU engine in the
/// plan's order over pools named as the GPU's: the GPU target's reference, its results
/// those the twins give for the same calls.
pub struct TwinTarget<'a> {
    target: KernelTarget<'a>,
    /// The reduction's workgroups: one partial each.
    workgroups: u32,
}

impl<'a> TwinTarget<'a> {
    /// `target` (metres) as [`KernelTarget::new`] takes it, reducing into `workgroups`
    /// partials (the GPU's are the adapter's reduction workgroups).
    pub fn new(
        target: &'a [[f32; 3]],
        radius: f32,
        method: NnMethod,
        workgroups: u32,
    ) -> Result<TwinTarget<'a>> {
        Ok(TwinTarget {
            target: KernelTarget::new(target, radius, method)?,
            workgroups: workgroups.max(1),
        })
    }

    /// Runs the plan over `queries` (with `cov`, the reduction too): each query's result
    /// and the partials.
    fn run(
        &self,
        queries: &[[f32; 4]],
        cov: Option<&ScanCovParams>,
    ) -> (Vec<ScanNnResult>, Vec<ScanCovPartial>) {
        let n = queries.len();
        let mut results = vec![ScanNnResult::zeroed(); n];
        let mut partials = vec![ScanCovPartial::zeroed(); self.workgroups as usize];
        // One thread per query, as the GPU's `PerPoint` pass with no device limit.
        let workgroups = n.div_ceil(SCAN_WORKGROUP_SIZE as usize).max(1) as u32;
        for call in self.target.plan(cov.is_some()) {
            let nn = (self.target).nn_params(call, n, workgroups * SCAN_WORKGROUP_SIZE);
            let mut pool = Pool::new();
            if let Some(nn) = &nn {
                pool.uniform("neighbours", nn);
            }
            if let Some(cov) = cov {
                pool.uniform("covariance", cov);
            }
            pool.read("queries", queries);
            pool.read("targets", &self.target.targets);
            if let Some(g) = &self.target.grid {
                pool.read("grid_points", &g.points);
                pool.read("bucket_start", &g.bucket_start);
            }
            let results = pool.write("results", &mut results);
            pool.alias("nn", results);
            pool.write("partials", &mut partials);
            run_call(call, pool);
        }
        (results, partials)
    }

    /// The twins' results for `queries` (metres), as the GPU target's `nearest_raw` (which
    /// may fail where this does not).
    pub fn nearest_raw(&self, queries: &[[f32; 3]]) -> Result<Vec<ScanNnResult>> {
        Ok(self.run(&to_vec4(queries), None).0)
    }

    /// The twins' partials of the pairs of `queries` under `cov` (see `reduce_raw`).
    fn partials(&self, queries: &[[f32; 3]], cov: &ScanCovParams) -> Result<Vec<ScanCovPartial>> {
        Ok(self.run(&to_vec4(queries), Some(cov)).1)
    }
}

/// For a target that holds its [`KernelTarget`] as `target`, its reduction's workgroups
/// as `workgroups`, and answers through its kernels' `nearest_raw` and `partials` (the GPU
/// target, and [`TwinTarget`]: the same answers from either engine): its `reduce_raw` and
/// [`NearestNeighbours`](super::NearestNeighbours).
macro_rules! kernel_nearest_neighbours {
    ($target:ident) => {
        impl $target<'_> {
            /// Raw per-workgroup partials of the inlier pairs of `queries` (metres) within
            /// `radius_sq` (m^2), points shifted by `anchor` (for parity tests).
            pub fn reduce_raw(
                &self,
                queries: &[[f32; 3]],
                anchor: [f32; 4],
                radius_sq: f32,
            ) -> $crate::Result<Vec<$crate::layout::scan::ScanCovPartial>> {
                let n = queries.len();
                let cov =
                    $crate::scan::kernel_target::cov_params(anchor, n, radius_sq, self.workgroups);
                self.partials(queries, &cov)
            }
        }

        impl $crate::scan::NearestNeighbours for $target<'_> {
            fn points(&self) -> &[[f32; 3]] {
                self.target.points
            }

            fn nearest(&self, queries: &[[f32; 3]], out: &mut [(u32, f32)]) -> $crate::Result<()> {
                $crate::scan::kernel_target::nearest_from(&self.nearest_raw(queries)?, out);
                Ok(())
            }

            fn reduce_pairs(
                &self,
                queries: &[[f32; 3]],
                radius_sq: f64,
            ) -> $crate::Result<Option<$crate::geometry::align::CrossCovariance>> {
                $crate::scan::kernel_target::reduce_with(queries, radius_sq, |anchor, radius_sq| {
                    self.reduce_raw(queries, anchor, radius_sq)
                })
            }
        }
    };
}
// The GPU target's (`gpu.rs`: not on wasm, where scans are not registered).
#[cfg_attr(target_arch = "wasm32", allow(unused_imports))]
pub(crate) use kernel_nearest_neighbours;

kernel_nearest_neighbours!(TwinTarget);
