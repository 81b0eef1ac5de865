//! A compute kernel: one pipeline, its explicit bind-group layout and its workgroup size,
//! built once from a kernel name (`shaders/<name>.wgsl`, entry point `main`) and the list of
//! its bindings. Dispatch computes nothing itself beyond skipping empty dispatches.
//!
//! Not a scheduler: which kernel runs when, on which buffers, is the backend's business.
//! Layouts are explicit because with `layout: None` bindings an entry point does not use
//! vanish from the derived layout, and bind-group creation then panics.

use super::context::GpuContext;
use super::shaders;
use crate::{Error, Result};

/// What one `@group(0) @binding(i)` is. Bindings are listed in `i` order.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BindingKind {
    /// `var<storage, read> params`: a params struct from `src/layout.rs` in a read-only
    /// storage buffer, not a uniform buffer: lavapipe (Mesa 22.3) inlines the values of a
    /// uniform buffer into the shader and compiles a new variant after every write of
    /// it, keeping each (0.75 MB of JIT code per `icp_reduce` iteration, so a 200-frame
    /// run grew by gigabytes and spent most of its time compiling; measured with
    /// `examples/params_memory.rs`). Storage buffers are not inlined.
    Params,
    /// `var<storage, read>`.
    StorageRead,
    /// `var<storage, read_write>` (including atomics).
    StorageReadWrite,
    /// `var: texture_2d<f32>` read with `textureLoad` (rgba32float, unfilterable).
    TextureF32,
    /// `var: texture_2d<u32>` read with `textureLoad` (r16uint, rgba8uint).
    TextureU32,
    /// `var: texture_storage_2d<FORMAT, write>` or `<FORMAT, read_write>`.
    StorageTexture {
        format: TexelFormat,
        read_write: bool,
    },
}

/// Storage-texture formats the kernels use.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TexelFormat {
    /// `vec4<f32>`: maps, surfel position + weight, surfel colour.
    Rgba32F,
    /// `vec4<u32>`: surfel normal bits + last_frame.
    Rgba32U,
}

impl TexelFormat {
    /// The wgpu texture format.
    pub const fn wgpu(self) -> wgpu::TextureFormat {
        match self {
            TexelFormat::Rgba32F => wgpu::TextureFormat::Rgba32Float,
            TexelFormat::Rgba32U => wgpu::TextureFormat::Rgba32Uint,
        }
    }
}

/// One binding with a label for the layout (what the buffer is, for error messages).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Binding {
    pub kind: BindingKind,
    pub label: &'static str,
}

impl Binding {
    /// A params struct (see [`BindingKind::Params`]).
    pub const fn params(label: &'static str) -> Binding {
        Binding {
            kind: BindingKind::Params,
            label,
        }
    }
    /// A read-only storage array.
    pub const fn read(label: &'static str) -> Binding {
        Binding {
            kind: BindingKind::StorageRead,
            label,
        }
    }
    /// A read-write storage array.
    pub const fn read_write(label: &'static str) -> Binding {
        Binding {
            kind: BindingKind::StorageReadWrite,
            label,
        }
    }
    /// A float texture read with `textureLoad`.
    pub const fn texture_f32(label: &'static str) -> Binding {
        Binding {
            kind: BindingKind::TextureF32,
            label,
        }
    }
    /// An unsigned-integer texture read with `textureLoad`.
    pub const fn texture_u32(label: &'static str) -> Binding {
        Binding {
            kind: BindingKind::TextureU32,
            label,
        }
    }
    /// A write-only rgba32float storage texture.
    pub const fn write_texture(label: &'static str) -> Binding {
        Self::storage_texture(TexelFormat::Rgba32F, false, label)
    }
    /// A storage texture of `format`, write-only or read-write.
    pub const fn storage_texture(
        format: TexelFormat,
        read_write: bool,
        label: &'static str,
    ) -> Binding {
        Binding {
            kind: BindingKind::StorageTexture { format, read_write },
            label,
        }
    }
}

