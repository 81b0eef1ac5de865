//! CPU twin of `shaders/nn_grid.wgsl` (radius-limited nearest neighbour through a hashed
//! uniform voxel grid), and the grid build that both twins use (a CPU step: counting sort
//! of the target points by hash bucket).
//!
//! With a cell edge at least the radius, every target point within the radius of a query
//! lies in the 3x3x3 cells around the query's cell, so the answer equals brute force
//! within the radius (same tie rule). Hash collisions only add candidates.

use super::binding::twin;
use super::{scan_closer, scan_dist_sq};
use crate::layout::scan::{ScanNnParams, ScanNnResult, SCAN_NN_NONE};

/// Cell coordinates of a point. Mirrors `scan_cell_of` in nn_grid.wgsl.
#[inline]
pub fn scan_cell_of(p: [f32; 4], cell_size: f32) -> [i32; 3] {
    [
        (p[0] / cell_size).floor() as i32,
        (p[1] / cell_size).floor() as i32,
        (p[2] / cell_size).floor() as i32,
    ]
}

/// Hash bucket of a cell (three large primes, xor, masked). Mirrors `scan_bucket`.
#[inline]
pub fn scan_bucket(c: [i32; 3], table_mask: u32) -> u32 {
    let h = (c[0] as u32).wrapping_mul(73_856_093)
        ^ (c[1] as u32).wrapping_mul(19_349_663)
        ^ (c[2] as u32).wrapping_mul(83_492_791);
    h & table_mask
}

/// Relative margin added to the radius to get the cell edge, so that rounding in
/// `floor(p / cell)` (which the GPU may compute with a 1-ulp division) never hides a point
/// that is within the radius.
pub const CELL_MARGIN: f32 = 1e-3;

/// A hashed uniform grid over a target cloud, ready for upload.
#[derive(Debug, Clone, PartialEq)]
pub struct HashGrid {
    /// Cell edge, metres.
    pub cell_size: f32,
    /// Bucket count minus one (buckets are a power of two).
    pub table_mask: u32,
    /// Target points sorted by bucket: xyz metres, `w` = original index as f32 bits.
    pub points: Vec<[f32; 4]>,
    /// `bucket_start[b]..bucket_start[b + 1]` are bucket `b`'s points (length buckets + 1).
    pub bucket_start: Vec<u32>,
}

impl HashGrid {
    /// Builds the grid for radius-limited queries up to `radius` metres (cell edge
    /// `radius * (1 + CELL_MARGIN)`), with at least twice as many buckets as points.
    pub fn build(targets: &[[f32; 3]], radius: f32) -> HashGrid {
        let cell_size = radius * (1.0 + CELL_MARGIN);
        let buckets = (2 * targets.len()).next_power_of_two().max(1);
        let table_mask = (buckets - 1) as u32;
        let bucket_of: Vec<u32> = targets
            .iter()
            .map(|p| scan_bucket(scan_cell_of([p[0], p[1], p[2], 0.0], cell_size), table_mask))
            .collect();
        let mut bucket_start = vec![0u32; buckets + 1];
        for &b in &bucket_of {
            bucket_start[b as usize + 1] += 1;
        }
        for b in 0..buckets {
            bucket_start[b + 1] += bucket_start[b];
        }
        let mut fill = bucket_start.clone();
        let mut points = vec![[0f32; 4]; targets.len()];
        for (i, (p, &b)) in targets.iter().zip(&bucket_of).enumerate() {
            let slot = &mut fill[b as usize];
            points[*slot as usize] = [p[0], p[1], p[2], f32::from_bits(i as u32)];
            *slot += 1;
        }
        HashGrid {
            cell_size,
            table_mask,
            points,
            bucket_start,
        }
    }
}

twin! {
    /// For every query, the nearest grid point within `radius_sq` (searching the 27 cells
    /// around the query's cell), as an index into the ORIGINAL target cloud; `SCAN_NN_NONE`
    /// with `dist_sq` = the best squared distance seen (`f32::MAX` if none) otherwise.
    ///
    /// Arguments: the shader's bindings in `@binding` order, named as there; see the
    /// declarations in `shaders/nn_grid.wgsl` for shapes, units and frames.
    pub fn nn_grid(
        params: &ScanNnParams,
        queries: &[[f32; 4]],
        grid_points: &[[f32; 4]],
        bucket_start: &[u32],
        results: &mut [ScanNnResult],
    ) {
        for q in 0..params.n_queries as usize {
            let p = queries[q];
            let c = scan_cell_of(p, params.cell_size);
            let mut best_d = f32::MAX;
            let mut best_i = SCAN_NN_NONE;
            for dz in -1..=1 {
                for dy in -1..=1 {
                    for dx in -1..=1 {
                        let cell = [c[0] + dx, c[1] + dy, c[2] + dz];
                        let b = scan_bucket(cell, params.table_mask) as usize;
                        let bucket = bucket_start[b] as usize..bucket_start[b + 1] as usize;
                        for t in &grid_points[bucket] {
                            let d2 = scan_dist_sq(*t, p);
                            let i = t[3].to_bits();
                            if scan_closer(d2, i, best_d, best_i) {
                                best_d = d2;
                                best_i = i;
                            }
                        }
                    }
                }
            }
            if best_d > params.radius_sq {
                best_i = SCAN_NN_NONE;
            }
            results[q] = ScanNnResult {
                index: best_i,
                dist_sq: best_d,
            };
        }
    }
}
