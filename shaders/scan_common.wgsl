// scan_common.wgsl: structs and helpers shared by the scan-registration kernels
// (nn_brute, nn_grid, cross_covariance).
//
// Prepended to each of those kernels by `crates/gpu/src/shaders.rs` instead of common.wgsl (WGSL
// has no includes; these kernels need neither the dense-SLAM structs nor 64-bit integers),
// so this file declares no bindings and no entry point. Each struct mirrors the
// `#[repr(C)]` struct of the same name in `crates/core/src/layout/scan.rs` (checked by
// `tests/it/scan_kernels.rs`); each helper mirrors the function of the same name in
// `crates/core/src/cpu/mod.rs`.

// Mirrors `scan::layout::ScanNnParams`.
struct ScanNnParams {
    n_queries: u32,
    n_targets: u32,
    radius_sq: f32,
    n_threads: u32,
    cell_size: f32,
    table_mask: u32,
    target_begin: u32,
    target_end: u32,
}

// Mirrors `scan::layout::ScanNnResult`.
struct ScanNnResult {
    index: u32,
    dist_sq: f32,
}

// Mirrors `scan::layout::ScanCovParams`.
struct ScanCovParams {
    anchor: vec4<f32>,
    n_pairs: u32,
    n_threads: u32,
    radius_sq: f32,
    _pad0: u32,
}

// Mirrors `scan::layout::ScanCovPartial`: (count, sum|p-q|^2, sum|p|^2, sum|q|^2), sum p,
// sum q, rows of sum p q^T.
struct ScanCovPartial {
    count_sq: vec4<f32>,
    sum_p: vec4<f32>,
    sum_q: vec4<f32>,
    pq0: vec4<f32>,
    pq1: vec4<f32>,
    pq2: vec4<f32>,
}

// `ScanNnResult::index` when no target lies within the radius (mirrors
// `scan::layout::SCAN_NN_NONE`).
const SCAN_NN_NONE: u32 = 0xffffffffu;
// The largest finite f32 (Rust's `f32::MAX`): the "nothing found yet" distance.
const SCAN_F32_MAX: f32 = 3.40282347e38;

// Whether squared distance d at target i beats (best_d, best_i): equal distances go to
// the lower index. Mirrors `cpu::scan_closer`.
fn scan_closer(d: f32, i: u32, best_d: f32, best_i: u32) -> bool {
    return d < best_d || (d == best_d && i < best_i);
}

// Squared distance of the xyz parts. Mirrors `cpu::scan_dist_sq`.
fn scan_dist_sq(a: vec4<f32>, b: vec4<f32>) -> f32 {
    let d = a.xyz - b.xyz;
    return d.x * d.x + d.y * d.y + d.z * d.z;
}