/// A compute pipeline with its bind-group layout (group 0) and `@workgroup_size` (x, y:
/// grid-stride kernels are one-dimensional, per-pixel kernels use 8x8 tiles).
#[derive(Debug)]
pub struct Kernel {
    /// The kernel's name (`shaders/<name>.wgsl`).
    pub name: String,
    pub pipeline: wgpu::ComputePipeline,
    pub bind_group_layout: wgpu::BindGroupLayout,
    /// Threads per workgroup along x, read from the shader's `@workgroup_size`.
    pub workgroup_size: u32,
    /// Threads per workgroup along y (1 for one-dimensional kernels).
    pub workgroup_size_y: u32,
    bindings: Vec<Binding>,
}

impl Kernel {
    /// Builds the kernel `shaders/<name>.wgsl` (with `common.wgsl` prepended). Create every
    /// kernel once: pipeline creation costs 60-130 ms on lavapipe.
    ///
    /// Panics when `bindings` disagree with the shader's declarations (an internal
    /// contract); wgpu validation errors become [`Error::Gpu`].
    pub fn new(ctx: &GpuContext, name: &str, bindings: &[Binding]) -> Result<Kernel> {
        Self::from_source(ctx, name, &shaders::source(name), bindings)
    }

    /// Builds a kernel from full WGSL text (used by [`Kernel::new`] and by tests with
    /// inline shaders).
    pub fn from_source(
        ctx: &GpuContext,
        name: &str,
        wgsl: &str,
        bindings: &[Binding],
    ) -> Result<Kernel> {
        let [workgroup_size, workgroup_size_y] = check_shader_interface(name, wgsl, bindings)?;
        ctx.scoped(&format!("creating kernel `{name}`"), || {
            let entries = layout_entries(bindings);
            let bind_group_layout =
                ctx.device
                    .create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                        label: Some(name),
                        entries: &entries,
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
                    compilation_options: Default::default(),
                    cache: None,
                });
            Ok(Kernel {
                name: name.to_string(),
                pipeline,
                bind_group_layout,
                workgroup_size,
                workgroup_size_y,
                bindings: bindings.to_vec(),
            })
        })
    }

    /// The bindings this kernel was built with, in `@binding` order.
    pub fn bindings(&self) -> &[Binding] {
        &self.bindings
    }

    /// A bind group with `resources[i]` at `@binding(i)`. Panics when the count differs
    /// from the kernel's bindings (an internal contract).
    pub fn bind_group(
        &self,
        ctx: &GpuContext,
        resources: &[wgpu::BindingResource<'_>],
    ) -> wgpu::BindGroup {
        assert_eq!(
            resources.len(),
            self.bindings.len(),
            "kernel `{}`: {} resources for bindings {:?}",
            self.name,
            resources.len(),
            self.bindings
        );
        let entries: Vec<wgpu::BindGroupEntry> = resources
            .iter()
            .enumerate()
            .map(|(i, r)| wgpu::BindGroupEntry {
                binding: i as u32,
                resource: r.clone(),
            })
            .collect();
        ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some(&self.name),
            layout: &self.bind_group_layout,
            entries: &entries,
        })
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

/// The bind-group layout entry type of one binding kind.
fn layout_type(kind: BindingKind) -> wgpu::BindingType {
    match kind {
        BindingKind::Params => buffer(wgpu::BufferBindingType::Storage { read_only: true }),
        BindingKind::StorageRead => buffer(wgpu::BufferBindingType::Storage { read_only: true }),
        BindingKind::StorageReadWrite => {
            buffer(wgpu::BufferBindingType::Storage { read_only: false })
        }
        BindingKind::TextureF32 => texture(wgpu::TextureSampleType::Float { filterable: false }),
        BindingKind::TextureU32 => texture(wgpu::TextureSampleType::Uint),
        BindingKind::StorageTexture { format, read_write } => wgpu::BindingType::StorageTexture {
            access: if read_write {
                wgpu::StorageTextureAccess::ReadWrite
            } else {
                wgpu::StorageTextureAccess::WriteOnly
            },
            format: format.wgpu(),
            view_dimension: wgpu::TextureViewDimension::D2,
        },
    }
}

