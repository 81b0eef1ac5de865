//! Every kernel's binding layout as naga reflects it from the WGSL, without a GPU.
//!
//! The layouts the GPU code creates are these reflections (`gpu::reflect`, used by
//! `Kernel::new`): there is no hand-written table to disagree with. What is checked here is
//! that every kernel of `gpu::shaders::KERNELS` reflects into bindings the kernels can bind
//! (group 0, no uniforms, 2D textures of the formats in use, a `@compute fn main` with a one-
//! or two-dimensional workgroup), every problem of every kernel reported at once, and that
//! the reflection reports a broken declaration by kernel and binding name.

use crate::common;

use common::harness::plain;
use wgslam::cpu::binding::{Access, Slot};
use wgslam::gpu::{self, shaders};
use wgslam_core::registry::KernelId;

fn every_kernel_reflects_into_bindable_layouts() {
    let mut failures = Vec::new();
    let mut bindings = 0;
    for (name, _) in shaders::KERNELS {
        match gpu::reflect(name, &shaders::source(name)) {
            Ok((reflected, _)) => {
                bindings += reflected.len();
                // Bindings are dense from 0, so a kernel's resources are all named.
                for (i, b) in reflected.iter().enumerate() {
                    if b.binding != i as u32 || b.name.is_empty() {
                        failures.push(format!(
                            "kernel `{name}`: binding {} (`{}`) at position {i}",
                            b.binding, b.name
                        ));
                    }
                }
            }
            Err(problems) => failures.extend(problems),
        }
    }
    assert!(
        failures.is_empty(),
        "{} binding problem(s):\n{}",
        failures.len(),
        failures.join("\n")
    );
    eprintln!(
        "reflected {bindings} bindings of {} kernels",
        shaders::KERNELS.len()
    );
}

/// The reflection itself refuses what the kernels cannot bind, naming kernel and binding,
/// all at once (so a passing run above means something).
fn a_broken_declaration_is_reported_by_name() {
    let wgsl = shaders::source("fuse_add")
        .replace(
            "var<storage, read> params: FuseParams",
            "var<uniform> params: FuseParams",
        )
        .replace("@group(0) @binding(9)", "@group(1) @binding(9)");
    let problems = gpu::reflect("fuse_add", &wgsl).expect_err("two broken bindings");
    assert_eq!(problems.len(), 2, "got: {problems:#?}");
    assert!(
        problems[0].starts_with("kernel `fuse_add` binding 0 (`params`): a uniform buffer"),
        "{problems:#?}"
    );
    assert!(
        problems[1].starts_with("kernel `fuse_add` binding 9 (`index_map`): @group(1)"),
        "{problems:#?}"
    );
    let problems = gpu::reflect("fuse_add", "fn main() {}").expect_err("no entry point");
    assert_eq!(problems, ["kernel `fuse_add` has no `@compute fn main`"]);
}

/// Every portable variant of a key kernel shares its kernel's twin: it binds what the
/// kernel binds and adds only the key pass ([`portable_variant_problems`]). Every problem
/// of every variant reported at once.
fn every_portable_variant_shares_its_kernels_twin() {
    let mut failures = Vec::new();
    let mut variants = 0;
    for (name, _) in shaders::KERNELS {
        if shaders::file_of(name) != *name {
            failures.extend(portable_variant_problems(name, shaders::file_of(name)));
            variants += 1;
        }
    }
    assert!(
        variants > 0,
        "no portable variant found: the check checked nothing"
    );
    assert!(failures.is_empty(), "{}", failures.join("\n"));
    eprintln!("{variants} portable variants share their kernels' twins");
}

/// A portable variant `variant` of the key kernel `kernel` binds what the kernel binds, under
/// the same names and numbers, and adds one `override`, `KEY_PASS`, which its twin (the
/// kernel's, `crates/core/src/cpu/<kernel>.rs`) takes inside its key-map arguments
/// (`cpu::key_writer::KeyPass`) rather than as a parameter of its own.
fn portable_variant_problems(variant: &str, kernel: &str) -> Vec<String> {
    let names = |name: &str| {
        gpu::reflect(name, &shaders::source(name)).map(|(reflected, _)| {
            reflected
                .into_iter()
                .map(|b| (b.binding, b.name))
                .collect::<Vec<_>>()
        })
    };
    let (ours, theirs) = match (names(variant), names(kernel)) {
        (Ok(ours), Ok(theirs)) => (ours, theirs),
        (ours, theirs) => {
            return [ours.err(), theirs.err()]
                .into_iter()
                .flatten()
                .flatten()
                .collect()
        }
    };
    let mut problems = Vec::new();
    if ours != theirs {
        problems.push(format!(
            "kernel `{variant}`: bindings {ours:?} differ from `{kernel}`'s {theirs:?}, whose \
             twin it shares"
        ));
    }
    let module = common::wgsl::parse(variant, &shaders::source(variant));
    let overrides: Vec<_> = module
        .overrides
        .iter()
        .filter_map(|(_, o)| o.name.clone())
        .collect();
    if overrides != [shaders::KEY_PASS] {
        problems.push(format!(
            "kernel `{variant}`: overrides {overrides:?}, expected only `{}` (carried by \
             cpu::key_writer::KeyPass)",
            shaders::KEY_PASS
        ));
    }
    problems
}

