//! Job ids: the id an unnamed job or a grid's combination is given from its values, and
//! the check that an id can name the job's folder and lock file.

use std::collections::BTreeSet;

use super::{option_value, Combination};

/// Every field of a job (an unnamed `[[job]]` is named by all its values).
pub(super) fn all_axes(c: &Combination) -> BTreeSet<String> {
    let mut v: BTreeSet<String> = ["sequence", "frames", "downsample", "profile", "backend"]
        .into_iter()
        .map(String::from)
        .collect();
    v.extend(c.overrides.keys().map(|k| format!("override:{k}")));
    v
}

/// `prefix-value-value...`: the grid's name (or the sequence's folder name) and the values
/// of `axes`, in index order, reduced to `[A-Za-z0-9._=-]`.
pub(super) fn generated_id(
    prefix: Option<&str>,
    c: &Combination,
    axes: &BTreeSet<String>,
) -> String {
    let seq_name = c
        .sequence
        .as_ref()
        .and_then(|s| s.file_name())
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "sequence".into());
    let mut parts = vec![prefix.map(String::from).unwrap_or_else(|| seq_name.clone())];
    let has = |a: &str| axes.contains(a);
    if has("sequence") && prefix.is_some() {
        parts.push(seq_name);
    }
    if has("frames") {
        parts.push(format!("f{}", c.frames.as_deref().unwrap_or("all")));
    }
    if has("downsample") {
        parts.push(format!("ds{}", c.downsample.unwrap_or_default()));
    }
    if has("profile") {
        parts.push(c.profile.clone());
    }
    if has("backend") {
        parts.push(c.backend.clone());
    }
    for (k, v) in &c.overrides {
        if has(&format!("override:{k}")) {
            parts.push(format!("{k}={}", option_value(v).unwrap_or_default()));
        }
    }
    parts
        .join("-")
        .chars()
        .map(|ch| {
            if ch.is_ascii_alphanumeric() || "._=-".contains(ch) {
                ch
            } else {
                '_'
            }
        })
        .collect()
}

/// The longest job id: it names a folder and a lock file, whose names file systems cap
/// at 255 bytes.
pub const MAX_ID_BYTES: usize = 200;

/// Why `id` cannot be a job id (a folder name inside the batch folder), or `None`.
pub(super) fn id_problem(id: &str) -> Option<String> {
    if id.is_empty() || id.starts_with('.') || id.contains(['/', '\\']) {
        return Some(format!("the job name {id:?} cannot be a folder name"));
    }
    if id.chars().any(char::is_control) {
        return Some(format!(
            "the job name {id:?} holds a control character (NUL, newline, ...); it names a folder"
        ));
    }
    if id.len() > MAX_ID_BYTES {
        return Some(format!(
            "the job name is {} bytes long, more than {MAX_ID_BYTES}; it names a folder",
            id.len()
        ));
    }
    None
}
