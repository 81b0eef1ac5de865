//! Parses and validates every `shaders/*.wgsl` with naga, without a GPU.
//!
//! Each kernel is checked as the runtime builds it (`common.wgsl` + kernel, through
//! `wgslam::gpu::shaders::source`), both variants of each key kernel included (the 64-bit
//! one and its portable variant, composed from one file and `key_writer.wgsl`), and
//! `common.wgsl` is also checked alone so its errors show up even before any kernel exists.
//! All failures are reported at once, each with the file and line it comes from.

use crate::common;

use std::path::Path;

use common::harness::plain;
use common::wgsl;
use wgslam::gpu::shaders;

/// [`wgsl::check`] with the capabilities the kernels need.
fn check(label: &str, source: &str, origin: impl Fn(usize) -> (String, usize)) -> Option<String> {
    wgsl::check(label, source, wgsl::kernel_capabilities(), origin)
}

fn every_shader_parses_and_validates() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("shaders");
    let mut failures = Vec::new();

    for (prefix, text) in shaders::PREFIXES {
        if let Some(f) = check(&format!("{prefix}.wgsl alone"), text, |l| {
            (format!("shaders/{prefix}.wgsl"), l)
        }) {
            failures.push(f);
        }
    }

    let mut on_disk: Vec<String> = std::fs::read_dir(&dir)
        .expect("shaders/ directory exists")
        .filter_map(|e| {
            let p = e.expect("readable directory entry").path();
            (p.extension()? == "wgsl").then(|| p.file_stem()?.to_str().map(str::to_string))?
        })
        .filter(|name| !shaders::PREFIXES.iter().any(|(p, _)| p == name))
        .filter(|name| name != shaders::KEY_WRITER_FILE)
        .filter(|name| !shaders::ENTRIES.iter().any(|(e, _)| e == name))
        .collect();
    on_disk.sort();
    // key_writer.wgsl is not valid alone (it writes the key kernel's index_map): it is
    // checked inside both variants of every key kernel below.
    let key_writer = format!("{}.wgsl", shaders::KEY_WRITER_FILE);
    if std::fs::read_to_string(dir.join(&key_writer))
        .ok()
        .as_deref()
        != Some(shaders::KEY_WRITER)
    {
        failures.push(format!(
            "shaders/{key_writer}: missing or differs from the embedded copy (rebuild)"
        ));
    }

    // The entry files are not valid alone either (each calls its kernel's function): they
    // are checked inside every kernel that names them.
    for (entry, text) in shaders::ENTRIES {
        if std::fs::read_to_string(dir.join(format!("{entry}.wgsl")))
            .ok()
            .as_deref()
            != Some(text)
        {
            failures.push(format!(
                "shaders/{entry}.wgsl: missing or differs from the embedded copy (rebuild)"
            ));
        }
    }
    for name in &on_disk {
        let Some(embedded) = shaders::kernel_text(name) else {
            failures.push(format!(
                "shaders/{name}.wgsl: not listed in gpu::shaders::KERNELS (it would never run)"
            ));
            continue;
        };
        let file = std::fs::read_to_string(dir.join(format!("{name}.wgsl")))
            .expect("kernel file is readable");
        if file != embedded {
            failures.push(format!(
                "shaders/{name}.wgsl: differs from the embedded copy (rebuild)"
            ));
        }
    }
    // Every kernel the runtime builds, so both variants of every key kernel.
    for (name, _) in shaders::KERNELS {
        let file = shaders::file_of(name);
        if !on_disk.iter().any(|n| n == file) {
            failures.push(format!(
                "gpu::shaders::KERNELS lists `{name}` but shaders/{file}.wgsl is missing"
            ));
            continue;
        }
        if let Some(f) = check(name, &shaders::source(name), |l| {
            shaders::origin_of_line(name, l)
        }) {
            failures.push(f);
        }
    }

    assert!(
        failures.is_empty(),
        "{} shader failure(s):\n\n{}",
        failures.len(),
        failures.join("\n\n")
    );
    eprintln!(
        "validated common.wgsl and {} kernel(s) from {} file(s): {:?}",
        shaders::KERNELS.len(),
        on_disk.len(),
        on_disk
    );
}

