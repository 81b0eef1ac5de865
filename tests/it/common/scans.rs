//! The bundled LiDAR pair (`assets/lidar/fast_gicp_pair`) and the inputs of the
//! nearest-neighbour kernels (`nn_brute`, `nn_grid`) and their CPU twins, for the scan tests.

use std::path::PathBuf;

use glam::DMat4;
use wgslam::cpu::nn_grid::HashGrid;
use wgslam::layout::scan::{ScanNnParams, ScanNnResult};
use wgslam::scan::{read_matrix4, read_pcd};

/// The fast_gicp pair: `251370668.pcd`, `251371071.pcd` and `relative.txt`.
pub fn fast_gicp_dir() -> PathBuf {
    super::asset("lidar/fast_gicp_pair/data")
}

/// `(source, target, relative)`: the later scan (251371071), the earlier one (251370668),
/// and relative.txt, the reference `T_source_to_target` (fast_gicp's GICP, not ground truth).
pub fn fast_gicp_pair() -> (Vec<[f32; 3]>, Vec<[f32; 3]>, DMat4) {
    let d = fast_gicp_dir();
    (
        read_pcd(&d.join("251371071.pcd")).unwrap().points,
        read_pcd(&d.join("251370668.pcd")).unwrap().points,
        read_matrix4(&d.join("relative.txt")).unwrap(),
    )
}

/// Points as the kernels store them: `vec4` with w = 0.
pub fn v4(p: &[[f32; 3]]) -> Vec<[f32; 4]> {
    p.iter().map(|q| [q[0], q[1], q[2], 0.0]).collect()
}

/// Parameters of a nearest-neighbour search of `n_queries` points among all of `target`
/// within `radius` (metres), 64 threads, on `grid` (built over `target` with that radius).
pub fn nn_params(
    n_queries: usize,
    target: &[[f32; 3]],
    radius: f32,
    grid: &HashGrid,
) -> ScanNnParams {
    ScanNnParams {
        n_queries: n_queries as u32,
        n_targets: target.len() as u32,
        radius_sq: radius * radius,
        n_threads: 64,
        cell_size: grid.cell_size,
        table_mask: grid.table_mask,
        target_begin: 0,
        target_end: target.len() as u32,
    }
}

/// `n` zeroed results for a twin to fill.
pub fn zeroed_results(n: usize) -> Vec<ScanNnResult> {
    vec![
        ScanNnResult {
            index: 0,
            dist_sq: 0.0
        };
        n
    ]
}
