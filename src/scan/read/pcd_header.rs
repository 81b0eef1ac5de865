//! A PCD file's header ([`read_pcd`](super::read_pcd)): its lines parsed up to `DATA`,
//! FIELDS, SIZE, TYPE and COUNT checked against each other, the number of records, and where
//! x, y and z sit in a record. Not the records themselves (`read_ascii_records`,
//! `read_binary_records` in the parent).

use std::path::Path;

use super::{next_line, Scalar, XyzLayout};
use crate::{Error, Result};

/// A count in a header line: `what`'s value `s` on line `line`.
fn parse_usize(path: &Path, line: usize, s: &str, what: &str) -> Result<usize> {
    s.parse::<usize>()
        .map_err(|_| Error::parse(path, line, format!("{what}: `{s}` is not a count")))
}

/// A PCD file's header, as its lines give it (up to and including `DATA`).
pub(super) struct PcdHeader {
    fields: Vec<String>,
    /// Bytes per value of each field.
    sizes: Vec<usize>,
    /// `F`, `I` or `U` for each field.
    types: Vec<char>,
    /// Values per field (empty when the header has no `COUNT`).
    counts: Vec<usize>,
    points: Option<usize>,
    width: Option<usize>,
    height: Option<usize>,
    /// The `DATA` kind, lower case: `ascii`, `binary`, ...
    pub(super) data: String,
    /// Byte offset of the first record, just after the `DATA` line.
    pub(super) data_start: usize,
    /// Lines in the header, the `DATA` line included.
    pub(super) lines: usize,
}

impl PcdHeader {
    /// Reads the header lines of `bytes` up to `DATA`; comments (`#`) and blank lines are
    /// skipped, an unknown key is an error.
    pub(super) fn parse(path: &Path, bytes: &[u8]) -> Result<Self> {
        let mut pos = 0usize;
        let mut line_no = 0usize;
        let mut fields: Vec<String> = Vec::new();
        let mut sizes: Vec<usize> = Vec::new();
        let mut types: Vec<char> = Vec::new();
        let mut counts: Vec<usize> = Vec::new();
        let mut points: Option<usize> = None;
        let (mut width, mut height) = (None, None);
        let data = loop {
            let Some(raw) = next_line(bytes, &mut pos) else {
                return Err(Error::format(path, "PCD header has no DATA line"));
            };
            line_no += 1;
            let text = std::str::from_utf8(raw)
                .map_err(|_| Error::parse(path, line_no, "PCD header line is not text"))?;
            let text = text.split('#').next().unwrap_or("").trim();
            if text.is_empty() {
                continue;
            }
            let mut tok = text.split_whitespace();
            let key = tok.next().unwrap_or("").to_ascii_uppercase();
            let rest: Vec<&str> = tok.collect();
            match key.as_str() {
                "VERSION" | "VIEWPOINT" => {}
                "FIELDS" => fields = rest.iter().map(|s| s.to_string()).collect(),
                "SIZE" => {
                    sizes = rest
                        .iter()
                        .map(|s| parse_usize(path, line_no, s, "SIZE"))
                        .collect::<Result<_>>()?
                }
                "TYPE" => {
                    types = rest
                        .iter()
                        .map(|s| match s.to_ascii_uppercase().as_str() {
                            "F" => Ok('F'),
                            "I" => Ok('I'),
                            "U" => Ok('U'),
                            other => Err(Error::parse(
                                path,
                                line_no,
                                format!("TYPE `{other}` is not F, I or U"),
                            )),
                        })
                        .collect::<Result<_>>()?
                }
                "COUNT" => {
                    counts = rest
                        .iter()
                        .map(|s| parse_usize(path, line_no, s, "COUNT"))
                        .collect::<Result<_>>()?
                }
                "WIDTH" | "HEIGHT" | "POINTS" => {
                    let v = rest.first().ok_or_else(|| {
                        Error::parse(path, line_no, format!("{key} needs a value"))
                    })?;
                    let n = parse_usize(path, line_no, v, &key)?;
                    match key.as_str() {
                        "WIDTH" => width = Some(n),
                        "HEIGHT" => height = Some(n),
                        _ => points = Some(n),
                    }
                }
                "DATA" => {
                    let kind = rest.first().copied().unwrap_or("").to_ascii_lowercase();
                    break kind;
                }
                other => {
                    return Err(Error::parse(
                        path,
                        line_no,
                        format!("unknown PCD header key `{other}`"),
                    ))
                }
            }
        };
        Ok(Self {
            fields,
            sizes,
            types,
            counts,
            points,
            width,
            height,
            data,
            data_start: pos,
            lines: line_no,
        })
    }