/// The bindings kernel `name`'s WGSL declares, as [`Slot`]s in `@binding` order: how it
/// uses each (read only unless it may store), and the bytes of an element where WGSL
/// fixes them (a struct's size, an array's stride, a storage texture's texel; a sampled
/// float texture is one of the frame's rgba32float maps; a sampled integer texture's
/// format, the raw depth's or colour's, is the host's: `None`).
fn declared_slots(name: &str) -> Vec<(Slot, Option<usize>)> {
    let module = common::wgsl::parse(name, &shaders::source(name));
    let mut layouter = naga::proc::Layouter::default();
    layouter
        .update(module.to_ctx())
        .expect("naga lays out the module");
    let mut slots: Vec<(u32, Slot, Option<usize>)> = Vec::new();
    for (_, g) in module.global_variables.iter() {
        let Some(binding) = g.binding.as_ref() else {
            continue;
        };
        let stores = |access: naga::StorageAccess| match access.contains(naga::StorageAccess::STORE)
        {
            true => Access::ReadWrite,
            false => Access::Read,
        };
        let (access, bytes) = match (g.space, &module.types[g.ty].inner) {
            (naga::AddressSpace::Storage { access }, naga::TypeInner::Array { stride, .. }) => {
                (stores(access), Some(*stride as usize))
            }
            (naga::AddressSpace::Storage { access }, _) => {
                (stores(access), Some(layouter[g.ty].size as usize))
            }
            (_, naga::TypeInner::Image { class, .. }) => match class {
                naga::ImageClass::Storage { access, format } => {
                    let texel = match format {
                        naga::StorageFormat::Rgba32Float | naga::StorageFormat::Rgba32Uint => 16,
                        other => panic!("kernel `{name}`: no texel size for {other:?}"),
                    };
                    (stores(*access), Some(texel))
                }
                naga::ImageClass::Sampled { kind, .. } => (
                    Access::Read,
                    (*kind == naga::ScalarKind::Float).then_some(16),
                ),
                other => panic!("kernel `{name}`: unexpected image class {other:?}"),
            },
            (space, _) => panic!("kernel `{name}`: unexpected binding space {space:?}"),
        };
        let slot = Slot {
            name: g.name.clone().map_or("", |n| n.leak()),
            access,
            element_bytes: bytes.unwrap_or(0),
        };
        slots.push((binding.binding, slot, bytes));
    }
    slots.sort_by_key(|&(binding, _, _)| binding);
    slots
        .into_iter()
        .map(|(_, slot, bytes)| (slot, bytes))
        .collect()
}

/// `(kernel, binding, why)`: the bindings whose elements are the CPU's own, f64 where the
/// shader's are f32 (twice the bytes; everything else of the binding as declared). A
/// reduction's partial systems and their sum: the CPU sums its rows in f64, and its outputs
/// are those sums bit for bit, whereas the GPU's f32 partials differ from them by rounding
/// (`docs/extending.md`, "The one call shape"). Every entry must name a bound twin's
/// binding that is wider (a stale entry fails).
const CPU_F64: &[(&str, &str, &str)] = &[
    (
        "icp_reduce",
        "partials",
        "the CPU reduces as one workgroup whose sums are f64",
    ),
    (
        "photo_reduce",
        "partials",
        "the CPU reduces as one workgroup whose sums are f64",
    ),
    (
        "icp_reduce_final",
        "partials",
        "it sums the reductions' f64 partials",
    ),
    (
        "icp_reduce_final",
        "system",
        "the CPU's system is the f64 sum of its partials",
    ),
];

/// Bytes of an f32, the shader's element where [`CPU_F64`] lets the twin take an f64.
const F32_BYTES: usize = 4;

/// Where `twin` (the bindings a twin takes) differs from kernel `name`'s declarations:
/// one sentence per binding (an element of [`CPU_F64`] may be an f64 for the shader's f32).
fn slot_problems(name: &str, twin: &[Slot]) -> Vec<String> {
    let declared = declared_slots(name);
    let mut problems = Vec::new();
    for i in 0..declared.len().max(twin.len()) {
        match (declared.get(i), twin.get(i)) {
            (Some((wgsl, bytes)), Some(rust)) => {
                if wgsl.name != rust.name || wgsl.access != rust.access {
                    problems.push(format!(
                        "kernel `{name}` binding {i}: the shader declares `{}` ({:?}), the twin \
                         takes `{}` ({:?})",
                        wgsl.name, wgsl.access, rust.name, rust.access
                    ));
                }
                let widened = CPU_F64.iter().any(|&(k, b, _)| k == name && b == wgsl.name)
                    && *bytes == Some(F32_BYTES)
                    && rust.element_bytes == 2 * F32_BYTES;
                if bytes.is_some_and(|b| b != rust.element_bytes) && !widened {
                    problems.push(format!(
                        "kernel `{name}` binding {i} (`{}`): elements of {} bytes in WGSL, {} in \
                         the twin",
                        wgsl.name, wgsl.element_bytes, rust.element_bytes
                    ));
                }
            }
            (Some((wgsl, _)), None) => problems.push(format!(
                "kernel `{name}`: the twin takes no binding {i} (`{}`)",
                wgsl.name
            )),
            (None, Some(rust)) => problems.push(format!(
                "kernel `{name}`: the twin takes `{}` at {i}, which the shader does not declare",
                rust.name
            )),
            (None, None) => unreachable!(),
        }
    }
    problems
}

