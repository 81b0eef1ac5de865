//! Frame files named by number (`frame-000012.depth.png`, ScanNet's `12.jpg`, Replica's
//! `depth000012.png`): listing a folder's files of one pattern, ordered by their number as
//! a number (`2` before `10`), not as a string.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use crate::{Error, Result};

/// A file name pattern: `prefix`, then one or more ASCII digits, then `suffix`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Pattern {
    pub prefix: &'static str,
    pub suffix: &'static str,
}

/// Largest accepted frame number: 2^53, the last integer an f64 stamp holds exactly (frames
/// 2^53 and 2^53 + 1 got one stamp; a number beyond u64 was dropped without a word).
pub const MAX_FRAME_NUMBER: u64 = 1 << 53;

impl Pattern {
    /// The pattern `prefix`, digits, `suffix` (for the layouts' `const` patterns).
    pub const fn new(prefix: &'static str, suffix: &'static str) -> Self {
        Self { prefix, suffix }
    }

    /// The digits of `name` when it fits the pattern (whatever their value).
    fn digits<'a>(&self, name: &'a str) -> Option<&'a str> {
        let digits = name.strip_prefix(self.prefix)?.strip_suffix(self.suffix)?;
        (!digits.is_empty() && digits.bytes().all(|b| b.is_ascii_digit())).then_some(digits)
    }

    /// The frame number in `name` when it fits the pattern and is at most
    /// [`MAX_FRAME_NUMBER`].
    pub fn number(&self, name: &str) -> Option<u64> {
        self.digits(name)?
            .parse()
            .ok()
            .filter(|&n| n <= MAX_FRAME_NUMBER)
    }

    /// The pattern as a user reads it, e.g. `frame-N.depth.png`.
    pub fn describe(&self) -> String {
        format!("{}N{}", self.prefix, self.suffix)
    }
}

/// The files in `dir` that fit `pattern`, by frame number, ascending. Two files with the
/// same number (`7.png` and `07.png`) are an error naming both. A missing `dir` lists
/// nothing.
pub fn list(dir: &Path, pattern: Pattern) -> Result<BTreeMap<u64, PathBuf>> {
    let mut out = BTreeMap::new();
    let Ok(entries) = super::source::list(dir) else {
        return Ok(out);
    };
    for path in entries {
        let name = path.file_name().unwrap_or_default().to_string_lossy();
        let Some(n) = pattern.number(&name) else {
            if pattern.digits(&name).is_some() {
                return Err(Error::format(
                    path.clone(),
                    format!(
                        "frame number beyond {MAX_FRAME_NUMBER} (2^53, the largest an f64 stamp \
                         holds exactly); renumber the frames"
                    ),
                ));
            }
            continue;
        };
        if let Some(previous) = out.insert(n, path.clone()) {
            return Err(Error::format(
                dir,
                format!(
                    "two files with frame number {n}: {} and {}",
                    previous.display(),
                    path.clone().display()
                ),
            ));
        }
    }
    Ok(out)
}

/// True when `dir` holds at least one file that fits `pattern` (for layout detection).
pub fn any(dir: &Path, pattern: Pattern) -> bool {
    super::source::list(dir).is_ok_and(|entries| {
        entries.iter().any(|p| {
            let name = p.file_name().unwrap_or_default().to_string_lossy();
            pattern.number(&name).is_some()
        })
    })
}

/// Pairs two numbered lists frame by frame into `(number, colour path, depth path)`, by
/// number; a number in one list but not in the other is an error naming the file that has
/// no partner and both counts.
pub fn pair(
    depth: &BTreeMap<u64, PathBuf>,
    color: &BTreeMap<u64, PathBuf>,
    depth_pattern: Pattern,
    color_pattern: Pattern,
) -> Result<Vec<(u64, PathBuf, PathBuf)>> {
    let lonely = depth
        .iter()
        .find(|(n, _)| !color.contains_key(n))
        .map(|(n, p)| (p, color_pattern, n))
        .or_else(|| {
            color
                .iter()
                .find(|(n, _)| !depth.contains_key(n))
                .map(|(n, p)| (p, depth_pattern, n))
        });
    if let Some((path, missing, n)) = lonely {
        return Err(Error::format(
            path,
            format!(
                "has no partner: {} depth and {} colour images, and frame {n} has no {} file",
                depth.len(),
                color.len(),
                missing.describe()
            ),
        ));
    }
    Ok(depth
        .iter()
        .map(|(&n, d)| (n, color[&n].clone(), d.clone()))
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_parse_only_where_the_pattern_fits() {
        let p = Pattern::new("frame-", ".depth.png");
        assert_eq!(p.number("frame-000012.depth.png"), Some(12));
        assert_eq!(p.number("frame-.depth.png"), None);
        assert_eq!(p.number("frame-12.color.png"), None);
        assert_eq!(p.number("frame-1a.depth.png"), None);
        let bare = Pattern::new("", ".jpg");
        assert_eq!(bare.number("10.jpg"), Some(10));
        assert_eq!(bare.number("+1.jpg"), None);
        assert_eq!(bare.number("9007199254740992.jpg"), Some(MAX_FRAME_NUMBER));
        assert_eq!(bare.number("9007199254740993.jpg"), None);
        assert_eq!(
            bare.digits("99999999999999999999999.jpg"),
            Some("99999999999999999999999")
        );
    }
}
