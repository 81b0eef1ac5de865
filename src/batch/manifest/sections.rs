//! Parameter keys by section in a manifest's `overrides` (`icp.stop_chi2`,
//! `loop_closure.enabled`: the [`SlamParams`](crate::slam::params::SlamParams) keys that a
//! parameter file sets in its sections, docs/params-file.md), next to the option names
//! (`icp-dist`). A manifest may write one as a quoted dotted key, `"icp.stop_chi2" = 3`, or
//! as a table, `icp = { stop_chi2 = [3, 6] }`; both become the override `icp.stop_chi2`, and
//! a list in either form is a grid axis as for any override. The job's parameter file
//! holds it in its section (`[icp]`, [`insert_dotted`]), where `wgslam run --params` checks
//! it against the field's type and range like any other.

use std::collections::BTreeMap;
use std::path::Path;

use super::{FileToml, OneOrMany};
use crate::slam::params::KEY_SECTIONS;
use crate::{Error, Result};

/// [`flatten_sections`] on the overrides of every table of the manifest `path`; the error
/// names the table.
pub(super) fn flatten_file(path: &Path, file: &mut FileToml) -> Result<()> {
    let jobs = file.job.iter_mut().enumerate();
    let grids = file.grid.iter_mut().enumerate();
    let tables = std::iter::once(("[defaults]".to_string(), &mut file.defaults))
        .chain(jobs.map(|(k, j)| (format!("[[job]] number {}", k + 1), j)))
        .chain(grids.map(|(k, g)| (format!("[[grid]] number {}", k + 1), g)));
    for (origin, fields) in tables {
        flatten_sections(&mut fields.overrides)
            .map_err(|why| Error::format(path, format!("{origin}: {why}")))?;
    }
    Ok(())
}

/// Replaces each section table among `overrides` (`icp = { stop_chi2 = 3 }`) by its keys
/// (`icp.stop_chi2`), nested tables as deeper keys; a list under a key is a grid axis.
/// Errs on a table under a name that is not a section, a key written both ways, or a key
/// a job field sets.
fn flatten_sections(
    overrides: &mut BTreeMap<String, OneOrMany<toml::Value>>,
) -> std::result::Result<(), String> {
    let mut flat = BTreeMap::new();
    for (name, value) in std::mem::take(overrides) {
        let OneOrMany::One(toml::Value::Table(table)) = value else {
            insert_once(&mut flat, name, value)?;
            continue;
        };
        if !KEY_SECTIONS.contains(&name.as_str()) {
            return Err(format!(
                "override `{name}` is a table but not a section; the sections are: {}",
                KEY_SECTIONS.join(", ")
            ));
        }
        let mut keys = Vec::new();
        leaves(&name, table, &mut keys);
        for (key, value) in keys {
            let axis = match value {
                toml::Value::Array(items) => OneOrMany::Many(items),
                scalar => OneOrMany::One(scalar),
            };
            insert_once(&mut flat, key, axis)?;
        }
    }
    *overrides = flat;
    if let Some(key) = overrides
        .keys()
        .find(|k| RESERVED_KEYS.contains(&k.as_str()))
    {
        return Err(format!(
            "override `{key}` is the job field `downsample`; set it as a field, not an override"
        ));
    }
    Ok(())
}

/// Adds override `key`, which must not be there yet (written both as a table's key and as
/// a dotted key).
fn insert_once(
    overrides: &mut BTreeMap<String, OneOrMany<toml::Value>>,
    key: String,
    axis: OneOrMany<toml::Value>,
) -> std::result::Result<(), String> {
    match overrides.contains_key(&key) {
        true => Err(format!("override `{key}` is set twice")),
        false => {
            overrides.insert(key, axis);
            Ok(())
        }
    }
}

/// Section keys a job field sets (`downsample`), which an override may not set again.
const RESERVED_KEYS: [&str; 1] = ["input.downsample"];

/// The leaves of `table`, each keyed `prefix.name` (nested tables as deeper keys).
fn leaves(prefix: &str, table: toml::Table, out: &mut Vec<(String, toml::Value)>) {
    for (name, value) in table {
        let key = format!("{prefix}.{name}");
        match value {
            toml::Value::Table(inner) => leaves(&key, inner, out),
            other => out.push((key, other)),
        }
    }
}

/// Sets `value` at the dotted `key` of `table`: `icp.pyramid.radius_px` goes into the table
/// `icp`'s table `pyramid` (made when missing), as a parameter file's sections hold it.
pub fn insert_dotted(table: &mut toml::Table, key: &str, value: toml::Value) {
    let mut names = key.split('.').peekable();
    let mut table = table;
    while let Some(name) = names.next() {
        if names.peek().is_none() {
            table.insert(name.into(), value);
            return;
        }
        table = table
            .entry(name)
            .or_insert_with(|| toml::Value::Table(Default::default()))
            .as_table_mut()
            .expect("a section is a table (no option name holds a dot)");
    }
}
