//! The kernel registry: one row per kernel, pairing its shader `shaders/<name>.wgsl` with
//! its CPU twin `crate::cpu::<name>::<name>` (the model is vello's
//! `add_shader!(name, ..., CpuShaderType::Present(cpu::name))`). From the rows, the
//! [`registry!`] macro below makes
//!
//! - [`KERNELS`], every kernel's `(name, text of its file)` for the runtime and the naga
//!   tests (a key kernel's portable variant is a second entry over the same text, see
//!   [`super::shaders::PORTABLE_KERNELS`]);
//! - [`Kernels`], the dense pipeline's pipelines, one field per kernel named after it,
//!   built once per backend by [`Kernels::new`];
//! - a compile-time check that each row's twin exists (an underscore import of
//!   `crate::cpu::<name>::<name>`): a row without a twin does not build.
//!
//! What the registry does not hold: a kernel's bindings (reflected from the WGSL, see
//! [`Kernel::new`]; bound by name in `super::bind_groups`), and the order kernels run in
//! (`crate::slam::plan`).

use super::context::GpuContext;
use super::kernel::{Kernel, KeyKernel};
use crate::Result;

/// One row per kernel, in four groups by how the kernel is built:
///
/// - `kernels`: a [`Kernel`] field of [`Kernels`] (built with the backend);
/// - `key_kernels`: a [`KeyKernel`] field (the 64-bit kernel, or its portable variant
///   `<name>_portable` on a device without 64-bit atomics; both are in [`KERNELS`]);
/// - `elsewhere`: built by the code that runs it (`deform_surfels` at the first loop
///   closure, the scan registration's and the renderer's kernels);
/// - `key_elsewhere`: a key kernel built by the code that runs it (the renderer's splat).
macro_rules! registry {
    (
        kernels: { $($kernel:ident,)* }
        key_kernels: { $($key:ident,)* }
        elsewhere: { $($other:ident,)* }
        key_elsewhere: { $($other_key:ident,)* }
    ) => {
        /// Every kernel the runtime builds as `(name, text of shaders/<file_of(name)>.wgsl)`:
        /// one row per file, plus one per portable variant of a key kernel (the same text,
        /// see [`super::shaders::PORTABLE_KERNELS`]). `tests/it/shaders.rs` fails when a
        /// `.wgsl` file is missing here.
        pub const KERNELS: &[(&str, &str)] = &[
            $((stringify!($kernel), include_str!(concat!("../../shaders/", stringify!($kernel), ".wgsl"))),)*
            $((stringify!($key), include_str!(concat!("../../shaders/", stringify!($key), ".wgsl"))),)*
            $((concat!(stringify!($key), "_portable"), include_str!(concat!("../../shaders/", stringify!($key), ".wgsl"))),)*
            $((stringify!($other), include_str!(concat!("../../shaders/", stringify!($other), ".wgsl"))),)*
            $((stringify!($other_key), include_str!(concat!("../../shaders/", stringify!($other_key), ".wgsl"))),)*
            $((concat!(stringify!($other_key), "_portable"), include_str!(concat!("../../shaders/", stringify!($other_key), ".wgsl"))),)*
        ];

        /// Each row's CPU twin, `crate::cpu::<name>::<name>`: this does not compile when
        /// one is missing.
        #[allow(unused_imports)]
        mod twins {
            $(use crate::cpu::$kernel::$kernel as _;)*
            $(use crate::cpu::$key::$key as _;)*
            $(use crate::cpu::$other::$other as _;)*
            $(use crate::cpu::$other_key::$other_key as _;)*
        }

        /// Every kernel of the dense pipeline, one field per kernel named after it.
        pub(super) struct Kernels {
            $(pub $kernel: Kernel,)*
            $(pub $key: KeyKernel,)*
        }

        impl Kernels {
            /// Builds every kernel (pipeline creation costs 60-130 ms each on lavapipe).
            pub fn new(ctx: &GpuContext) -> Result<Kernels> {
                Ok(Kernels {
                    $($kernel: Kernel::new(ctx, stringify!($kernel))?,)*
                    $($key: KeyKernel::new(ctx, stringify!($key))?,)*
                })
            }
        }
    };
}

registry! {
    kernels: {
        depth_to_vertex,
        bilateral_filter,
        vertex_to_normal,
        pyramid_depth,
        block_bounds,
        predict_model,
        pyramid_model,
        icp_reduce,
        icp_reduce_final,
        icp_candidates,
        fern_encode,
        keypoint_detect,
        keypoint_describe,
        fuse_merge,
        fuse_merge_chosen,
        fuse_prune,
        fuse_flags,
        compact_flags,
        // The scan's three kernels: block sums, their scan, each block's scan.
        prefix_sum_reduce,
        prefix_sum_blocks,
        prefix_sum,
        compact_scatter,
    }
    key_kernels: {
        project_model,
        fuse_select,
        fuse_add,
    }
    elsewhere: {
        // Loop closure's map deformation (src/gpu/loops.rs), built at the first closure.
        deform_surfels,
        // Scan registration (point-to-point ICP): see src/scan/gpu.rs.
        nn_brute,
        nn_grid,
        cross_covariance,
        // Pictures of the map (src/render/gpu.rs), not part of the SLAM pipeline.
        render_resolve,
    }
    key_elsewhere: {
        render_splat,
    }
}
