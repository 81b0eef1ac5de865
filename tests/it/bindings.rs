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
use wgslam::gpu::{self, shaders};

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
    ]
}
