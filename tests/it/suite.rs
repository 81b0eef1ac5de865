//! The test suite's own wiring: every test lives in the one crate `tests/it` and runs under
//! the harness of `tests/it/common/harness.rs`. With `harness = false`, a `#[test]` function
//! is compiled out without a word, a file that no `mod` declares is never compiled, and a
//! new file directly in `tests/` would be its own test binary under libtest, where a test
//! without a GPU or data would pass silently; all three are caught here. No GPU needed.

use crate::common;

use std::path::{Path, PathBuf};

use common::harness::plain;

pub fn tests() -> Vec<common::harness::Test> {
    vec![plain(
        "every_test_file_is_a_module_under_the_harness",
        every_test_file_is_a_module_under_the_harness,
    )]
}

/// The files under `dir` whose extension is one of `extensions`, recursively, sorted (also
/// for `kernel_places`).
pub fn files_under(dir: &Path, extensions: &[&str]) -> Vec<PathBuf> {
    let mut files = Vec::new();
    for entry in std::fs::read_dir(dir).expect("directory is readable") {
        let path = entry.expect("directory entry").path();
        if path.is_dir() {
            files.extend(files_under(&path, extensions));
        } else if path
            .extension()
            .is_some_and(|e| extensions.iter().any(|x| e == *x))
        {
            files.push(path);
        }
    }
    files.sort();
    files
}

fn every_test_file_is_a_module_under_the_harness() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let it = root.join("tests/it");
    let mut failures = Vec::new();
    for entry in std::fs::read_dir(root.join("tests")).expect("tests/ is readable") {
        let path = entry.expect("directory entry").path();
        if path != it {
            failures.push(format!(
                "{}: every test belongs in tests/it (a module of the one test crate `it`)",
                path.strip_prefix(root).unwrap_or(&path).display()
            ));
        }
    }
    let files = files_under(&it, &["rs"]);
    for path in &files {
        let shown = path
            .strip_prefix(root)
            .unwrap_or(path)
            .display()
            .to_string();
        let text = std::fs::read_to_string(path).expect("test file is readable");
        if let Some(line) = text.lines().position(|l| l.trim() == "#[test]") {
            failures.push(format!(
                "{shown}:{}: #[test] never runs under this harness; list the function in the \
                 module's tests() (common::harness::plain / gpu / shared)",
                line + 1
            ));
        }
        // The file that must declare this one: `main.rs` or the directory's `mod.rs`.
        let stem = path.file_stem().unwrap().to_string_lossy().to_string();
        let dir = path.parent().unwrap();
        let (parent, module) = match stem.as_str() {
            "main" if dir == it => continue,
            "mod" => {
                let up = dir.parent().unwrap();
                let name = dir.file_name().unwrap().to_string_lossy().to_string();
                let parent = if up == it {
                    it.join("main.rs")
                } else {
                    up.join("mod.rs")
                };
                (parent, name)
            }
            _ if dir == it => (it.join("main.rs"), stem),
            _ => (dir.join("mod.rs"), stem),
        };
        let declared = std::fs::read_to_string(&parent).is_ok_and(|p| {
            p.lines().any(|l| {
                l.trim().strip_prefix("pub ").unwrap_or(l.trim()) == format!("mod {module};")
            })
        });
        if !declared {
            failures.push(format!(
                "{shown}: no `mod {module};` in {}, so it is never compiled",
                parent.strip_prefix(root).unwrap_or(&parent).display()
            ));
        }
    }
    eprintln!("{} files in tests/it", files.len());
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