/// Every twin in the one call shape (`KernelId::twin`, the registry's `bound` rows) takes
/// the bindings its shader declares as naga reflects them: the same names in `@binding`
/// order, read only where the shader only reads (and writable where it may write), and
/// elements of the shader's size. The CPU engine binds a twin by these names, so a twin that
/// would bind another buffer than its shader fails here. Every mismatch reported at once.
fn every_bound_twin_takes_its_shaders_declarations() {
    let mut failures = Vec::new();
    let mut bound = 0;
    for kernel in KernelId::ALL {
        // A twin's parameters are its bindings (`twin!` takes no other, and returns
        // nothing), so its shader may not have an `override` for the twin to miss.
        let module = common::wgsl::parse(kernel.name(), &shaders::source(kernel.name()));
        for (_, o) in module.overrides.iter() {
            failures.push(format!(
                "kernel `{}` declares `override {}`, which its twin cannot take",
                kernel.name(),
                o.name.as_deref().unwrap_or("?")
            ));
        }
        match kernel.twin() {
            Some(twin) => {
                failures.extend(slot_problems(kernel.name(), twin.bindings));
                bound += 1;
            }
            // Every row names its twin in the one call shape (a row ending in `bound`).
            None => failures.push(format!(
                "`{}`'s row names no twin in the one call shape (end the row in `bound`)",
                kernel.name()
            )),
        }
    }
    for &(kernel, binding, _) in CPU_F64 {
        let slot = KernelId::ALL
            .iter()
            .find(|k| k.name() == kernel)
            .and_then(|k| k.twin())
            .and_then(|twin| twin.bindings.iter().find(|s| s.name == binding));
        if slot.is_none_or(|s| s.element_bytes != 2 * F32_BYTES) {
            failures.push(format!(
                "CPU_F64 names `{kernel}`'s `{binding}`, which is no f64 binding of a bound twin"
            ));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
    eprintln!(
        "{bound} of {} twins in the one call shape match their shaders",
        KernelId::ALL.len()
    );
}

/// The check above sees a twin that binds another buffer than its shader: two bindings
/// swapped, one read-only where the shader writes it, one of another element size (an f64
/// for an f32 too, where [`CPU_F64`] does not allow it, or wider than an f64 where it does).
fn a_twin_binding_another_buffer_is_refused() {
    let twin = KernelId::vertex_to_normal
        .twin()
        .expect("vertex_to_normal is bound");
    let mut swapped = twin.bindings.to_vec();
    swapped.swap(1, 3);
    assert_eq!(slot_problems("vertex_to_normal", &swapped).len(), 2);
    let mut read_only = twin.bindings.to_vec();
    read_only[2].access = Access::Read;
    assert_eq!(slot_problems("vertex_to_normal", &read_only).len(), 1);
    let mut narrow = twin.bindings.to_vec();
    narrow[1].element_bytes = 12;
    assert_eq!(slot_problems("vertex_to_normal", &narrow).len(), 1);
    assert!(slot_problems("vertex_to_normal", twin.bindings).is_empty());
    // An f64 for an f32 only where CPU_F64 says so: icp_candidates' u32 counts are not.
    let twin = KernelId::icp_candidates
        .twin()
        .expect("icp_candidates is bound");
    let mut wide = twin.bindings.to_vec();
    wide[3].element_bytes = 2 * F32_BYTES;
    assert_eq!(slot_problems("icp_candidates", &wide).len(), 1);
    let twin = KernelId::icp_reduce.twin().expect("icp_reduce is bound");
    assert!(slot_problems("icp_reduce", twin.bindings).is_empty());
    let mut wider = twin.bindings.to_vec();
    wider[4].element_bytes = 4 * F32_BYTES;
    assert_eq!(slot_problems("icp_reduce", &wider).len(), 1);
}

pub fn tests() -> Vec<common::harness::Test> {
    vec![
        plain(
            "every_kernel_reflects_into_bindable_layouts",
            every_kernel_reflects_into_bindable_layouts,
        ),
        plain(
            "a_broken_declaration_is_reported_by_name",
            a_broken_declaration_is_reported_by_name,
        ),
        plain(
            "every_portable_variant_shares_its_kernels_twin",
            every_portable_variant_shares_its_kernels_twin,
        ),
        plain(
            "every_bound_twin_takes_its_shaders_declarations",
            every_bound_twin_takes_its_shaders_declarations,
        ),
        plain(
            "a_twin_binding_another_buffer_is_refused",
            a_twin_binding_another_buffer_is_refused,
        ),
    ]
}
