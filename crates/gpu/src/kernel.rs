//! A compute kernel: one pipeline, its explicit bind-group layout and its workgroup size,
//! built once from a kernel name (`shaders/<name>.wgsl`, entry point `main`). The layout is
//! naga's reflection of the WGSL's `@group(0) @binding(i)` declarations, the one place a
//! binding is written; bind groups are made by the WGSL variables' names, so a resource
//! bound to the wrong binding fails at once with the kernel's and the binding's name.
//! Dispatch computes nothing itself beyond skipping empty dispatches.
//!
//! Not a scheduler: which kernel runs when, on which buffers, is the backend's business.
//! Layouts are explicit because with `layout: None` bindings an entry point does not use
//! vanish from the derived layout, and bind-group creation then panics.

use super::context::GpuContext;
use super::shaders;
use crate::{Error, Result};
use wgslam_core::registry::KernelId;

/// One `@group(0) @binding(i)` of a kernel as naga reflects it from the WGSL: the layout
/// is built from these, and bind groups are made by `name`. Parameter structs are
/// `var<storage, read> params`, not uniforms: lavapipe (Mesa 22.3) inlines the values of a
/// uniform buffer into the shader and compiles a new variant after every write of it,
/// keeping each (0.75 MB of JIT code per `icp_reduce` iteration, so a 200-frame run grew by
/// gigabytes; measured with `examples/params_memory.rs`). Storage buffers are not inlined;
/// `tests/it/bindings.rs` checks that no kernel declares a uniform.
#[derive(Debug, Clone, PartialEq)]
pub struct ReflectedBinding {
    /// `i` of `@binding(i)`.
    pub binding: u32,
    /// The WGSL variable's name.
    pub name: String,
    /// The layout entry type the declaration asks for.
    pub ty: wgpu::BindingType,
}

/// A compute pipeline with its bind-group layout (group 0) and `@workgroup_size` (x, y:
/// grid-stride kernels are one-dimensional, per-pixel kernels use 8x8 tiles).
#[derive(Debug, Clone)]
pub struct Kernel {
    /// The kernel's name (`shaders/<name>.wgsl`).
    pub name: String,
    pub pipeline: wgpu::ComputePipeline,
    pub bind_group_layout: wgpu::BindGroupLayout,
    /// Threads per workgroup along x, read from the shader's `@workgroup_size`.
    pub workgroup_size: u32,
    /// Threads per workgroup along y (1 for one-dimensional kernels).
    pub workgroup_size_y: u32,
    bindings: Vec<ReflectedBinding>,
}

impl Kernel {
    /// Builds the kernel `shaders/<name>.wgsl` (with `common.wgsl` prepended), its layout
    /// reflected from the WGSL. Create every kernel once: pipeline creation costs 60-130 ms
    /// on lavapipe.
    ///
    /// [`Error::Gpu`] when the WGSL does not parse or declares a binding the kernels cannot
    /// use; wgpu validation errors likewise.
    pub fn new(ctx: &GpuContext, name: &str) -> Result<Kernel> {
        // Built once per device ([`GpuContext::cached`]).
        ctx.cached(name, || {
            Self::from_source(ctx, name, &shaders::source(name))
        })
    }

    /// The kernel of registry row `id` ([`Kernel::new`] of its name): how the rows of the
    /// kernels outside the dense pipeline (the renderer's, scan registration's) are built
    /// (`super::row_kernels`), by a typed id that cannot be misspelt.
    pub fn of(ctx: &GpuContext, id: KernelId) -> Result<Kernel> {
        Self::new(ctx, id.name())
    }

    /// Builds a kernel from full WGSL text (used by [`Kernel::new`] and by tests with
    /// inline shaders).
    pub fn from_source(ctx: &GpuContext, name: &str, wgsl: &str) -> Result<Kernel> {
        Self::build(ctx, name, wgsl, &[], None)
    }

    /// The passes of a portable key kernel variant (`name` as in
    /// [`shaders::PORTABLE_KERNELS`]): one kernel per value of its `override KEY_PASS` (0,
    /// then 1), sharing one bind-group layout, so a bind group made with the first runs
    /// both passes.
    pub fn key_passes(ctx: &GpuContext, name: &str) -> Result<[Kernel; 2]> {
        ctx.cached(&format!("{name} key passes"), || {
            let wgsl = shaders::source(name);
            let first = Self::build(ctx, name, &wgsl, &[(shaders::KEY_PASS, 0.0)], None)?;
            let layout = first.bind_group_layout.clone();
            let second = Self::build(ctx, name, &wgsl, &[(shaders::KEY_PASS, 1.0)], Some(layout))?;
            Ok([first, second])
        })
    }

