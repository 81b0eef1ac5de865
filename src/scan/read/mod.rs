//! Point-cloud readers for registration: PCD (ascii / binary), PLY (ascii / binary
//! little-endian, xyz only), plain `x y z` text, and KITTI `.bin` float records; plus the
//! 4x4 transform text format used by `--init` and `relative.txt`.
//!
//! Readers keep only x, y, z (metres, as f32); other fields are skipped. NaN / infinite
//! points are dropped and counted in [`CloudStats`](super::cloud::CloudStats). Every
//! malformed file is an [`Error`] naming the file and the line (text) or byte offset
//! (binary). Not supported, with a clear error: PCD `binary_compressed`, big-endian PLY.
//! This is not the general PLY reader of `crate::io::ply` (colours, normals, faces).

use std::path::Path;

use glam::DMat4;

use super::cloud::PointCloud;
use crate::{Error, Result};
use pcd_header::PcdHeader;

mod pcd_header;

/// Reads a cloud, choosing the format from the extension: `.pcd`, `.ply`, `.bin` (KITTI),
/// anything else as `x y z` text (`.txt`, `.xyz`, `.pts`, `.csv`).
pub fn read_cloud(path: &Path) -> Result<PointCloud> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .unwrap_or("")
        .to_ascii_lowercase();
    match ext.as_str() {
        "pcd" => read_pcd(path),
        "ply" => read_ply_xyz(path),
        "bin" => read_kitti_bin(path),
        _ => read_xyz_text(path),
    }
}

/// True when `path` has an extension [`read_cloud`] treats as a point cloud.
pub fn is_cloud_file(path: &Path) -> bool {
    matches!(
        path.extension()
            .and_then(|e| e.to_str())
            .map(|e| e.to_ascii_lowercase())
            .as_deref(),
        Some("pcd" | "ply" | "bin" | "txt" | "xyz" | "pts" | "csv")
    )
}

/// A regular file of bounded size ([`crate::io::input::read_input`]): never `/dev/zero`
/// or a FIFO.
fn read_bytes(path: &Path) -> Result<Vec<u8>> {
    crate::io::input::read_input(path)
}

/// Splits off the next `\n`-terminated line at `*pos`; returns it without `\r\n`.
fn next_line<'a>(bytes: &'a [u8], pos: &mut usize) -> Option<&'a [u8]> {
    if *pos >= bytes.len() {
        return None;
    }
    let start = *pos;
    let end = bytes[start..]
        .iter()
        .position(|&b| b == b'\n')
        .map_or(bytes.len(), |i| start + i);
    *pos = (end + 1).min(bytes.len());
    let mut line = &bytes[start..end];
    if line.last() == Some(&b'\r') {
        line = &line[..line.len() - 1];
    }
    Some(line)
}

/// Scalar type of a binary field.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Scalar {
    F32,
    F64,
    /// Any other type: only its size in bytes matters (it is skipped).
    Other(usize),
}

impl Scalar {
    fn read_le(self, b: &[u8]) -> f32 {
        match self {
            Scalar::F32 => f32::from_le_bytes([b[0], b[1], b[2], b[3]]),
            Scalar::F64 => {
                f64::from_le_bytes([b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]]) as f32
            }
            Scalar::Other(_) => unreachable!("x/y/z are checked to be float fields"),
        }
    }
}

/// Where x, y, z sit in a record: byte offsets (binary) and token indices (ascii).
#[derive(Debug, Clone, Copy)]
struct XyzLayout {
    scalar: [Scalar; 3],
    byte_offset: [usize; 3],
    token_index: [usize; 3],
    record_bytes: usize,
    record_tokens: usize,
}

/// Reads a PCD v0.5-0.7 file with fields `x y z` (f32 or f64) and any others.
pub fn read_pcd(path: &Path) -> Result<PointCloud> {
    let bytes = read_bytes(path)?;
    let mut header = PcdHeader::parse(path, &bytes)?;
    header.check_fields(path)?;
    let n_points = header.point_count(path)?;
    let layout = header.xyz_layout(path)?;
    let (pos, line_no) = (header.data_start, header.lines);
    match header.data.as_str() {
        "ascii" => read_ascii_records(path, &bytes, pos, line_no, n_points, &layout),
        "binary" => read_binary_records(path, &bytes, pos, n_points, &layout),
        "binary_compressed" => Err(Error::format(
            path,
            "PCD `DATA binary_compressed` is unsupported; convert to binary or ascii (e.g. pcl_convert_pcd_ascii_binary)",
        )),
        other => Err(Error::parse(
            path,
            line_no,
            format!("unknown PCD DATA kind `{other}`"),
        )),
    }
}

