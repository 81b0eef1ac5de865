//! The WGSL sources, embedded at build time: two shared prefixes (`shaders/common.wgsl`,
//! `shaders/scan_common.wgsl`) plus one file per kernel.
//!
//! WGSL has no includes, so a kernel's source is its prefix followed by
//! `shaders/<kernel>.wgsl`: `scan_common.wgsl` for the scan kernels ([`SCAN_KERNELS`]),
//! `common.wgsl` for every other. The key kernels ([`PORTABLE_KERNELS`]) are followed by
//! `shaders/key_writer.wgsl` and each built in two variants from that one text by
//! [`preprocess`] (`#ifdef KEY_64`). Kernels of one shape share their entry point
//! ([`ENTRIES`]: the per-pixel grid, the walk over the surfels in view), named by an
//! `#entry` line and appended last. [`source`] builds it all; the runtime (pipeline
//! creation) and the naga tests (`tests/it/shaders.rs`, `tests/it/bindings.rs`) both use
//! it, so what is validated is what runs. This module does not compile anything; see
//! [`super::kernel`].

/// `shaders/common.wgsl`: the structs of `crates/core/src/layout/mod.rs` and the helpers of `crates/core/src/cpu/mod.rs`
/// (dense SLAM and renders).
pub const COMMON: &str = include_str!("../../../shaders/common.wgsl");

/// `shaders/scan_common.wgsl`: the structs of `crates/core/src/layout/scan.rs` and the scan helpers of
/// `crates/core/src/cpu/mod.rs`.
pub const SCAN_COMMON: &str = include_str!("../../../shaders/scan_common.wgsl");

/// The prefix files as `(name, text)` (not kernels: no entry point, no bindings).
pub const PREFIXES: &[(&str, &str)] = &[("common", COMMON), ("scan_common", SCAN_COMMON)];

/// `shaders/key_writer.wgsl`: how a key kernel's `index_map` keeps the larger key, in both
/// variants (mirrors `crates/core/src/cpu/key_writer.rs`). Appended to each key kernel; not a kernel,
/// and not valid alone (it writes the kernel's `index_map`).
pub const KEY_WRITER: &str = include_str!("../../../shaders/key_writer.wgsl");

/// The name of [`KEY_WRITER`]'s file, `shaders/<KEY_WRITER_FILE>.wgsl`.
pub const KEY_WRITER_FILE: &str = "key_writer";

/// The shared entry points as `(name, text of shaders/<name>.wgsl)`: the `main` of every
/// kernel of one shape, appended to a kernel whose file has an `#entry <name>` line (see
/// [`parts`]). Like [`KEY_WRITER`] not valid alone: each calls a function its kernel
/// defines (the file's header says which), and its CPU mirror is the `cpu` function of the
/// same name.
pub const ENTRIES: &[(&str, &str)] = &[
    (
        "pixel_grid",
        include_str!("../../../shaders/pixel_grid.wgsl"),
    ),
    (
        "visible_surfels",
        include_str!("../../../shaders/visible_surfels.wgsl"),
    ),
    (
        "system_grid",
        include_str!("../../../shaders/system_grid.wgsl"),
    ),
];

/// The kernels prefixed with `scan_common.wgsl`, and the key kernels with their portable
/// variants: both made from the kernel registry's rows (`wgslam_core::registry`).
pub use wgslam_core::registry::{PORTABLE_KERNELS, SCAN_KERNELS};

/// The name of the `override` constant that picks a portable kernel's pass (0: the high
/// word, 1: the index word).
pub const KEY_PASS: &str = "KEY_PASS";

/// The [`preprocess`] symbol that picks a key kernel's 64-bit variant.
pub const KEY_64: &str = "KEY_64";

/// True for the kernels that need 64-bit integers (the first of each [`PORTABLE_KERNELS`]).
pub fn needs_int64(kernel_name: &str) -> bool {
    PORTABLE_KERNELS.iter().any(|(k, _)| *k == kernel_name)
}

/// The file a kernel is built from, `shaders/<file_of(name)>.wgsl`: the kernel itself, or
/// for a portable variant the key kernel it is a variant of.
pub fn file_of(kernel_name: &str) -> &str {
    PORTABLE_KERNELS
        .iter()
        .find(|(_, portable)| *portable == kernel_name)
        .map_or(kernel_name, |(kernel, _)| kernel)
}