    /// A kernel from full WGSL with its `override` constants set to `constants`, and with
    /// `layout` as its bind-group layout (else one made from the reflected bindings).
    fn build(
        ctx: &GpuContext,
        name: &str,
        wgsl: &str,
        constants: &[(&str, f64)],
        layout: Option<wgpu::BindGroupLayout>,
    ) -> Result<Kernel> {
        let interface = reflect(name, wgsl).map_err(|problems| Error::Gpu(problems.join("\n")))?;
        let (bindings, [workgroup_size, workgroup_size_y]) = interface;
        ctx.scoped(&format!("creating kernel `{name}`"), || {
            let entries = layout_entries(&bindings);
            let bind_group_layout = layout.unwrap_or_else(|| {
                ctx.device
                    .create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                        label: Some(name),
                        entries: &entries,
                    })
            });
            let layout = ctx
                .device
                .create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                    label: Some(name),
                    bind_group_layouts: &[Some(&bind_group_layout)],
                    immediate_size: 0,
                });
            let module = ctx
                .device
                .create_shader_module(wgpu::ShaderModuleDescriptor {
                    label: Some(name),
                    source: wgpu::ShaderSource::Wgsl(wgsl.into()),
                });
            let pipeline = ctx
                .device
                .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                    label: Some(name),
                    layout: Some(&layout),
                    module: &module,
                    entry_point: Some("main"),
                    compilation_options: wgpu::PipelineCompilationOptions {
                        constants,
                        ..Default::default()
                    },
                    cache: ctx.pipeline_cache(),
                });
            Ok(Kernel {
                name: name.to_string(),
                pipeline,
                bind_group_layout,
                workgroup_size,
                workgroup_size_y,
                bindings,
            })
        })
    }

    /// A bind group with each `(name, resource)` at the binding whose WGSL variable is
    /// `name`; the order of `resources` does not matter.
    ///
    /// Panics (an internal contract) naming the kernel and the binding when a binding gets
    /// no resource or two, a name is not one of the kernel's bindings, or a buffer is given
    /// for a texture binding or the other way round.
    pub fn bind_group(
        &self,
        ctx: &GpuContext,
        resources: &[(&str, wgpu::BindingResource<'_>)],
    ) -> wgpu::BindGroup {
        let mut problems = Vec::new();
        for (name, _) in resources {
            if !self.bindings.iter().any(|b| b.name == *name) {
                problems.push(format!("`{name}` is not one of its bindings"));
            }
        }
        let mut entries = Vec::with_capacity(self.bindings.len());
        for b in &self.bindings {
            let given: Vec<_> = resources.iter().filter(|(n, _)| *n == b.name).collect();
            match given.as_slice() {
                [(_, resource)] => {
                    let is_buffer = matches!(resource, wgpu::BindingResource::Buffer(_));
                    let wants_buffer = matches!(b.ty, wgpu::BindingType::Buffer { .. });
                    if is_buffer != wants_buffer {
                        problems.push(format!(
                            "binding {} (`{}`) is {:?}, given a {}",
                            b.binding,
                            b.name,
                            b.ty,
                            if is_buffer {
                                "buffer"
                            } else {
                                "texture or other resource"
                            }
                        ));
                    }
                    entries.push(wgpu::BindGroupEntry {
                        binding: b.binding,
                        resource: resource.clone(),
                    });
                }
                [] => problems.push(format!(
                    "binding {} (`{}`) has no resource",
                    b.binding, b.name
                )),
                _ => problems.push(format!(
                    "binding {} (`{}`) is given {} resources",
                    b.binding,
                    b.name,
                    given.len()
                )),
            }
        }
        assert!(
            problems.is_empty(),
            "kernel `{}`: bind group does not match the WGSL:\n{}",
            self.name,
            problems.join("\n")
        );
        ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some(&self.name),
            layout: &self.bind_group_layout,
            entries: &entries,
        })
    }

    /// A bind group from a pool of named resources: each of the kernel's bindings takes
    /// the pool's resource of its WGSL variable's name; the pool may hold resources other
    /// kernels need. Names the pool holds twice are taken from the first entry, so a pool
    /// can start with the kernel's own resources (its `params`) and go on with shared ones.
    ///
    /// Panics (an internal contract) naming the kernel and the binding when the pool has no
    /// resource of a binding's name, or one of the wrong kind (see [`Kernel::bind_group`]).
    pub fn bind_group_from(
        &self,
        ctx: &GpuContext,
        pool: &[(&str, wgpu::BindingResource<'_>)],
    ) -> wgpu::BindGroup {
        let chosen: Vec<(&str, wgpu::BindingResource<'_>)> = self
            .bindings
            .iter()
            .filter_map(|b| pool.iter().find(|(name, _)| *name == b.name).cloned())
            .collect();
        self.bind_group(ctx, &chosen)
    }

    /// Whether the kernel declares a binding named `name`.
    pub fn binds(&self, name: &str) -> bool {
        self.bindings.iter().any(|b| b.name == name)
    }

    /// Workgroups needed to give each of `n` items one thread: `ceil(n / workgroup_size)`.
    pub fn workgroups_for(&self, n: usize) -> u32 {
        n.div_ceil(self.workgroup_size as usize) as u32
    }

    /// Records `set_pipeline`, `set_bind_group(0)` and a one-dimensional dispatch of
    /// `workgroups`. Does nothing when `workgroups == 0`; [`Error::Capacity`] when it
    /// exceeds the device's `max_compute_workgroups_per_dimension`.
    pub fn dispatch(
        &self,
        ctx: &GpuContext,
        pass: &mut wgpu::ComputePass<'_>,
        bind_group: &wgpu::BindGroup,
        workgroups: u32,
    ) -> Result<()> {
        self.dispatch_grid(ctx, pass, bind_group, [workgroups, 1])
    }

    /// Workgroups covering a `width x height` image with one thread per pixel.
    pub fn workgroups_for_image(&self, width: u32, height: u32) -> [u32; 2] {
        [
            width.div_ceil(self.workgroup_size),
            height.div_ceil(self.workgroup_size_y),
        ]
    }

    /// Workgroups for a kernel whose threads walk a `width x height` image in a 2-D
    /// grid-stride loop over tiles of its workgroup size (thread `(x, y)` takes pixels
    /// `(x + i X, y + j Y)`, `X x Y` the threads dispatched): see [`image_grid`].
    pub fn grid_workgroups_for_image(&self, ctx: &GpuContext, width: u32, height: u32) -> [u32; 2] {
        image_grid(
            self.workgroups_for_image(width, height),
            ctx.grid_workgroups_cap(),
            ctx.is_cpu_adapter(),
        )
    }

    /// Like [`Kernel::dispatch`] with an `[x, y]` grid of workgroups (each at most the
    /// device's `max_compute_workgroups_per_dimension`).
    pub fn dispatch_grid(
        &self,
        ctx: &GpuContext,
        pass: &mut wgpu::ComputePass<'_>,
        bind_group: &wgpu::BindGroup,
        [x, y]: [u32; 2],
    ) -> Result<()> {
        if x == 0 || y == 0 {
            return Ok(());
        }
        let max = ctx.limits().max_compute_workgroups_per_dimension;
        if x > max || y > max {
            return Err(Error::Capacity(format!(
                "kernel `{}`: {x}x{y} workgroups of {}x{} threads exceed the device limit \
                 of {max} per dimension",
                self.name, self.workgroup_size, self.workgroup_size_y
            )));
        }
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, bind_group, &[]);
        pass.dispatch_workgroups(x, y, 1);
        Ok(())
    }
}

/// A kernel that keeps the nearest surfel per pixel in a map of 64-bit keys: the 64-bit
/// kernel in one pass where the device has 64-bit atomics, else its portable variant in two
/// passes (see [`shaders::PORTABLE_KERNELS`]). Every pass runs over the same bind groups
/// (made with [`KeyKernel::first`]); each pass covers every chunk before the next begins.
#[derive(Debug)]
pub struct KeyKernel {
    /// One kernel (64-bit) or two (the portable kernel's `KEY_PASS` 0 and 1), in order.
    pub passes: Vec<Kernel>,
}

impl KeyKernel {
    /// The kernel `name` (one of the 64-bit kernels of [`shaders::PORTABLE_KERNELS`]) or,
    /// on a device without 64-bit atomics, its portable variant.
    pub fn new(ctx: &GpuContext, name: &str) -> Result<KeyKernel> {
        let portable = shaders::PORTABLE_KERNELS
            .iter()
            .find(|(k, _)| *k == name)
            .unwrap_or_else(|| panic!("`{name}` is not a 64-bit key kernel"))
            .1;
        let passes = if ctx.has_int64_atomics() {
            vec![Kernel::new(ctx, name)?]
        } else {
            Kernel::key_passes(ctx, portable)?.into()
        };
        Ok(KeyKernel { passes })
    }

    /// The key kernel of registry row `id` ([`KeyKernel::new`] of its name; see
    /// [`Kernel::of`]).
    pub fn of(ctx: &GpuContext, id: KernelId) -> Result<KeyKernel> {
        Self::new(ctx, id.name())
    }

    /// The first pass: its layout makes the bind groups, its workgroup size the grid.
    pub fn first(&self) -> &Kernel {
        &self.passes[0]
    }
}

/// The workgroup grid for a 2-D grid-stride loop over an image of `[x, y]` tiles (one
/// workgroup each), `cap` being [`GpuContext::grid_workgroups_cap`]:
///
/// - a GPU (`cpu_adapter` false): one workgroup per tile, so one thread per pixel, each
///   dimension clamped to `cap` (the per-dimension limit; the loop covers any rest);
/// - a CPU adapter (lavapipe): one column of workgroups, one per band of tile rows up to
///   `cap` bands, each walking its band left to right. lavapipe pays per workgroup, and
///   walking a band keeps each core's reads and writes moving along whole rows: at 640x480
///   the six per-pixel kernels took 0.62-0.82x their time in 80x60 tiles in 60 bands
///   (4 to 60 bands measured alike), and a grid of several workgroups across a band
///   (4x60, 16x60, 80x3) was slower than one.
///
/// Empty stays empty (a zero in either dimension).
pub fn image_grid([x, y]: [u32; 2], cap: u32, cpu_adapter: bool) -> [u32; 2] {
    match cpu_adapter {
        true => [x.min(1), y.min(cap)],
        false => [x.min(cap), y.min(cap)],
    }
}

/// A buffer binding of type `ty` (no dynamic offset, no minimum size).
fn buffer(ty: wgpu::BufferBindingType) -> wgpu::BindingType {
    wgpu::BindingType::Buffer {
        ty,
        has_dynamic_offset: false,
        min_binding_size: None,
    }
}

/// A sampled 2D texture binding (not multisampled).
fn texture(sample_type: wgpu::TextureSampleType) -> wgpu::BindingType {
    wgpu::BindingType::Texture {
        sample_type,
        view_dimension: wgpu::TextureViewDimension::D2,
        multisampled: false,
    }
}

/// The explicit bind-group layout entries of reflected bindings, compute stage only.
fn layout_entries(bindings: &[ReflectedBinding]) -> Vec<wgpu::BindGroupLayoutEntry> {
    bindings
        .iter()
        .map(|b| wgpu::BindGroupLayoutEntry {
            binding: b.binding,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: b.ty,
            count: None,
        })
        .collect()
}

/// The layout entry type naga's reflection of one WGSL global asks for (uniform, storage
/// read / read_write, sampled 2D texture of f32 or u32, 2D storage texture with format and
/// access), or a sentence saying why the kernels cannot use it.
fn reflected_type(
    module: &naga::Module,
    g: &naga::GlobalVariable,
) -> Result<wgpu::BindingType, String> {
    match g.space {
        naga::AddressSpace::Uniform => Err(
            "a uniform buffer: declare it `var<storage, read>` (lavapipe recompiles a kernel \
             after every write of a uniform; see ReflectedBinding)"
                .into(),
        ),
        naga::AddressSpace::Storage { access } => Ok(buffer(wgpu::BufferBindingType::Storage {
            read_only: !access.contains(naga::StorageAccess::STORE),
        })),
        naga::AddressSpace::Handle => match &module.types[g.ty].inner {
            naga::TypeInner::Image {
                dim: naga::ImageDimension::D2,
                arrayed: false,
                class,
            } => match class {
                naga::ImageClass::Sampled {
                    kind: naga::ScalarKind::Float,
                    multi: false,
                } => Ok(texture(wgpu::TextureSampleType::Float {
                    filterable: false,
                })),
                naga::ImageClass::Sampled {
                    kind: naga::ScalarKind::Uint,
                    multi: false,
                } => Ok(texture(wgpu::TextureSampleType::Uint)),
                naga::ImageClass::Storage { format, access } => {
                    let format = match format {
                        naga::StorageFormat::Rgba32Float => wgpu::TextureFormat::Rgba32Float,
                        naga::StorageFormat::Rgba32Uint => wgpu::TextureFormat::Rgba32Uint,
                        other => return Err(format!("unsupported storage format {other:?}")),
                    };
                    let access = match (
                        access.contains(naga::StorageAccess::LOAD),
                        access.contains(naga::StorageAccess::STORE),
                    ) {
                        (true, true) => wgpu::StorageTextureAccess::ReadWrite,
                        (false, true) => wgpu::StorageTextureAccess::WriteOnly,
                        _ => wgpu::StorageTextureAccess::ReadOnly,
                    };
                    Ok(wgpu::BindingType::StorageTexture {
                        access,
                        format,
                        view_dimension: wgpu::TextureViewDimension::D2,
                    })
                }
                other => Err(format!("unsupported image class {other:?}")),
            },
            other => Err(format!("unsupported handle type {other:?}")),
        },
        other => Err(format!("unsupported binding space {other:?}")),
    }
}

/// The interface of kernel `name`'s WGSL as naga reflects it: its `@group(0)
/// @binding(i)` globals in binding order, with the layout type each asks for, and
/// `@workgroup_size(x, y)` of its `@compute fn main`. `Err` lists every problem at once,
/// one sentence each naming the kernel and the binding: a parse error, no `main`, a
/// three-dimensional workgroup, a group other than 0, a binding declared twice, a type the
/// kernels cannot bind. Needs no device (`tests/it/bindings.rs` runs it on every kernel).
pub fn reflect(
    name: &str,
    wgsl: &str,
) -> std::result::Result<(Vec<ReflectedBinding>, [u32; 2]), Vec<String>> {
    let module = naga::front::wgsl::parse_str(wgsl).map_err(|e| {
        vec![format!(
            "kernel `{name}` does not parse:\n{}",
            e.emit_to_string(wgsl)
        )]
    })?;
    let mut problems = Vec::new();
    let mut bindings: Vec<ReflectedBinding> = Vec::new();
    for (_, g) in module.global_variables.iter() {
        let Some(rb) = g.binding.as_ref() else {
            continue;
        };
        let var = g.name.clone().unwrap_or_default();
        if rb.group != 0 {
            problems.push(format!(
                "kernel `{name}` binding {} (`{var}`): @group({}), only @group(0) is used",
                rb.binding, rb.group
            ));
            continue;
        }
        if bindings.iter().any(|b| b.binding == rb.binding) {
            problems.push(format!(
                "kernel `{name}` binding {} (`{var}`): declared twice",
                rb.binding
            ));
            continue;
        }
        match reflected_type(&module, g) {
            Ok(ty) => bindings.push(ReflectedBinding {
                binding: rb.binding,
                name: var,
                ty,
            }),
            Err(why) => problems.push(format!(
                "kernel `{name}` binding {} (`{var}`): {why}",
                rb.binding
            )),
        }
    }
    bindings.sort_by_key(|b| b.binding);
    let size = match module
        .entry_points
        .iter()
        .find(|e| e.name == "main" && e.stage == naga::ShaderStage::Compute)
    {
        None => {
            problems.push(format!("kernel `{name}` has no `@compute fn main`"));
            [0, 0]
        }
        Some(entry) => {
            let [x, y, z] = entry.workgroup_size;
            if z != 1 {
                problems.push(format!(
                    "kernel `{name}`: only one- and two-dimensional workgroups are supported"
                ));
            }
            [x, y]
        }
    };
    match problems.is_empty() {
        true => Ok((bindings, size)),
        false => Err(problems),
    }
}

#[cfg(test)]
mod tests {
    use super::image_grid;

    /// A GPU gets one workgroup per tile up to the per-dimension cap; a CPU adapter one
    /// column of band workgroups up to the cap; empty grids stay empty.
    #[test]
    fn image_grids() {
        // 640x480 in 8x8 tiles.
        assert_eq!(image_grid([80, 60], 65535, false), [80, 60]);
        assert_eq!(image_grid([80, 60], 256, true), [1, 60]);
        // More bands than the cap: the loop strides over the rest.
        assert_eq!(image_grid([600, 500], 256, true), [1, 256]);
        assert_eq!(image_grid([70000, 3], 65535, false), [65535, 3]);
        assert_eq!(image_grid([0, 60], 256, true), [0, 60]);
        assert_eq!(image_grid([80, 0], 65535, false), [80, 0]);
    }
}