/// Ascii records, one per line, starting at byte `pos` after header line `line_no`.
fn read_ascii_records(
    path: &Path,
    bytes: &[u8],
    mut pos: usize,
    mut line_no: usize,
    n_points: usize,
    layout: &XyzLayout,
) -> Result<PointCloud> {
    let mut cloud = PointCloud::default();
    // A record takes at least two bytes a value ("0 "): reserve no more than the rest of
    // the file can hold, whatever the header declares.
    let fit = bytes.len().saturating_sub(pos) / (2 * layout.record_tokens).max(1);
    cloud.points.reserve(n_points.min(fit));
    while cloud.stats.records < n_points {
        let Some(raw) = next_line(bytes, &mut pos) else {
            return Err(Error::format(
                path,
                format!(
                    "header promises {n_points} points but the file ends after {} (line {line_no})",
                    cloud.stats.records
                ),
            ));
        };
        line_no += 1;
        let text = std::str::from_utf8(raw)
            .map_err(|_| Error::parse(path, line_no, "line is not text"))?
            .trim();
        if text.is_empty() {
            continue;
        }
        let tokens: Vec<&str> = text.split_whitespace().collect();
        if tokens.len() < layout.record_tokens {
            return Err(Error::parse(
                path,
                line_no,
                format!(
                    "expected {} values, found {}",
                    layout.record_tokens,
                    tokens.len()
                ),
            ));
        }
        let mut p = [0f32; 3];
        for (c, &ti) in p.iter_mut().zip(&layout.token_index) {
            let t = tokens[ti];
            *c = parse_float(t)
                .ok_or_else(|| Error::parse(path, line_no, format!("`{t}` is not a number")))?;
        }
        cloud.push_record(p);
    }
    Ok(cloud)
}

/// Parses a float, accepting `nan` / `inf` spellings (they are dropped later, not errors).
fn parse_float(t: &str) -> Option<f32> {
    t.parse::<f32>().ok()
}

/// Fixed-size little-endian records starting at byte `start`.
fn read_binary_records(
    path: &Path,
    bytes: &[u8],
    start: usize,
    n_points: usize,
    layout: &XyzLayout,
) -> Result<PointCloud> {
    let need = n_points.saturating_mul(layout.record_bytes);
    let have = bytes.len().saturating_sub(start);
    if have < need {
        let full = have / layout.record_bytes.max(1);
        return Err(Error::format(
            path,
            format!(
                "binary data truncated: {n_points} records of {} bytes need {need} bytes from byte offset {start}, file has {have}; record {full} (at byte offset {}) is incomplete",
                layout.record_bytes,
                start + full * layout.record_bytes
            ),
        ));
    }
    let mut cloud = PointCloud::default();
    cloud.points.reserve(n_points);
    for rec in bytes[start..start + need].chunks_exact(layout.record_bytes) {
        let p: [f32; 3] = std::array::from_fn(|axis| {
            layout.scalar[axis].read_le(&rec[layout.byte_offset[axis]..])
        });
        cloud.push_record(p);
    }
    Ok(cloud)
}

/// Reads the vertex positions of a PLY file (ASCII or binary little-endian) with the
/// one PLY reader, [`crate::io::read_ply`]: `x y z` of any scalar type; other vertex
/// properties, elements before the vertices (list properties included) and everything
/// after them are skipped. Non-finite records are dropped and counted.
pub fn read_ply_xyz(path: &Path) -> Result<PointCloud> {
    let ply = crate::io::read_ply(path)?;
    Ok(PointCloud::from_records(ply.positions))
}