/// The [`preprocess`] symbols a kernel is built with: [`KEY_64`] for the 64-bit key
/// kernels, none for every other (portable variants included).
pub fn defines_of(kernel_name: &str) -> &'static [&'static str] {
    if needs_int64(kernel_name) {
        &[KEY_64]
    } else {
        &[]
    }
}

/// Every kernel the runtime builds as `(name, text)`: made from the kernel registry's
/// rows (`wgslam_core::registry`), one per kernel pairing its file and its CPU twin.
pub use wgslam_core::registry::{GENERIC_KERNELS, KERNELS};

/// The kernel file's text alone (without `common.wgsl`, not preprocessed), or `None` for an
/// unknown name.
pub fn kernel_text(kernel_name: &str) -> Option<&'static str> {
    KERNELS
        .iter()
        .find(|(name, _)| *name == kernel_name)
        .map(|(_, text)| *text)
}

/// The prefix of a kernel as `(file name without .wgsl, text)`: `scan_common` for
/// [`SCAN_KERNELS`], `common` for every other name (inline test kernels included).
pub fn prefix_of(kernel_name: &str) -> (&'static str, &'static str) {
    if SCAN_KERNELS.contains(&kernel_name) {
        ("scan_common", SCAN_COMMON)
    } else {
        ("common", COMMON)
    }
}

/// The full WGSL of a kernel: its prefix ([`prefix_of`]) followed by its [`parts`].
/// Line numbers are those of the files (see [`origin_of_line`]).
///
/// Panics on an unknown kernel name or a malformed directive: kernel names and files are
/// compile-time constants of this crate, so either is a bug, not a user error.
pub fn source(kernel_name: &str) -> String {
    let body: String = parts(kernel_name)
        .into_iter()
        .map(|(_, text)| text)
        .collect();
    concat(prefix_of(kernel_name).1, &body)
}

/// The files a kernel is composed of after its prefix, in order, each [`preprocess`]ed, as
/// `(file name without .wgsl, text)`: `shaders/<file_of(name)>.wgsl` with
/// [`defines_of`]`(name)`, then [`KEY_WRITER`] for a key kernel (either variant), then the
/// [`ENTRIES`] file its `#entry` line names, these two with the kernel's defines plus its
/// own `#define`s.
///
/// Panics as [`source`] does, and on an `#entry` that [`ENTRIES`] does not list.
pub fn parts(kernel_name: &str) -> Vec<(&str, String)> {
    let text = kernel_text(kernel_name).unwrap_or_else(|| {
        panic!("unknown WGSL kernel `{kernel_name}` (not listed in gpu::shaders::KERNELS)")
    });
    let compose = |file: &str, text: &str, defines: &[&str]| {
        preprocess(text, defines).unwrap_or_else(|e| panic!("shaders/{file}.wgsl: {e}"))
    };
    let file = file_of(kernel_name);
    let kernel = compose(file, text, defines_of(kernel_name));
    let defines: Vec<&str> = (defines_of(kernel_name).iter().copied())
        .chain(kernel.defined.iter().map(String::as_str))
        .collect();
    let mut parts = Vec::new();
    if needs_int64(file) {
        parts.push((
            KEY_WRITER_FILE,
            compose(KEY_WRITER_FILE, KEY_WRITER, &defines).text,
        ));
    }
    if let Some(entry) = &kernel.entry {
        let (name, text) = ENTRIES
            .iter()
            .find(|(name, _)| name == entry)
            .unwrap_or_else(|| {
                panic!("shaders/{file}.wgsl: `#entry {entry}` is not in gpu::shaders::ENTRIES")
            });
        parts.push((name, compose(name, text, &defines).text));
    }
    parts.insert(0, (file, kernel.text));
    parts
}

/// One file [`preprocess`]ed: its text (line for line the file's), and what its own
/// directives asked of the composition.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Preprocessed {
    /// The kept lines; every other line empty.
    pub text: String,
    /// The symbols its kept `#define NAME` lines defined, for the files composed after it.
    pub defined: Vec<String>,
    /// The [`ENTRIES`] file its kept `#entry NAME` line asked for.
    pub entry: Option<String>,
}