    /// Checks that FIELDS, SIZE, TYPE and COUNT (1 each by default) agree in length and
    /// that every size is 1, 2, 4 or 8 bytes.
    pub(super) fn check_fields(&mut self, path: &Path) -> Result<()> {
        let Self {
            fields,
            sizes,
            types,
            counts,
            ..
        } = self;
        let n_fields = fields.len();
        if n_fields == 0 {
            return Err(Error::format(path, "PCD header has no FIELDS"));
        }
        if counts.is_empty() {
            *counts = vec![1; n_fields];
        }
        if sizes.len() != n_fields || types.len() != n_fields || counts.len() != n_fields {
            return Err(Error::format(
                path,
                format!(
                    "PCD header: FIELDS has {n_fields} entries but SIZE {}, TYPE {}, COUNT {}",
                    sizes.len(),
                    types.len(),
                    counts.len()
                ),
            ));
        }
        if let Some(i) = sizes.iter().position(|s| ![1, 2, 4, 8].contains(s)) {
            return Err(Error::format(
                path,
                format!(
                    "PCD field `{}` has SIZE {}: sizes are 1, 2, 4 or 8 bytes",
                    fields[i], sizes[i]
                ),
            ));
        }
        Ok(())
    }

    /// The number of records: POINTS, else WIDTH x HEIGHT.
    pub(super) fn point_count(&self, path: &Path) -> Result<usize> {
        Ok(match (self.points, self.width, self.height) {
            (Some(p), _, _) => p,
            (None, Some(w), Some(h)) => w.checked_mul(h).ok_or_else(|| {
                Error::format(path, format!("PCD WIDTH {w} x HEIGHT {h} overflows"))
            })?,
            _ => {
                return Err(Error::format(
                    path,
                    "PCD header has neither POINTS nor WIDTH/HEIGHT",
                ))
            }
        })
    }

    /// Where x, y and z sit in a record; they must be float32 or float64 fields.
    pub(super) fn xyz_layout(&self, path: &Path) -> Result<XyzLayout> {
        let (fields, sizes, types, counts) = (&self.fields, &self.sizes, &self.types, &self.counts);
        let mut layout = XyzLayout {
            scalar: [Scalar::F32; 3],
            byte_offset: [0; 3],
            token_index: [0; 3],
            record_bytes: 0,
            record_tokens: 0,
        };
        let mut found = [false; 3];
        for i in 0..fields.len() {
            let scalar = match (types[i], sizes[i]) {
                ('F', 4) => Scalar::F32,
                ('F', 8) => Scalar::F64,
                (_, s) => Scalar::Other(s),
            };
            if let Some(axis) = ["x", "y", "z"].iter().position(|a| *a == fields[i]) {
                if !matches!(scalar, Scalar::F32 | Scalar::F64) {
                    return Err(Error::format(
                        path,
                        format!(
                            "PCD field `{}` has TYPE {} SIZE {}: only float32 / float64 coordinates are supported",
                            fields[i], types[i], sizes[i]
                        ),
                    ));
                }
                // A coordinate without a value would index an empty record (fuzz replay).
                if counts[i] == 0 {
                    return Err(Error::format(
                        path,
                        format!(
                            "PCD field `{}` has COUNT 0: a coordinate needs a value",
                            fields[i]
                        ),
                    ));
                }
                layout.scalar[axis] = scalar;
                layout.byte_offset[axis] = layout.record_bytes;
                layout.token_index[axis] = layout.record_tokens;
                found[axis] = true;
            }
            let overflow = || {
                Error::format(
                    path,
                    format!(
                        "PCD COUNT {} of field `{}` is too large",
                        counts[i], fields[i]
                    ),
                )
            };
            layout.record_bytes = sizes[i]
                .checked_mul(counts[i])
                .and_then(|b| b.checked_add(layout.record_bytes))
                .ok_or_else(overflow)?;
            layout.record_tokens = layout
                .record_tokens
                .checked_add(counts[i])
                .ok_or_else(overflow)?;
        }
        if found.iter().any(|f| !f) {
            return Err(Error::format(
                path,
                format!("PCD FIELDS `{}` lack one of x, y, z", fields.join(" ")),
            ));
        }
        Ok(layout)
    }
}