/// Reads plain text, one point per line: `x y z [ignored columns...]`, separated by
/// spaces, tabs or commas. Blank lines and `#` comments (whole-line or trailing) are skipped.
pub fn read_xyz_text(path: &Path) -> Result<PointCloud> {
    let bytes = read_bytes(path)?;
    let mut cloud = PointCloud::default();
    let mut pos = 0usize;
    let mut line_no = 0usize;
    while let Some(raw) = next_line(&bytes, &mut pos) {
        line_no += 1;
        let text = std::str::from_utf8(raw)
            .map_err(|_| Error::parse(path, line_no, "line is not UTF-8 text"))?;
        let text = text.split('#').next().unwrap_or("").trim();
        if text.is_empty() {
            continue;
        }
        let tokens: Vec<&str> = text
            .split(|c: char| c.is_whitespace() || c == ',')
            .filter(|s| !s.is_empty())
            .collect();
        if tokens.len() < 3 {
            return Err(Error::parse(
                path,
                line_no,
                format!("expected `x y z`, found {} value(s)", tokens.len()),
            ));
        }
        let mut p = [0f32; 3];
        for (axis, t) in tokens[..3].iter().enumerate() {
            p[axis] = parse_float(t)
                .ok_or_else(|| Error::parse(path, line_no, format!("`{t}` is not a number")))?;
        }
        cloud.push_record(p);
    }
    Ok(cloud)
}

/// Bytes per KITTI Velodyne record: float32 x, y, z, intensity.
const KITTI_RECORD_BYTES: usize = 16;

/// Reads a KITTI-style `.bin`: little-endian float32 records `x y z intensity`.
pub fn read_kitti_bin(path: &Path) -> Result<PointCloud> {
    let bytes = read_bytes(path)?;
    let rem = bytes.len() % KITTI_RECORD_BYTES;
    if rem != 0 {
        let offset = bytes.len() - rem;
        return Err(Error::format(
            path,
            format!(
                "size {} is not a multiple of {KITTI_RECORD_BYTES} (float32 x y z intensity): {rem} trailing byte(s) at byte offset {offset}",
                bytes.len()
            ),
        ));
    }
    let layout = XyzLayout {
        scalar: [Scalar::F32; 3],
        byte_offset: [0, 4, 8],
        token_index: [0, 1, 2],
        record_bytes: KITTI_RECORD_BYTES,
        record_tokens: 4,
    };
    read_binary_records(path, &bytes, 0, bytes.len() / KITTI_RECORD_BYTES, &layout)
}

/// Largest deviation from a rigid transform accepted in a 4x4 text file: `R^T R` vs the
/// identity and the bottom row vs `0 0 0 1`. Files print 6 significant digits (as
/// `relative.txt` does), so the check allows about 10x their rounding.
const RIGID_TOL: f64 = 1e-4;

/// Reads a 4x4 homogeneous transform from text: 16 numbers in row-major order (usually
/// four lines of four), separated by whitespace or commas; `#` starts a comment.
/// The matrix must be rigid (orthonormal rotation, bottom row `0 0 0 1`, within 1e-4);
/// the rotation is re-orthonormalised so rounding in the file does not leak a scale.
pub fn read_matrix4(path: &Path) -> Result<DMat4> {
    let text = crate::io::input::read_input_string(path)?;
    let mut v: Vec<f64> = Vec::with_capacity(16);
    for (i, line) in text.lines().enumerate() {
        let line = line.split('#').next().unwrap_or("");
        for t in line
            .split(|c: char| c.is_whitespace() || c == ',')
            .filter(|s| !s.is_empty())
        {
            let x: f64 = t
                .parse()
                .map_err(|_| Error::parse(path, i + 1, format!("`{t}` is not a number")))?;
            if !x.is_finite() {
                return Err(Error::parse(path, i + 1, format!("`{t}` is not finite")));
            }
            v.push(x);
        }
    }
    if v.len() != 16 {
        return Err(Error::format(
            path,
            format!("a 4x4 transform needs 16 numbers, found {}", v.len()),
        ));
    }
    let m = DMat4::from_cols_array(&[
        v[0], v[4], v[8], v[12], v[1], v[5], v[9], v[13], v[2], v[6], v[10], v[14], v[3], v[7],
        v[11], v[15],
    ]);
    let bottom = [v[12], v[13], v[14], v[15] - 1.0];
    let r = glam::DMat3::from_mat4(m);
    let dev = (r.transpose() * r - glam::DMat3::IDENTITY)
        .to_cols_array()
        .iter()
        .chain(bottom.iter())
        .fold(0.0f64, |a, b| a.max(b.abs()));
    if dev > RIGID_TOL || r.determinant() <= 0.0 {
        return Err(Error::format(
            path,
            format!(
                "not a rigid transform (deviation {dev:.2e}, det {:.4})",
                r.determinant()
            ),
        ));
    }
    let r = crate::geometry::rigid::nearest_rotation(r);
    Ok(crate::geometry::se3::from_rt(r, m.w_axis.truncate()))
}
