//! The kernel registry: one row per kernel, pairing its shader `shaders/<name>.wgsl` with
//! its CPU twin `crate::cpu::<name>::<name>` (the model is vello's
//! `add_shader!(name, ..., CpuShaderType::Present(cpu::name))`). From the rows, the
//! `registry!` macro below makes
//!
//! - [`KERNELS`], every kernel's `(name, text of its file)` for the runtime and the naga
//!   tests (a key kernel's portable variant is a second entry over the same text, see
//!   [`super::shaders::PORTABLE_KERNELS`]);
//! - [`Kernels`], the dense pipeline's pipelines, one field per kernel named after it,
//!   built once per backend by [`Kernels::new`];
//! - for the `generic` rows, how the kernel is bound and dispatched ([`Shape`], and the
//!   uniform bound as its `params`): `super::bind_groups` and `super::steps` then need
//!   nothing of their own for it;
//! - a compile-time check that each row's twin exists (an underscore import of
//!   `crate::cpu::<name>::<name>`): a row without a twin does not build.
//!
//! What the registry does not hold: a kernel's bindings (reflected from the WGSL, see
//! [`Kernel::new`], and bound by the WGSL variables' names), the bind groups and passes of
//! the kernels that fit no [`Shape`] (`super::bind_groups`, `super::steps`), and the order
//! kernels run in (`crate::slam::plan`).

use super::context::GpuContext;
use super::kernel::{Kernel, KeyKernel};
use super::resources::Uniforms;
use crate::Result;

/// One row per kernel, in five groups by how the kernel is built:
///
/// - `generic`: `name: Shape(uniform)`, a [`Kernel`] field of [`Kernels`] whose bind groups
///   and passes the row decides ([`Shape`]; `uniform` is the `super::resources::Uniforms`
///   field bound as its `params`): nothing else in `src/gpu/` names it;
/// - `kernels`: a [`Kernel`] field of [`Kernels`] with bind groups in `super::bind_groups`
///   and passes in `super::steps` or `super::single_steps` of its own;
/// - `key_kernels`: a [`KeyKernel`] field (the 64-bit kernel, or its portable variant
///   `<name>_portable` on a device without 64-bit atomics; both are in [`KERNELS`]);
/// - `elsewhere`: built by the code that runs it (`deform_surfels` at the first loop
///   closure, the scan registration's and the renderer's kernels);
/// - `key_elsewhere`: a key kernel built by the code that runs it (the renderer's splat).
macro_rules! registry {
    (
        generic: { $($generic:ident: $shape:ident($uniform:ident),)* }
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
            $((stringify!($generic), include_str!(concat!("../../shaders/", stringify!($generic), ".wgsl"))),)*
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
            $(use crate::cpu::$generic::$generic as _;)*
            $(use crate::cpu::$kernel::$kernel as _;)*
            $(use crate::cpu::$key::$key as _;)*
            $(use crate::cpu::$other::$other as _;)*
            $(use crate::cpu::$other_key::$other_key as _;)*
        }

        /// Every kernel of the dense pipeline, one field per kernel named after it.
        pub(super) struct Kernels {
            $(pub $generic: Kernel,)*
            $(pub $kernel: Kernel,)*
            $(pub $key: KeyKernel,)*
        }

        impl Kernels {
            /// Builds every kernel (pipeline creation costs 60-130 ms each on lavapipe).
            pub fn new(ctx: &GpuContext) -> Result<Kernels> {
                Ok(Kernels {
                    $($generic: Kernel::new(ctx, stringify!($generic))?,)*
                    $($kernel: Kernel::new(ctx, stringify!($kernel))?,)*
                    $($key: KeyKernel::new(ctx, stringify!($key))?,)*
                })
            }

            /// The `generic` rows: each kernel's name, pipeline, [`Shape`] and parameters.
            pub fn generic<'a>(&'a self, u: &'a Uniforms) -> Vec<GenericRow<'a>> {
                vec![$(GenericRow {
                    name: stringify!($generic),
                    kernel: &self.$generic,
                    shape: Shape::$shape,
                    params: u.$uniform.binding(),
                },)*]
            }

            /// The `generic` rows' kernels.
            pub fn generic_kernels(&self) -> Vec<&Kernel> {
                vec![$(&self.$generic,)*]
            }

            /// The `generic` row's kernel `name` and its [`Shape`], or `None` for a kernel
            /// with bind groups and passes of its own.
            pub fn generic_kernel(&self, name: &str) -> Option<(&Kernel, Shape)> {
                match name {
                    $(stringify!($generic) => Some((&self.$generic, Shape::$shape)),)*
                    _ => None,
                }
            }
        }
    };
}

/// How a `generic` row's kernel is bound and dispatched: its bind groups take what the
/// kernel's WGSL declares from the frame's pool of named resources (and each map chunk's),
/// with the row's uniform as `params` (see `super::bind_groups`); its passes follow the
/// plan (see `super::step_grid::StepGrid::generic`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Shape {
    /// One bind group over the frame's pool; one pass over the frame's pixels.
    OverFrame,
    /// One bind group per map chunk; per chunk a pass over the frame's pixels.
    PerChunk,
    /// One bind group per map chunk; per chunk a pass of one workgroup per culling block
    /// holding live surfels.
    PerBlock,
}

/// One `generic` row of the registry, as [`Kernels::generic`] lends it.
pub(super) struct GenericRow<'a> {
    pub name: &'static str,
    pub kernel: &'a Kernel,
    pub shape: Shape,
    /// The row's uniform buffer, bound as the kernel's `params`.
    pub params: wgpu::BindingResource<'a>,
}

registry! {
    generic: {
        predict_model: PerChunk(project),
        fuse_merge_chosen: PerChunk(fuse),
        fuse_prune: PerBlock(fuse),
        fuse_merge: PerBlock(fuse),
        fuse_flags: OverFrame(fuse),
    }
    kernels: {
        depth_to_vertex,
        bilateral_filter,
        vertex_to_normal,
        pyramid_depth,
        block_bounds,
        pyramid_model,
        icp_reduce,
        icp_reduce_final,
        // RGB-D tracking's photometric term (its sum: icp_reduce_final) and the frame's
        // intensity pyramid it reads.
        photo_reduce,
        intensity_pyramid,
        icp_candidates,
        fern_encode,
        keypoint_detect,
        keypoint_describe,
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
