//! The dense pipeline's kernels, built: one field of [`Kernels`] per row of the registry
//! (`wgslam_core::registry`, read through its `pipeline_rows!`), and for the `generic` rows
//! what each is bound with ([`GenericRow`]; how, its [`Shape`], is the row's too).

use super::context::GpuContext;
use super::kernel::{Kernel, KeyKernel};
use super::resources::{LevelUniforms, Uniforms};
use crate::Result;
use wgslam_core::registry::{KernelId, Shape};

/// Makes [`Kernels`] from the registry's rows (see `wgslam_core::registry` for the groups).
macro_rules! registry_pipelines {
    (
        generic: { $($generic:ident: $shape:ident($uniform:ident),)* }
        generic_keys: { $($generic_key:ident: $key_shape:ident($key_uniform:ident),)* }
        kernels: { $($kernel:ident,)* }
        key_kernels: { $($key:ident,)* }
        generic_levels: { $($level:ident: $level_shape:ident($level_uniform:ident),)* }
    ) => {
        /// Every kernel of the dense pipeline, one field per kernel named after it.
        pub(super) struct Kernels {
            $(pub $generic: Kernel,)*
            $(pub $generic_key: KeyKernel,)*
            $(pub $level: Kernel,)*
            $(pub $kernel: Kernel,)*
            $(pub $key: KeyKernel,)*
        }

        impl Kernels {
            /// Builds every kernel, on every core at once ([`build_on_every_core`]), then
            /// takes them from the device's cache.
            pub fn new(ctx: &GpuContext) -> Result<Kernels> {
                build_on_every_core(ctx, &[
                    $((stringify!($generic), false),)*
                    $((stringify!($generic_key), true),)*
                    $((stringify!($level), false),)*
                    $((stringify!($kernel), false),)*
                    $((stringify!($key), true),)*
                ])?;
                Ok(Kernels {
                    $($generic: Kernel::new(ctx, stringify!($generic))?,)*
                    $($generic_key: KeyKernel::new(ctx, stringify!($generic_key))?,)*
                    $($level: Kernel::new(ctx, stringify!($level))?,)*
                    $($kernel: Kernel::new(ctx, stringify!($kernel))?,)*
                    $($key: KeyKernel::new(ctx, stringify!($key))?,)*
                })
            }

            /// The `generic` rows: each kernel's id, passes, [`Shape`] and parameters.
            pub fn generic<'a>(&'a self, u: &'a Uniforms) -> Vec<GenericRow<'a>> {
                vec![
                    $(GenericRow {
                        id: KernelId::$generic,
                        passes: std::slice::from_ref(&self.$generic),
                        shape: Shape::$shape,
                        params: RowParams::Frame(u.$uniform.binding()),
                    },)*
                    $(GenericRow {
                        id: KernelId::$generic_key,
                        passes: &self.$generic_key.passes,
                        shape: Shape::$key_shape,
                        params: RowParams::Frame(u.$key_uniform.binding()),
                    },)*
                    $(GenericRow {
                        id: KernelId::$level,
                        passes: std::slice::from_ref(&self.$level),
                        shape: Shape::$level_shape,
                        params: RowParams::Level(|l| l.$level_uniform.clone()),
                    },)*
                ]
            }

            /// The `generic` row's passes for the kernel `id` (one kernel, or a key
            /// kernel's passes in order) and its [`Shape`], or `None` for a kernel with bind
            /// groups and passes of its own.
            pub fn generic_kernel(&self, id: KernelId) -> Option<(&[Kernel], Shape)> {
                match id {
                    $(KernelId::$generic => {
                        Some((std::slice::from_ref(&self.$generic), Shape::$shape))
                    })*
                    $(KernelId::$generic_key => {
                        Some((&self.$generic_key.passes[..], Shape::$key_shape))
                    })*
                    $(KernelId::$level => {
                        Some((std::slice::from_ref(&self.$level), Shape::$level_shape))
                    })*
                    _ => None,
                }
            }
        }
    };
}

/// Builds each kernel of `kernels`, `(name, keyed)` (keyed: a [`KeyKernel`]), into the
/// device's cache (`GpuContext::cached`), on as many threads as there are cores: parsing,
/// validating and translating the WGSL and the driver's compilation of about 40 pipelines
/// took 0.165 s of a 0.5 s one-frame run's start-up on one thread (lavapipe, 2 cores).
/// An error of one of them, if any (each thread stops at its first). In a browser (one
/// thread), nothing: `Kernels::new` builds them one by one.
fn build_on_every_core(ctx: &GpuContext, kernels: &[(&str, bool)]) -> Result<()> {
    #[cfg(not(target_arch = "wasm32"))]
    {
        use std::sync::atomic::{AtomicUsize, Ordering};
        let next = AtomicUsize::new(0);
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
        let build = || -> Result<()> {
            while let Some(&(name, keyed)) = kernels.get(next.fetch_add(1, Ordering::Relaxed)) {
                if keyed {
                    KeyKernel::new(ctx, name)?;
                } else {
                    Kernel::new(ctx, name)?;
                }
            }
            Ok(())
        };
        std::thread::scope(|s| {
            let threads: Vec<_> = (0..cores.min(kernels.len()))
                .map(|_| s.spawn(build))
                .collect();
            let results: Vec<Result<()>> = threads
                .into_iter()
                .map(|t| t.join().unwrap_or_else(|p| std::panic::resume_unwind(p)))
                .collect();
            results.into_iter().collect()
        })
    }
    #[cfg(target_arch = "wasm32")]
    {
        let _ = (ctx, kernels);
        Ok(())
    }
}

/// One `generic` row of the registry, as [`Kernels::generic`] lends it.
pub(super) struct GenericRow<'a> {
    pub id: KernelId,
    /// The kernel's passes: one, or a key kernel's (the first's layout makes the bind
    /// groups).
    pub passes: &'a [Kernel],
    pub shape: Shape,
    /// The row's uniform buffer, bound as the kernel's `params`.
    pub params: RowParams<'a>,
}

/// A `generic_levels` row's uniform at a level: its field of [`LevelUniforms`], `None`
/// where the level has none.
pub(super) type LevelParams = for<'b> fn(&LevelUniforms<'b>) -> Option<wgpu::BindingResource<'b>>;

/// A `generic` row's `params`: the frame's uniform buffer of the row's name, or for a
/// `generic_levels` row the one of each pyramid level.
pub(super) enum RowParams<'a> {
    Frame(wgpu::BindingResource<'a>),
    Level(LevelParams),
}

wgslam_core::pipeline_rows!();
