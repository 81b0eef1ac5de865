//! The layout contract of the scan kernels (`shaders/nn_brute.wgsl`, `nn_grid.wgsl`,
//! `cross_covariance.wgsl`): `#[repr(C)]` Pod structs, each mirroring the WGSL struct of the
//! same name in `shaders/common.wgsl`, which those kernels are prefixed with (it points
//! back here). Only scalars and 4-vectors, padded to 16 bytes. Checked against naga's
//! layout in `tests/it/scan_kernels.rs`.
//!
//! Point arrays are `[f32; 4]` (`vec4<f32>`): xyz in metres, `w` unused except in the
//! sorted grid points, where it holds the original target index bit-cast to f32.

use bytemuck::{Pod, Zeroable};

/// Threads per workgroup of every scan kernel (`@workgroup_size(64)` in the shaders).
pub const SCAN_WORKGROUP_SIZE: u32 = 64;

/// `ScanNnResult::index` when no target point lies within the radius.
pub const SCAN_NN_NONE: u32 = u32::MAX;

/// Parameters of `nn_brute` and `nn_grid` (mirrors `ScanNnParams`).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct ScanNnParams {
    /// Queries to answer.
    pub n_queries: u32,
    /// Target points (brute force: all of them; grid: the sorted grid points).
    pub n_targets: u32,
    /// Squared rejection radius, m^2: farther nearest neighbours are reported as none.
    pub radius_sq: f32,
    /// Grid-stride step: total threads dispatched (`workgroups * 64`).
    pub n_threads: u32,
    /// Grid cell edge, metres (>= radius); unused by `nn_brute`.
    pub cell_size: f32,
    /// Hash table size minus one (a power of two minus one); unused by `nn_brute`.
    pub table_mask: u32,
    /// `nn_brute` only: this dispatch scans targets `target_begin..target_end`, continuing
    /// from the best found so far in `results` when `target_begin > 0`, and applies the
    /// radius when `target_end == n_targets`. llvmpipe (lavapipe) stops a shader
    /// invocation's loops after about 65535 iterations in total, so a large target is
    /// scanned in several dispatches of at most [`SCAN_BRUTE_CHUNK`] targets.
    pub target_begin: u32,
    /// End (exclusive) of this dispatch's target range; see `target_begin`.
    pub target_end: u32,
}

/// Most targets one `nn_brute` dispatch scans (below llvmpipe's ~65535 loop iterations per
/// invocation, which silently cut a 70k-point scan short).
pub const SCAN_BRUTE_CHUNK: u32 = 32768;

/// Nearest neighbour of one query (mirrors `ScanNnResult`).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct ScanNnResult {
    /// Index into the original target cloud, or [`SCAN_NN_NONE`].
    pub index: u32,
    /// Squared distance to it, m^2 (brute force: to the nearest point even when beyond
    /// the radius; grid: `f32::MAX` when nothing was found in the 27 cells).
    pub dist_sq: f32,
}

/// Parameters of `cross_covariance` (mirrors `ScanCovParams`).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct ScanCovParams {
    /// Subtracted from every point before accumulating (metres, xyz; w unused), so f32 sums
    /// stay small: the host passes the centroid of the queries.
    pub anchor: [f32; 4],
    /// Pairs (queries) to reduce.
    pub n_pairs: u32,
    /// Grid-stride step: total threads dispatched (`workgroups * 64`).
    pub n_threads: u32,
    /// Squared rejection radius, m^2.
    pub radius_sq: f32,
    pub _pad0: u32,
}

/// One workgroup's f32 partial sums over inlier pairs `(p, q)`, both minus the anchor
/// (mirrors `ScanCovPartial`).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct ScanCovPartial {
    /// `(count, sum |p - q|^2, sum |p|^2, sum |q|^2)`.
    pub count_sq: [f32; 4],
    /// `sum p` (xyz; w 0).
    pub sum_p: [f32; 4],
    /// `sum q` (xyz; w 0).
    pub sum_q: [f32; 4],
    /// Row 0 of `sum p q^T`: `sum p_x q` (w 0).
    pub pq0: [f32; 4],
    /// Row 1: `sum p_y q` (w 0).
    pub pq1: [f32; 4],
    /// Row 2: `sum p_z q` (w 0).
    pub pq2: [f32; 4],
}

impl ScanCovPartial {
    /// The three rows of `sum p q^T`.
    pub fn pq(&self) -> [[f32; 4]; 3] {
        [self.pq0, self.pq1, self.pq2]
    }
}