/// Without 64-bit integers (WebGPU, and adapters without SHADER_INT64): every prefix and
/// every kernel but the 64-bit key kernels validates with no optional capability, and each
/// 64-bit key kernel has a portable variant (the same file without `KEY_64`) that does. The
/// portable variants' `override KEY_PASS` is left unset here (naga validates the module
/// with its overrides).
fn every_kernel_but_the_64_bit_ones_needs_no_capability() {
    let mut failures = Vec::new();
    for (prefix, text) in shaders::PREFIXES {
        if let Some(f) = wgsl::check(
            &format!("{prefix}.wgsl alone"),
            text,
            naga::valid::Capabilities::empty(),
            |l| (format!("shaders/{prefix}.wgsl"), l),
        ) {
            failures.push(f);
        }
    }
    let mut portable = 0;
    for (name, _) in shaders::KERNELS {
        if shaders::needs_int64(name) {
            continue;
        }
        portable += 1;
        if let Some(f) = wgsl::check(
            name,
            &shaders::source(name),
            naga::valid::Capabilities::empty(),
            |l| shaders::origin_of_line(name, l),
        ) {
            failures.push(f);
        }
    }
    for (int64, twin) in shaders::PORTABLE_KERNELS {
        assert!(
            shaders::kernel_text(int64).is_some() && shaders::kernel_text(twin).is_some(),
            "{int64} / {twin}: not both in KERNELS"
        );
        assert_eq!(
            shaders::file_of(twin),
            *int64,
            "{twin}: not composed from shaders/{int64}.wgsl"
        );
        // The 64-bit kernel really needs the capability (else it needs no twin).
        assert!(
            wgsl::check(
                int64,
                &shaders::source(int64),
                naga::valid::Capabilities::empty(),
                |l| shaders::origin_of_line(int64, l)
            )
            .is_some(),
            "{int64} validates without 64-bit integers: drop it from PORTABLE_KERNELS"
        );
    }
    assert!(
        failures.is_empty(),
        "{} kernel(s) need an optional capability:\n\n{}",
        failures.len(),
        failures.join("\n\n")
    );
    eprintln!(
        "{portable} kernels validate without 64-bit integers; {} have portable variants",
        shaders::PORTABLE_KERNELS.len()
    );
}

/// The checker itself reports a broken shader with the right file and line (so a passing
/// run above means something).
fn a_broken_kernel_is_reported_with_file_and_line() {
    let broken =
        "@compute @workgroup_size(64)\nfn main() {\n    let x: u32 = undefined_thing;\n}\n";
    let src = shaders::concat_with_common(broken);
    let msg = check("broken", &src, |l| shaders::origin_of_line("broken", l))
        .expect("an undefined identifier must fail");
    assert!(msg.starts_with("shaders/broken.wgsl:3:"), "got: {msg}");

    let invalid = "@compute @workgroup_size(64)\nfn main() {\n    let x: u32 = 1.5;\n}\n";
    let src = shaders::concat_with_common(invalid);
    assert!(
        check("invalid", &src, |l| shaders::origin_of_line("invalid", l)).is_some(),
        "a type mismatch must fail"
    );
}

pub fn tests() -> Vec<common::harness::Test> {
    vec![
        plain(
            "every_shader_parses_and_validates",
            every_shader_parses_and_validates,
        ),
        plain(
            "every_kernel_but_the_64_bit_ones_needs_no_capability",
            every_kernel_but_the_64_bit_ones_needs_no_capability,
        ),
        plain(
            "a_broken_kernel_is_reported_with_file_and_line",
            a_broken_kernel_is_reported_with_file_and_line,
        ),
    ]
}
