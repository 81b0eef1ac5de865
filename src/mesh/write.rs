//! A [`Mesh`] as bytes (binary little-endian PLY with vertex colours, or Wavefront OBJ
//! with the common `v x y z r g b` colour extension) and as a file written completely or
//! not at all. The byte forms need no file system (the browser build's downloads).

use std::io::Write;
use std::path::Path;

use super::Mesh;
use crate::io::atomic::write_atomic;
use crate::{Error, Result};

/// Which file format: OBJ for a `.obj` extension (any case), PLY otherwise.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MeshFormat {
    Ply,
    Obj,
}

impl MeshFormat {
    /// The format a path's extension asks for.
    pub fn of_path(path: &Path) -> MeshFormat {
        let obj = path
            .extension()
            .and_then(|e| e.to_str())
            .is_some_and(|e| e.eq_ignore_ascii_case("obj"));
        if obj {
            MeshFormat::Obj
        } else {
            MeshFormat::Ply
        }
    }
}

/// Binary little-endian PLY: `element vertex` with `float x y z` (world frame, metres) and
/// `uchar red green blue`, then `element face` with `list uchar int vertex_indices`.
pub fn ply_bytes(mesh: &Mesh) -> Vec<u8> {
    let header = format!(
        "ply\nformat binary_little_endian 1.0\ncomment wgslam mesh (world frame, metres)\n\
         element vertex {}\nproperty float x\nproperty float y\nproperty float z\n\
         property uchar red\nproperty uchar green\nproperty uchar blue\n\
         element face {}\nproperty list uchar int vertex_indices\nend_header\n",
        mesh.positions.len(),
        mesh.triangles.len()
    );
    let mut out =
        Vec::with_capacity(header.len() + 15 * mesh.positions.len() + 13 * mesh.triangles.len());
    out.extend_from_slice(header.as_bytes());
    for (p, c) in mesh.positions.iter().zip(&mesh.colors) {
        for v in p {
            out.extend_from_slice(&v.to_le_bytes());
        }
        out.extend_from_slice(c);
    }
    for t in &mesh.triangles {
        out.push(3);
        for &i in t {
            out.extend_from_slice(&(i as i32).to_le_bytes());
        }
    }
    out
}

/// Wavefront OBJ text: `v x y z r g b` (colours 0..1) per vertex, `f a b c` (1-based) per
/// triangle.
pub fn obj_bytes(mesh: &Mesh) -> Vec<u8> {
    let mut out = Vec::with_capacity(48 * mesh.positions.len() + 24 * mesh.triangles.len());
    out.extend_from_slice(b"# wgslam mesh (world frame, metres)\n");
    for (p, c) in mesh.positions.iter().zip(&mesh.colors) {
        let rgb = c.map(|x| x as f32 / 255.0);
        // Writing into a Vec cannot fail.
        let _ = writeln!(
            out,
            "v {} {} {} {:.4} {:.4} {:.4}",
            p[0], p[1], p[2], rgb[0], rgb[1], rgb[2]
        );
    }
    for t in &mesh.triangles {
        let _ = writeln!(out, "f {} {} {}", t[0] + 1, t[1] + 1, t[2] + 1);
    }
    out
}

/// Writes `mesh` at `path` in the format its extension asks for ([`MeshFormat::of_path`]),
/// completely or not at all. Refuses a mesh whose vertex count does not fit PLY's `int`
/// indices.
pub fn write_mesh(path: &Path, mesh: &Mesh) -> Result<()> {
    if mesh.positions.len() > i32::MAX as usize {
        return Err(Error::Capacity(format!(
            "{} mesh vertices do not fit 32-bit indices",
            mesh.positions.len()
        )));
    }
    let bytes = match MeshFormat::of_path(path) {
        MeshFormat::Ply => ply_bytes(mesh),
        MeshFormat::Obj => obj_bytes(mesh),
    };
    write_atomic(path, |w| {
        w.write_all(&bytes).map_err(|e| Error::write(path, e))
    })
}
