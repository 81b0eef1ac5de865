//! The test suite's own wiring: every file in `tests/` runs under the harness of
//! `tests/common/harness.rs`. With `harness = false`, a `#[test]` function is compiled out
//! without a word and a file missing from Cargo.toml falls back to libtest, where a test
//! without a GPU or data would pass silently; both are caught here. No GPU needed.

mod common;

use std::path::Path;
use std::process::ExitCode;

use common::harness::plain;

fn main() -> ExitCode {
    common::harness::run(vec![plain(
        "every_test_file_is_registered_with_the_harness",
        every_test_file_is_registered_with_the_harness,
    )])
}

/// The `name`s of the `[[test]]` sections of Cargo.toml that say `harness = false`.
fn harnessless_tests(manifest: &str) -> Vec<String> {
    let mut found = Vec::new();
    for section in manifest.split("\n[").skip(1) {
        if !section.starts_with("[test]]") {
            continue;
        }
        let value = |key: &str| {
            section.lines().find_map(|l| {
                let (k, v) = l.split_once('=')?;
                (k.trim() == key).then(|| v.trim().trim_matches('"').to_string())
            })
        };
        if value("harness").as_deref() == Some("false") {
            found.extend(value("name"));
        }
    }
    found
}

fn every_test_file_is_registered_with_the_harness() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let manifest = std::fs::read_to_string(root.join("Cargo.toml")).expect("Cargo.toml");
    let registered = harnessless_tests(&manifest);
    let mut failures = Vec::new();
    let mut files = Vec::new();
    for dir in ["tests", "tests/common"] {
        for entry in std::fs::read_dir(root.join(dir)).expect("tests/ is readable") {
            let path = entry.expect("directory entry").path();
            if path.extension().is_some_and(|e| e == "rs") {
                files.push((dir, path));
            }
        }
    }
    files.sort();
    for (dir, path) in &files {
        let text = std::fs::read_to_string(path).expect("test file is readable");
        let shown = format!("{dir}/{}", path.file_name().unwrap().to_string_lossy());
        if let Some(line) = text.lines().position(|l| l.trim() == "#[test]") {
            failures.push(format!(
                "{shown}:{}: #[test] never runs under this harness; register the function in \
                 the file's main (common::harness::plain / gpu / shared)",
                line + 1
            ));
        }
        if *dir == "tests" {
            let stem = path.file_stem().unwrap().to_string_lossy().to_string();
            if !registered.contains(&stem) {
                failures.push(format!(
                    "{shown}: no [[test]] name = \"{stem}\" harness = false in Cargo.toml"
                ));
            }
            if !text.contains("common::harness::run(") {
                failures.push(format!("{shown}: main does not call common::harness::run"));
            }
        }
    }
    for name in &registered {
        if !files
            .iter()
            .any(|(d, p)| *d == "tests" && p.file_stem().is_some_and(|s| *s == **name))
        {
            failures.push(format!(
                "Cargo.toml lists [[test]] {name} but tests/{name}.rs is missing"
            ));
        }
    }
    eprintln!(
        "{} test files, {} registered",
        files.len(),
        registered.len()
    );
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
