//! Where each kernel is named in the code (comments and unit tests left out): its base
//! places ([`base_places`]: its registry row, its shader, its twin and the twin's `pub mod`
//! line, its plan call and the CPU backend's side of it; tests anywhere), and the places of
//! [`OWN_PLACES`], each with its reason; a kernel of a `generic` row has none in the GPU
//! engine. A kernel named anywhere else fails, and so does an entry of [`OWN_PLACES`] that
//! no longer names its kernel (drop it). This is the count `docs/extending.md` gives. No
//! GPU needed.

use crate::common;

use std::path::Path;

use crate::suite::files_under;
use common::harness::plain;
use wgslam::gpu::shaders;

pub fn tests() -> Vec<common::harness::Test> {
    vec![plain(
        "each_kernel_is_named_in_its_places_alone",
        each_kernel_is_named_in_its_places_alone,
    )]
}

/// `(kernel, files, why)`: the places besides its base places where a kernel is named. A
/// kernel of a `generic` row has none in the GPU engine (`crates/gpu/src/`).
const OWN_PLACES: &[(&str, &[&str], &str)] = &[
    (
        "bilateral_filter",
        &["src/slam/bilateral_quality.rs"],
        "the filter-quality check runs its twin on the host",
    ),
    (
        "photo_reduce",
        &[
            "src/slam/step_params.rs",
            "crates/core/src/cpu/predict_model.rs",
        ],
        "its twin's constants are the photometric term's",
    ),
    (
        "prefix_sum_reduce",
        &[
            "crates/core/src/cpu/prefix_sum.rs",
            "crates/core/src/cpu/prefix_sum_blocks.rs",
        ],
        "the scan's other twins share its Hillis-Steele scan, and `cpu::prefix_sum::scan` \
         runs the three twins in order (the parity tests' reference)",
    ),
    (
        "prefix_sum_blocks",
        &["crates/core/src/cpu/prefix_sum.rs"],
        "`cpu::prefix_sum::scan` runs the three twins in order",
    ),
    (
        "icp_candidates",
        &["src/slam/instrumented.rs"],
        "its step is timed under its name",
    ),
];

/// A kernel's places that every kernel has: its registry row, shader, twin (and the twin's
/// `pub mod` line), its plan call, and the CPU backend's side of it.
fn base_places(kernel: &str, file: &str) -> bool {
    file == "crates/core/src/registry.rs"
        || file == format!("shaders/{kernel}.wgsl")
        || file == format!("crates/core/src/cpu/{kernel}.rs")
        || file == "crates/core/src/cpu/mod.rs"
        || file == "crates/core/src/plan.rs"
        || file.starts_with("crates/core/src/cpu_backend/")
}

/// A file's code: each line without its `//` comment (doc comments too), and nothing from
/// the first `#[cfg(test)]` on (unit tests name kernels freely).
fn code_of(text: &str) -> String {
    let text = text.split("#[cfg(test)]").next().unwrap_or_default();
    text.lines()
        .map(|l| l.split("//").next().unwrap_or_default())
        .collect::<Vec<_>>()
        .join("\n")
}

/// True when `code` has `word` with no identifier character on either side.
fn names(code: &str, word: &str) -> bool {
    let is_ident = |c: char| c.is_ascii_alphanumeric() || c == '_';
    code.match_indices(word).any(|(i, _)| {
        let before = code[..i].chars().next_back();
        let after = code[i + word.len()..].chars().next();
        !before.is_some_and(is_ident) && !after.is_some_and(is_ident)
    })
}

fn each_kernel_is_named_in_its_places_alone() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let files: Vec<(String, String)> = ["src", "crates", "shaders", "python/src", "examples"]
        .iter()
        .filter(|d| root.join(d).is_dir())
        .flat_map(|d| files_under(&root.join(d), &["rs", "wgsl"]))
        .map(|p| {
            let shown = p.strip_prefix(root).unwrap_or(&p).display().to_string();
            let text = std::fs::read_to_string(&p).expect("source file is readable");
            (shown, code_of(&text))
        })
        .collect();
    let kernels: Vec<&str> = shaders::KERNELS
        .iter()
        .map(|(name, _)| *name)
        .filter(|name| shaders::file_of(name) == *name)
        .collect();
    let mut failures = Vec::new();
    for &kernel in &kernels {
        let own = OWN_PLACES.iter().find(|(k, _, _)| *k == kernel);
        let generic = shaders::GENERIC_KERNELS.contains(&kernel);
        match (generic, own) {
            (true, Some((_, own_files, _))) => {
                for file in own_files
                    .iter()
                    .filter(|f| f.starts_with("crates/gpu/src/"))
                {
                    failures.push(format!(
                        "{kernel}: a `generic` row is bound and dispatched by its row alone; \
                         nothing else in the GPU engine names it ({file})"
                    ));
                }
            }
            (false, None) => failures.push(format!(
                "{kernel}: neither a `generic` row nor an OWN_PLACES entry"
            )),
            _ => {}
        }
        let own_files: &[&str] = own.map_or(&[], |(_, f, _)| f);
        let named: Vec<&str> = files
            .iter()
            .filter(|(_, code)| names(code, kernel))
            .map(|(f, _)| f.as_str())
            .collect();
        for file in &named {
            if !base_places(kernel, file) && !own_files.contains(file) {
                failures.push(format!(
                    "{kernel} is named in {file}: a kernel is named by its registry row, \
                     shader, twin, plan call and tests, and a kernel that fits no `Shape` \
                     also by its places in OWN_PLACES (tests/it/kernel_places.rs)"
                ));
            }
        }
        for file in own_files {
            if !named.contains(file) {
                failures.push(format!(
                    "{kernel}: {file} no longer names it; drop it from OWN_PLACES"
                ));
            }
        }
    }
    for (i, (kernel, _, _)) in OWN_PLACES.iter().enumerate() {
        if OWN_PLACES[..i].iter().any(|(k, _, _)| k == kernel) {
            failures.push(format!("OWN_PLACES lists `{kernel}` twice"));
        }
        if !kernels.contains(kernel) {
            failures.push(format!(
                "OWN_PLACES lists `{kernel}`, which is not a kernel"
            ));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
