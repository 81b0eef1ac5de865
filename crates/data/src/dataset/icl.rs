//! ICL-NUIM TUM-compatible layout: `associations.txt` with `<i> depth/<i>.png <i> rgb/<i>.png`
//! lines and a `*.gt.freiburg` trajectory whose first column is the FRAME INDEX.
//!
//! Only file lists live here; decoding is in [`super::frame`], ground-truth parsing in
//! [`crate::io::trajectory`].

use std::path::{Path, PathBuf};

use crate::io::text::finite_f64;
use crate::{Error, Result};

/// One line of `associations.txt`; paths are relative to the root.
#[derive(Debug, Clone, PartialEq)]
pub struct Association {
    /// The first column (the frame index for ICL-NUIM), used as the frame's stamp.
    pub stamp: f64,
    pub depth_path: PathBuf,
    pub rgb_path: PathBuf,
}

/// Reads `associations.txt` (`depth_stamp depth_path rgb_stamp rgb_path`; `#` comments and
/// blank lines skipped). Errors name `file:line` and quote the line.
pub fn read_associations(path: &Path) -> Result<Vec<Association>> {
    let text = super::source::read_string(path, crate::io::input::InputKind::List)?;
    parse_associations(path, &text)
}

/// [`read_associations`] over the file's text; `path` names it in errors.
pub fn parse_associations(path: &Path, text: &str) -> Result<Vec<Association>> {
    let mut out = Vec::new();
    for (lineno, line) in crate::io::text::data_lines(text) {
        let f: Vec<&str> = line.split_whitespace().collect();
        if f.len() != 4 {
            return Err(Error::parse(
                path,
                lineno,
                format!(
                    "expected 4 fields `<i> depth/<i>.png <i> rgb/<i>.png`, found {}: {line:?}",
                    f.len()
                ),
            ));
        }
        let stamp = finite_f64(f[0]).ok_or_else(|| {
            Error::parse(
                path,
                lineno,
                format!("index {:?} is not a number: {line:?}", f[0]),
            )
        })?;
        out.push(Association {
            stamp,
            depth_path: PathBuf::from(f[1]),
            rgb_path: PathBuf::from(f[3]),
        });
    }
    Ok(out)
}

/// The ground-truth file of an ICL-NUIM directory: its only `*.gt.freiburg`, or `None`.
/// Several candidates are an error (pass the one to use explicitly).
pub fn find_ground_truth(root: &Path) -> Result<Option<PathBuf>> {
    let mut found = Vec::new();
    for path in super::source::list(root).map_err(|e| Error::io(root, e))? {
        let name = path.file_name().unwrap_or_default().to_string_lossy();
        if name.ends_with(".gt.freiburg") && super::source::present(&path) {
            found.push(path);
        }
    }
    found.sort();
    match found.len() {
        0 => Ok(None),
        1 => Ok(found.pop()),
        _ => Err(Error::format(
            root,
            format!(
                "several ground-truth files ({}); choose one with --gt",
                found
                    .iter()
                    .map(|p| p.display().to_string())
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        )),
    }
}
