//! Every kernel's binding table against its WGSL, without a GPU.
//!
//! For each kernel of `gpu::shaders::KERNELS`, naga reflects the `@group(0) @binding(i)`
//! globals of the source the runtime builds (`gpu::shaders::source`) with their kind
//! (uniform, storage read / read_write, texture sample type, storage texture format and
//! access), and `gpu::layout_mismatches` compares them with the bind-group layout entries
//! the GPU code creates (`gpu::layout_entries` of the kernel's table in
//! `gpu::kernel_binding_tables`). Every mismatch of every kernel is reported at once, each
//! naming the kernel and the binding. Until now these tables were only checked when a GPU
//! pipeline was built.

use crate::common;

use common::harness::plain;
use wgslam::gpu::{self, shaders, Binding, TexelFormat};

fn every_kernel_layout_matches_its_wgsl() {
    let tables = gpu::kernel_binding_tables();
    let mut failures = Vec::new();
    for (name, _) in shaders::KERNELS {
        let Some((_, table)) = tables.iter().find(|(n, _)| n == name) else {
            failures.push(format!(
                "kernel `{name}`: no binding table in gpu::kernel_binding_tables"
            ));
            continue;
        };
        failures.extend(gpu::layout_mismatches(
            name,
            &shaders::source(name),
            &gpu::layout_entries(table),
        ));
    }
    for (name, _) in &tables {
        if shaders::kernel_text(name).is_none() {
            failures.push(format!(
                "gpu::kernel_binding_tables lists `{name}`, which is not a kernel"
            ));
        }
    }
    assert!(
        failures.is_empty(),
        "{} binding mismatch(es):\n{}",
        failures.len(),
        failures.join("\n")
    );
    eprintln!("checked the layouts of {} kernels", tables.len());
}

/// The check itself fails on a wrong table, and reports every mismatch at once (so a
/// passing run above means something).
fn a_wrong_table_is_reported_binding_by_binding() {
    // fuse_add's table with binding 3 a read-write buffer instead of read-only, binding 6
    // a storage texture instead of a buffer, and binding 9 (the last) missing.
    let mut wrong = gpu::backend::bindings::FUSE_ADD[..9].to_vec();
    wrong[3] = Binding::read_write("flags");
    wrong[6] = Binding::storage_texture(TexelFormat::Rgba32F, false, "position_weight");
    let problems = gpu::layout_mismatches(
        "fuse_add",
        &shaders::source("fuse_add"),
        &gpu::layout_entries(&wrong),
    );
    assert_eq!(problems.len(), 3, "got: {problems:#?}");
    for (b, var) in [(3, "flags"), (6, "position_weight"), (9, "index_map")] {
        let tag = format!("kernel `fuse_add` binding {b} (`{var}`)");
        assert!(
            problems.iter().any(|p| p.starts_with(&tag)),
            "no report for {tag}: {problems:#?}"
        );
    }

    // A texture format and a sample type.
    let mut wrong = gpu::layout_entries(gpu::backend::bindings::PREDICT_MODEL.as_slice());
    wrong[3].ty = wgpu::BindingType::Texture {
        sample_type: wgpu::TextureSampleType::Float { filterable: false },
        view_dimension: wgpu::TextureViewDimension::D2,
        multisampled: false,
    };
    let wrong_format = Binding::storage_texture(TexelFormat::Rgba32U, false, "pred_vertex");
    wrong[5] = gpu::layout_entries(&[wrong_format])[0];
    wrong[5].binding = 5;
    let problems =
        gpu::layout_mismatches("predict_model", &shaders::source("predict_model"), &wrong);
    assert_eq!(problems.len(), 2, "got: {problems:#?}");
    assert!(problems[0].starts_with("kernel `predict_model` binding 3 (`position_weight`)"));
    assert!(problems[1].starts_with("kernel `predict_model` binding 5 (`pred_vertex`)"));
}

pub fn tests() -> Vec<common::harness::Test> {
    vec![
        plain(
            "every_kernel_layout_matches_its_wgsl",
            every_kernel_layout_matches_its_wgsl,
        ),
        plain(
            "a_wrong_table_is_reported_binding_by_binding",
            a_wrong_table_is_reported_binding_by_binding,
        ),
    ]
}