/// Composes a variant of a kernel file: the lines between `#ifdef NAME` (or `#ifndef NAME`)
/// and its `#else` or `#endif` are kept where `NAME` is (is not) in `defines` (or defined by
/// an earlier `#define NAME` line of the file), those between `#else` and `#endif`
/// otherwise; directives nest. `#define NAME` and `#entry NAME` are recorded in the result
/// (see [`parts`]). Every directive line and every line left out becomes an empty line, so a
/// line of the result is the same line of the file. A directive is a line whose first
/// non-blank character is `#` (WGSL has no other use for one).
///
/// `Err` names the first malformed line (1-based): an unknown directive, `#else` or
/// `#endif` without `#ifdef`, a second `#entry`, or an `#ifdef` never closed.
pub fn preprocess(text: &str, defines: &[&str]) -> Result<Preprocessed, String> {
    // Per open #ifdef: (whether its current branch is kept, whether it has seen #else).
    let mut open: Vec<(bool, bool)> = Vec::new();
    let mut out = Preprocessed {
        text: String::with_capacity(text.len()),
        defined: Vec::new(),
        entry: None,
    };
    for (n, line) in text.lines().enumerate() {
        let kept = open.iter().all(|&(keep, _)| keep);
        let Some(directive) = line.trim_start().strip_prefix('#') else {
            if kept {
                out.text.push_str(line);
            }
            out.text.push('\n');
            continue;
        };
        let is_defined =
            |name: &str| defines.contains(&name) || out.defined.iter().any(|d| d == name);
        let mut words = directive.split_whitespace();
        match (words.next(), words.next(), words.next()) {
            (Some("ifdef"), Some(name), None) => open.push((is_defined(name), false)),
            (Some("ifndef"), Some(name), None) => open.push((!is_defined(name), false)),
            (Some("else"), None, None) => match open.last_mut() {
                Some((keep, seen_else @ false)) => {
                    *keep = !*keep;
                    *seen_else = true;
                }
                _ => return Err(format!("line {}: `#else` without `#ifdef`", n + 1)),
            },
            (Some("endif"), None, None) => {
                if open.pop().is_none() {
                    return Err(format!("line {}: `#endif` without `#ifdef`", n + 1));
                }
            }
            (Some("define"), Some(name), None) => {
                if kept {
                    out.defined.push(name.to_string());
                }
            }
            (Some("entry"), Some(name), None) => {
                if kept && out.entry.replace(name.to_string()).is_some() {
                    return Err(format!("line {}: a second `#entry`", n + 1));
                }
            }
            _ => {
                return Err(format!(
                    "line {}: unknown directive `{}`",
                    n + 1,
                    line.trim()
                ))
            }
        }
        out.text.push('\n');
    }
    if !open.is_empty() {
        return Err(format!("{} `#ifdef` without `#endif`", open.len()));
    }
    Ok(out)
}

/// `common.wgsl` followed by `kernel_text`, separated by one newline.
pub fn concat_with_common(kernel_text: &str) -> String {
    concat(COMMON, kernel_text)
}

/// `prefix` followed by `kernel_text`, separated by one newline.
fn concat(prefix: &str, kernel_text: &str) -> String {
    let mut s = String::with_capacity(prefix.len() + kernel_text.len() + 1);
    s.push_str(prefix);
    if !prefix.ends_with('\n') {
        s.push('\n');
    }
    s.push_str(kernel_text);
    s
}

/// Lines `common.wgsl` takes at the top of every concatenated dense or render source.
pub fn common_line_count() -> usize {
    COMMON.lines().count()
}

