//! The WGSL sources, embedded at build time: two shared prefixes (`shaders/common.wgsl`,
//! `shaders/scan_common.wgsl`) plus one file per kernel.
//!
//! WGSL has no includes, so a kernel's source is its prefix followed by
//! `shaders/<kernel>.wgsl`: `scan_common.wgsl` for the scan kernels ([`SCAN_KERNELS`]),
//! `common.wgsl` for every other. [`source`] builds it; the runtime (pipeline creation)
//! and the naga tests (`tests/it/shaders.rs`, `tests/it/bindings.rs`) both use it, so what is
//! validated is what runs. This module does not compile anything; see [`super::kernel`].

/// `shaders/common.wgsl`: the structs of `src/layout.rs` and the helpers of `src/cpu/mod.rs`
/// (dense SLAM and renders).
pub const COMMON: &str = include_str!("../../shaders/common.wgsl");

/// `shaders/scan_common.wgsl`: the structs of `src/scan/layout.rs` and the scan helpers of
/// `src/cpu/mod.rs`.
pub const SCAN_COMMON: &str = include_str!("../../shaders/scan_common.wgsl");

/// The prefix files as `(name, text)` (not kernels: no entry point, no bindings).
pub const PREFIXES: &[(&str, &str)] = &[("common", COMMON), ("scan_common", SCAN_COMMON)];

/// Kernels prefixed with `scan_common.wgsl` instead of `common.wgsl`.
pub const SCAN_KERNELS: &[&str] = &["nn_brute", "nn_grid", "cross_covariance"];

/// The kernels that need 64-bit integers and 64-bit `atomicMax` (`SHADER_INT64` and
/// `SHADER_INT64_ATOMIC_MIN_MAX`), each with its portable twin kernel: `(kernel, portable)`.
/// The portable kernel keeps the same 64-bit key as two u32 words, (low = index, high =
/// depth word), in two dispatches over the same bind groups (its `override KEY_PASS`: 0
/// then 1), and decides the same winner bit for bit. Every other kernel, portable ones
/// included, validates without 64-bit integers (`tests/it/shaders.rs`).
pub const PORTABLE_KERNELS: &[(&str, &str)] = &[
    ("project_model", "project_model_portable"),
    ("fuse_select", "fuse_select_portable"),
    ("fuse_add", "fuse_add_portable"),
    ("render_splat", "render_splat_portable"),
];

/// The name of the `override` constant that picks a portable kernel's pass (0: the high
/// word, 1: the index word).
pub const KEY_PASS: &str = "KEY_PASS";

/// True for the kernels that need 64-bit integers (the first of each [`PORTABLE_KERNELS`]).
pub fn needs_int64(kernel_name: &str) -> bool {
    PORTABLE_KERNELS.iter().any(|(k, _)| *k == kernel_name)
}

/// Every kernel as `(name, text of shaders/<name>.wgsl)`. Keep in sync with the directory:
/// `tests/it/shaders.rs` fails when a `.wgsl` file is missing here.
pub const KERNELS: &[(&str, &str)] = &[
    (
        "depth_to_vertex",
        include_str!("../../shaders/depth_to_vertex.wgsl"),
    ),
    (
        "block_bounds",
        include_str!("../../shaders/block_bounds.wgsl"),
    ),
    (
        "bilateral_filter",
        include_str!("../../shaders/bilateral_filter.wgsl"),
    ),
    (
        "vertex_to_normal",
        include_str!("../../shaders/vertex_to_normal.wgsl"),
    ),
    (
        "project_model",
        include_str!("../../shaders/project_model.wgsl"),
    ),
    (
        "predict_model",
        include_str!("../../shaders/predict_model.wgsl"),
    ),
    (
        "pyramid_depth",
        include_str!("../../shaders/pyramid_depth.wgsl"),
    ),
    (
        "pyramid_model",
        include_str!("../../shaders/pyramid_model.wgsl"),
    ),
    (
        "fern_encode",
        include_str!("../../shaders/fern_encode.wgsl"),
    ),
    (
        "keypoint_detect",
        include_str!("../../shaders/keypoint_detect.wgsl"),
    ),
    (
        "keypoint_describe",
        include_str!("../../shaders/keypoint_describe.wgsl"),
    ),
    (
        "icp_candidates",
        include_str!("../../shaders/icp_candidates.wgsl"),
    ),
    ("icp_reduce", include_str!("../../shaders/icp_reduce.wgsl")),
    (
        "icp_reduce_final",
        include_str!("../../shaders/icp_reduce_final.wgsl"),
    ),
    (
        "fuse_select",
        include_str!("../../shaders/fuse_select.wgsl"),
    ),
    ("fuse_merge", include_str!("../../shaders/fuse_merge.wgsl")),
    (
        "fuse_merge_chosen",
        include_str!("../../shaders/fuse_merge_chosen.wgsl"),
    ),
    ("fuse_prune", include_str!("../../shaders/fuse_prune.wgsl")),
    ("fuse_flags", include_str!("../../shaders/fuse_flags.wgsl")),
    ("fuse_add", include_str!("../../shaders/fuse_add.wgsl")),
    // The portable key kernels (two 32-bit passes each, see PORTABLE_KERNELS).
    (
        "project_model_portable",
        include_str!("../../shaders/project_model_portable.wgsl"),
    ),
    (
        "fuse_select_portable",
        include_str!("../../shaders/fuse_select_portable.wgsl"),
    ),
    (
        "fuse_add_portable",
        include_str!("../../shaders/fuse_add_portable.wgsl"),
    ),
    (
        "compact_flags",
        include_str!("../../shaders/compact_flags.wgsl"),
    ),
    // The compaction scan: prefix_sum_reduce, prefix_sum_blocks, then prefix_sum.
    (
        "prefix_sum_reduce",
        include_str!("../../shaders/prefix_sum_reduce.wgsl"),
    ),
    (
        "prefix_sum_blocks",
        include_str!("../../shaders/prefix_sum_blocks.wgsl"),
    ),
    ("prefix_sum", include_str!("../../shaders/prefix_sum.wgsl")),
    // Loop closure's map deformation (src/gpu/loops.rs), built at the first closure.
    (
        "deform_surfels",
        include_str!("../../shaders/deform_surfels.wgsl"),
    ),
    (
        "compact_scatter",
        include_str!("../../shaders/compact_scatter.wgsl"),
    ),
    // Scan registration (point-to-point ICP): see src/scan/gpu.rs.
    ("nn_brute", include_str!("../../shaders/nn_brute.wgsl")),
    ("nn_grid", include_str!("../../shaders/nn_grid.wgsl")),
    (
        "cross_covariance",
        include_str!("../../shaders/cross_covariance.wgsl"),
    ),
    // Pictures of the map (src/render/gpu.rs), not part of the SLAM pipeline.
    (
        "render_splat",
        include_str!("../../shaders/render_splat.wgsl"),
    ),
    (
        "render_splat_portable",
        include_str!("../../shaders/render_splat_portable.wgsl"),
    ),
    (
        "render_resolve",
        include_str!("../../shaders/render_resolve.wgsl"),
    ),
];