/// The explicit bind-group layout entries of a binding table: `bindings[i]` at
/// `@binding(i)`, compute stage only. Needs no device, so `tests/it/bindings.rs` checks the
/// very entries [`Kernel::from_source`] creates its layout from.
pub fn layout_entries(bindings: &[Binding]) -> Vec<wgpu::BindGroupLayoutEntry> {
    bindings
        .iter()
        .enumerate()
        .map(|(i, b)| wgpu::BindGroupLayoutEntry {
            binding: i as u32,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: layout_type(b.kind),
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
        naga::AddressSpace::Uniform => Ok(buffer(wgpu::BufferBindingType::Uniform)),
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

/// Every disagreement between the `@group(0) @binding(i)` globals of `wgsl` (reflected by
/// naga) and the layout `entries` built for kernel `name`, one sentence each naming the
/// kernel and the binding: a binding on one side only, a different type (uniform, storage
/// access, texture sample type, storage-texture format or access), a group other than 0,
/// a stage other than compute, an array count. Empty when they agree. A WGSL parse error
/// is one entry.
pub fn layout_mismatches(
    name: &str,
    wgsl: &str,
    entries: &[wgpu::BindGroupLayoutEntry],
) -> Vec<String> {
    let module = match naga::front::wgsl::parse_str(wgsl) {
        Ok(m) => m,
        Err(e) => {
            return vec![format!(
                "kernel `{name}`: WGSL does not parse: {}",
                e.message()
            )]
        }
    };
    let mut problems = Vec::new();
    let mut declared = std::collections::BTreeMap::new();
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
        match reflected_type(&module, g) {
            Ok(ty) => {
                declared.insert(rb.binding, (var, ty));
            }
            Err(why) => problems.push(format!(
                "kernel `{name}` binding {} (`{var}`): {why}",
                rb.binding
            )),
        }
    }
    let mut listed = std::collections::BTreeMap::new();
    for e in entries {
        if listed.insert(e.binding, e).is_some() {
            problems.push(format!(
                "kernel `{name}` binding {}: listed twice in the layout",
                e.binding
            ));
        }
        if e.visibility != wgpu::ShaderStages::COMPUTE {
            problems.push(format!(
                "kernel `{name}` binding {}: layout visibility {:?}, not COMPUTE",
                e.binding, e.visibility
            ));
        }
        if e.count.is_some() {
            problems.push(format!(
                "kernel `{name}` binding {}: layout has an array count",
                e.binding
            ));
        }
    }
    let all: std::collections::BTreeSet<u32> =
        declared.keys().chain(listed.keys()).copied().collect();
    for b in all {
        match (declared.get(&b), listed.get(&b)) {
            (Some((var, wgsl_ty)), Some(e)) if *wgsl_ty != e.ty => problems.push(format!(
                "kernel `{name}` binding {b} (`{var}`): WGSL declares {wgsl_ty:?}, the layout \
                 has {:?}",
                e.ty
            )),
            (Some((var, wgsl_ty)), None) => problems.push(format!(
                "kernel `{name}` binding {b} (`{var}`): declared in WGSL as {wgsl_ty:?}, missing \
                 from the layout"
            )),
            (None, Some(e)) => problems.push(format!(
                "kernel `{name}` binding {b}: in the layout as {:?}, not declared in WGSL",
                e.ty
            )),
            _ => {}
        }
    }
    problems
}

/// Checks `bindings` against the shader's declarations ([`layout_mismatches`]) and returns
/// `@workgroup_size(x, y)` of the entry point `main`.
///
/// A WGSL parse error is [`Error::Gpu`] (it means the embedded shader is broken, which
/// `tests/it/shaders.rs` also catches); a binding mismatch panics (a Rust/WGSL contract bug,
/// which `tests/it/bindings.rs` catches without a GPU).
fn check_shader_interface(name: &str, wgsl: &str, bindings: &[Binding]) -> Result<[u32; 2]> {
    let module = naga::front::wgsl::parse_str(wgsl).map_err(|e| {
        Error::Gpu(format!(
            "kernel `{name}` does not parse:\n{}",
            e.emit_to_string(wgsl)
        ))
    })?;
    let entry = module
        .entry_points
        .iter()
        .find(|e| e.name == "main" && e.stage == naga::ShaderStage::Compute)
        .unwrap_or_else(|| panic!("kernel `{name}` has no `@compute fn main`"));
    let problems = layout_mismatches(name, wgsl, &layout_entries(bindings));
    assert!(
        problems.is_empty(),
        "kernel `{name}`: WGSL bindings differ from the Rust list:\n{}",
        problems.join("\n")
    );
    let [x, y, z] = entry.workgroup_size;
    assert!(
        z == 1,
        "kernel `{name}`: only one- and two-dimensional workgroups are supported"
    );
    Ok([x, y])
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