/// Maps a 1-based line of a concatenated source back to `(file, line)`:
/// `("shaders/<prefix>.wgsl", l)` for the prefix, then each of the kernel's [`parts`] in
/// turn (its own file, `key_writer.wgsl`, its entry file), [`preprocess`] keeping line
/// numbers.
pub fn origin_of_line(kernel_name: &str, line: usize) -> (String, usize) {
    let (prefix, text) = prefix_of(kernel_name);
    let mut first = text.lines().count();
    if line <= first {
        return (format!("shaders/{prefix}.wgsl"), line);
    }
    // An inline test kernel (no file): every line after the prefix is its own.
    let parts = match kernel_text(kernel_name) {
        Some(_) => parts(kernel_name),
        None => return (format!("shaders/{kernel_name}.wgsl"), line - first),
    };
    let (last, before) = parts
        .split_last()
        .expect("parts() starts with the kernel's own file");
    for (file, text) in before {
        let n = text.lines().count();
        if line <= first + n {
            return (format!("shaders/{file}.wgsl"), line - first);
        }
        first += n;
    }
    (format!("shaders/{}.wgsl", last.0), line - first)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn line_mapping_splits_at_common() {
        let n = common_line_count();
        assert_eq!(origin_of_line("k", n).0, "shaders/common.wgsl");
        assert_eq!(
            origin_of_line("k", n + 3),
            ("shaders/k.wgsl".to_string(), 3)
        );
        let src = concat_with_common("// first\n");
        assert_eq!(src.lines().nth(n), Some("// first"));
        assert_eq!(
            origin_of_line("render_splat_portable", n + 2).0,
            "shaders/render_splat.wgsl"
        );
        let splat = kernel_text("render_splat").unwrap().lines().count();
        assert_eq!(
            origin_of_line("render_splat_portable", n + splat + 4),
            ("shaders/key_writer.wgsl".to_string(), 4)
        );
        let src = source("render_splat_portable");
        assert_eq!(
            src.lines().nth(n + splat + 3),
            KEY_WRITER.lines().nth(3),
            "line n + splat + 4 of the source is line 4 of key_writer.wgsl"
        );
    }

    #[test]
    fn preprocess_keeps_one_branch_and_every_line_number() {
        let text = "a\n#ifdef K\nk\n  #ifndef J\n  kj\n  #endif\n#else\nnot k\n#endif\nz\n";
        assert_eq!(
            preprocess(text, &["K"]).unwrap().text,
            "a\n\nk\n\n  kj\n\n\n\n\nz\n"
        );
        assert_eq!(
            preprocess(text, &["K", "J"]).unwrap().text,
            "a\n\nk\n\n\n\n\n\n\nz\n"
        );
        assert_eq!(
            preprocess(text, &[]).unwrap().text,
            "a\n\n\n\n\n\n\nnot k\n\nz\n"
        );
    }

    #[test]
    fn define_and_entry_reach_the_parts_composed_after() {
        let text = "#define C\n#ifdef C\nc\n#endif\n#entry grid\n";
        let done = preprocess(text, &[]).unwrap();
        assert_eq!(done.text, "\n\nc\n\n\n");
        assert_eq!(done.defined, ["C"]);
        assert_eq!(done.entry.as_deref(), Some("grid"));
        let skipped = preprocess("#ifdef X\n#define C\n#entry grid\n#endif\n", &[]).unwrap();
        assert!(skipped.defined.is_empty() && skipped.entry.is_none());
        // Every kernel with an entry gets it last, with its own defines: fuse_add's main
        // copies the chunk, vertex_to_normal's does not.
        let n = common_line_count();
        for (kernel, chunk) in [("fuse_add", true), ("vertex_to_normal", false)] {
            let parts = parts(kernel);
            assert_eq!(parts.last().unwrap().0, "pixel_grid", "{kernel}");
            let src = source(kernel);
            assert_eq!(src.contains("let ch = chunk;"), chunk, "{kernel}");
            let own: usize = parts[..parts.len() - 1]
                .iter()
                .map(|(_, t)| t.lines().count())
                .sum();
            assert_eq!(
                origin_of_line(kernel, n + own + 2),
                ("shaders/pixel_grid.wgsl".to_string(), 2)
            );
        }
    }

    #[test]
    fn preprocess_names_the_malformed_line() {
        let cases = [
            ("a\n#if K\n", "line 2: unknown directive `#if K`"),
            ("#else\n", "line 1: `#else` without `#ifdef`"),
            (
                "#ifdef K\n#else\n#else\n#endif\n",
                "line 3: `#else` without `#ifdef`",
            ),
            ("\n#endif\n", "line 2: `#endif` without `#ifdef`"),
            ("#ifdef K\n", "1 `#ifdef` without `#endif`"),
            ("#entry a\n#entry b\n", "line 2: a second `#entry`"),
        ];
        for (text, error) in cases {
            assert_eq!(preprocess(text, &[]).unwrap_err(), error, "{text:?}");
        }
    }

    #[test]
    fn each_key_kernel_has_two_variants_from_one_file() {
        for (kernel, portable) in PORTABLE_KERNELS {
            assert_eq!(file_of(portable), *kernel);
            assert_eq!(kernel_text(kernel), kernel_text(portable));
            let (wide, narrow) = (source(kernel), source(portable));
            let (u64_map, key_pass) = ("array<atomic<u64>>", "override KEY_PASS");
            assert!(
                wide.contains(u64_map) && !wide.contains(key_pass),
                "{kernel}"
            );
            assert!(
                !narrow.contains(u64_map) && narrow.contains(key_pass),
                "{portable}"
            );
            assert!(wide.contains("fn keep_nearer") && narrow.contains("fn keep_nearer"));
            assert_eq!(wide.lines().count(), narrow.lines().count());
        }
    }
}
