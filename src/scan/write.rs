//! Output files of the scan tools, written completely or not at all (temp file in the same
//! directory, then rename): binary little-endian xyz PLY, JSON, text tables.

use std::path::Path;

use glam::DMat4;

use crate::{Error, Result};

/// Writes `bytes` to `path` atomically: a temporary sibling file, flushed, then renamed.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    crate::io::atomic::write_atomic(path, |w| {
        w.write_all(bytes).map_err(|e| Error::write(path, e))
    })
}

/// Encodes points (metres) as a binary little-endian PLY with `float x y z` vertices.
pub fn encode_ply_xyz(points: &[[f32; 3]]) -> Vec<u8> {
    let header = format!(
        "ply\nformat binary_little_endian 1.0\ncomment written by wgslam\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\nend_header\n",
        points.len()
    );
    let mut out = Vec::with_capacity(header.len() + points.len() * 12);
    out.extend_from_slice(header.as_bytes());
    for p in points {
        for c in p {
            out.extend_from_slice(&c.to_le_bytes());
        }
    }
    out
}

/// Writes points (metres) atomically as a binary little-endian xyz PLY.
pub fn write_ply_xyz(path: &Path, points: &[[f32; 3]]) -> Result<()> {
    write_atomic(path, &encode_ply_xyz(points))
}

/// A 4x4 transform as four lines of four numbers (row-major), readable by
/// [`read_matrix4`](super::read::read_matrix4).
pub fn format_matrix4(t: &DMat4) -> String {
    let mut s = String::new();
    for r in 0..4 {
        let row = t.row(r);
        s.push_str(&format!(
            "{:>14.9} {:>14.9} {:>14.9} {:>14.9}\n",
            row.x, row.y, row.z, row.w
        ));
    }
    s
}

/// Transforms points (metres) by `t` in f64 and rounds back to f32.
pub fn transform_points(t: &DMat4, points: &[[f32; 3]]) -> Vec<[f32; 3]> {
    points
        .iter()
        .map(|p| {
            t.transform_point3(glam::DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64))
                .as_vec3()
                .to_array()
        })
        .collect()
}