/// The kernel file's text alone (without `common.wgsl`), or `None` for an unknown name.
pub fn kernel_text(kernel_name: &str) -> Option<&'static str> {
    KERNELS
        .iter()
        .find(|(name, _)| *name == kernel_name)
        .map(|(_, text)| *text)
}

/// The prefix of a kernel as `(file name without .wgsl, text)`: `scan_common` for
/// [`SCAN_KERNELS`], `common` for every other name (inline test kernels included).
pub fn prefix_of(kernel_name: &str) -> (&'static str, &'static str) {
    if SCAN_KERNELS.contains(&kernel_name) {
        ("scan_common", SCAN_COMMON)
    } else {
        ("common", COMMON)
    }
}

/// The full WGSL of a kernel: its prefix ([`prefix_of`]) + `shaders/<kernel_name>.wgsl`.
///
/// Panics on an unknown kernel name: kernel names are compile-time constants of this crate,
/// so a miss is a bug, not a user error.
pub fn source(kernel_name: &str) -> String {
    let text = kernel_text(kernel_name).unwrap_or_else(|| {
        panic!("unknown WGSL kernel `{kernel_name}` (not listed in gpu::shaders::KERNELS)")
    });
    concat(prefix_of(kernel_name).1, text)
}

/// `common.wgsl` followed by `kernel_text`, separated by one newline.
pub fn concat_with_common(kernel_text: &str) -> String {
    concat(COMMON, kernel_text)
}

/// `prefix` followed by `kernel_text`, separated by one newline.
fn concat(prefix: &str, kernel_text: &str) -> String {
    let mut s = String::with_capacity(prefix.len() + kernel_text.len() + 1);
    s.push_str(prefix);
    if !prefix.ends_with('\n') {
        s.push('\n');
    }
    s.push_str(kernel_text);
    s
}

/// Lines `common.wgsl` takes at the top of every concatenated dense or render source.
pub fn common_line_count() -> usize {
    COMMON.lines().count()
}

/// Maps a 1-based line of a concatenated source back to `(file, line)`:
/// `("shaders/<prefix>.wgsl", l)` for the prefix, `("shaders/<kernel>.wgsl", l)` after it.
pub fn origin_of_line(kernel_name: &str, line: usize) -> (String, usize) {
    let (prefix, text) = prefix_of(kernel_name);
    let n = text.lines().count();
    if line <= n {
        (format!("shaders/{prefix}.wgsl"), line)
    } else {
        (format!("shaders/{kernel_name}.wgsl"), line - n)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn line_mapping_splits_at_common() {
        let n = common_line_count();
        assert_eq!(origin_of_line("k", n).0, "shaders/common.wgsl");
        assert_eq!(
            origin_of_line("k", n + 3),
            ("shaders/k.wgsl".to_string(), 3)
        );
        let src = concat_with_common("// first\n");
        assert_eq!(src.lines().nth(n), Some("// first"));
    }
}
