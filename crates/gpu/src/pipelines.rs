//! The dense pipeline's kernels, built: one field of [`Kernels`] per row of the registry
//! (`super::kernels`, read through its `pipeline_rows!`), and for the `generic` rows how each
//! is bound and dispatched ([`Shape`], [`GenericRow`]).

use super::context::GpuContext;
use super::kernel::{Kernel, KeyKernel};
use super::kernels::pipeline_rows;
use super::resources::Uniforms;
use crate::Result;

/// Makes [`Kernels`] from the registry's rows (see `super::kernels` for the groups).
macro_rules! registry_pipelines {
    (
        generic: { $($generic:ident: $shape:ident($uniform:ident),)* }
        generic_keys: { $($generic_key:ident: $key_shape:ident($key_uniform:ident),)* }
        kernels: { $($kernel:ident,)* }
        key_kernels: { $($key:ident,)* }
    ) => {
        /// Every kernel of the dense pipeline, one field per kernel named after it.
        pub(super) struct Kernels {
            $(pub $generic: Kernel,)*
            $(pub $generic_key: KeyKernel,)*
            $(pub $kernel: Kernel,)*
            $(pub $key: KeyKernel,)*
        }

        impl Kernels {
            /// Builds every kernel (pipeline creation costs 60-130 ms each on lavapipe).
            pub fn new(ctx: &GpuContext) -> Result<Kernels> {
                Ok(Kernels {
                    $($generic: Kernel::new(ctx, stringify!($generic))?,)*
                    $($generic_key: KeyKernel::new(ctx, stringify!($generic_key))?,)*
                    $($kernel: Kernel::new(ctx, stringify!($kernel))?,)*
                    $($key: KeyKernel::new(ctx, stringify!($key))?,)*
                })
            }

            /// The `generic` rows: each kernel's name, passes, [`Shape`] and parameters.
            pub fn generic<'a>(&'a self, u: &'a Uniforms) -> Vec<GenericRow<'a>> {
                vec![
                    $(GenericRow {
                        name: stringify!($generic),
                        passes: std::slice::from_ref(&self.$generic),
                        shape: Shape::$shape,
                        params: u.$uniform.binding(),
                    },)*
                    $(GenericRow {
                        name: stringify!($generic_key),
                        passes: &self.$generic_key.passes,
                        shape: Shape::$key_shape,
                        params: u.$key_uniform.binding(),
                    },)*
                ]
            }

            /// The `generic` row's passes for the kernel `name` (one kernel, or a key
            /// kernel's passes in order) and its [`Shape`], or `None` for a kernel with bind
            /// groups and passes of its own.
            pub fn generic_kernel(&self, name: &str) -> Option<(&[Kernel], Shape)> {
                match name {
                    $(stringify!($generic) => {
                        Some((std::slice::from_ref(&self.$generic), Shape::$shape))
                    })*
                    $(stringify!($generic_key) => {
                        Some((&self.$generic_key.passes[..], Shape::$key_shape))
                    })*
                    _ => None,
                }
            }
        }
    };
}

/// How a `generic` row's kernel is bound and dispatched: its bind groups take what the
/// kernel's WGSL declares from the frame's pool of named resources (and each map chunk's),
/// with the row's uniform as `params` (see `super::bind_groups`); its passes follow the
/// plan (see `super::step_grid::StepGrid::generic`). A key kernel's passes run in turn,
/// each over every bind group before the next (the portable kernel's second pass reads the
/// first's result over the whole map).
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
    /// The kernel's passes: one, or a key kernel's (the first's layout makes the bind
    /// groups).
    pub passes: &'a [Kernel],
    pub shape: Shape,
    /// The row's uniform buffer, bound as the kernel's `params`.
    pub params: wgpu::BindingResource<'a>,
}

pipeline_rows!();
