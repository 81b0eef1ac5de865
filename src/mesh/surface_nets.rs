//! The zero level set of a [`SparseGrid`] TSDF as a triangle mesh, by surface nets.
//!
//! A cell is the cube between eight voxel centres (origin voxel `v`, corners `v + d` for
//! `d` in {0,1}^3). A cell whose corners are all known (weight at least `min_weight`) and
//! do not all have the same sign gets one vertex: the mean of the points where the field
//! crosses zero on its edges (linear interpolation), with the colour interpolated there.
//! Each edge between two known voxels of opposite signs is shared by four cells; when all
//! four have a vertex they make a quad (two triangles), oriented so that it faces the
//! positive side (where the surfel normals point). No lookup tables, and no triangle
//! crosses an unknown region: the mesh stops where the map stops.

use std::collections::HashMap;
use std::hash::BuildHasherDefault;

use glam::Vec3;

use super::tsdf::{KeyHasher, SparseGrid, Voxel};
use super::{Mesh, MeshParams};

/// The twelve edges of a cell as pairs of corner numbers (`dx + 2 dy + 4 dz`).
const CELL_EDGES: [(usize, usize); 12] = [
    (0, 1),
    (2, 3),
    (4, 5),
    (6, 7),
    (0, 2),
    (1, 3),
    (4, 6),
    (5, 7),
    (0, 4),
    (1, 5),
    (2, 6),
    (3, 7),
];

fn add(a: [i32; 3], b: [i32; 3]) -> [i32; 3] {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

fn sub(a: [i32; 3], b: [i32; 3]) -> [i32; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn unit(axis: usize) -> [i32; 3] {
    let mut e = [0; 3];
    e[axis] = 1;
    e
}

/// A voxel whose value counts: touched with at least `min_weight`.
fn known(grid: &SparseGrid, v: [i32; 3], min_weight: f32) -> Option<Voxel> {
    grid.get(v).filter(|x| x.weight >= min_weight).copied()
}

/// The vertex of the cell at `origin`: position (metres) and colour, or `None` when a
/// corner is unknown or the field does not change sign in it.
fn cell_vertex(grid: &SparseGrid, origin: [i32; 3], min_weight: f32) -> Option<(Vec3, Vec3)> {
    let mut corners = [Voxel::default(); 8];
    for (c, corner) in corners.iter_mut().enumerate() {
        let d = [(c & 1) as i32, ((c >> 1) & 1) as i32, ((c >> 2) & 1) as i32];
        *corner = known(grid, add(origin, d), min_weight)?;
    }
    let inside = corners.map(|v| v.sdf() < 0.0);
    if inside.iter().all(|&s| s) || inside.iter().all(|&s| !s) {
        return None;
    }
    let corner_pos = |c: usize| Vec3::new((c & 1) as f32, ((c >> 1) & 1) as f32, (c >> 2) as f32);
    let (mut pos, mut col, mut count) = (Vec3::ZERO, Vec3::ZERO, 0.0f32);
    for (a, b) in CELL_EDGES {
        if inside[a] == inside[b] {
            continue;
        }
        let (da, db) = (corners[a].sdf(), corners[b].sdf());
        // Opposite signs, so da - db is not zero.
        let t = da / (da - db);
        pos += corner_pos(a).lerp(corner_pos(b), t);
        col += corners[a].color().lerp(corners[b].color(), t);
        count += 1.0;
    }
    let o = Vec3::new(origin[0] as f32, origin[1] as f32, origin[2] as f32);
    let p = (o + pos / count) * grid.voxel_m;
    // A mesh file never holds NaN: a field that overflowed makes no vertex.
    (p.is_finite() && col.is_finite()).then_some((p, col / count))
}

/// Extracts the mesh of `grid` (see the module header). Deterministic: vertices and
/// triangles come in the grid's voxel order.
pub fn extract(grid: &SparseGrid, params: &MeshParams) -> Mesh {
    let min_weight = params.min_weight;
    let mut mesh = Mesh::default();
    let mut vertex_of: HashMap<[i32; 3], u32, BuildHasherDefault<KeyHasher>> = HashMap::default();
    // Every cell with all corners known has a touched origin voxel.
    for (v, _) in grid.touched() {
        if let Some((p, c)) = cell_vertex(grid, v, min_weight) {
            vertex_of.insert(v, mesh.positions.len() as u32);
            mesh.positions.push(p.into());
            let rgb = c.round().clamp(Vec3::ZERO, Vec3::splat(255.0));
            mesh.colors.push([rgb.x as u8, rgb.y as u8, rgb.z as u8]);
        }
    }
    for (a, va) in grid.touched() {
        if va.weight < min_weight {
            continue;
        }
        for axis in 0..3 {
            let Some(vb) = known(grid, add(a, unit(axis)), min_weight) else {
                continue;
            };
            let (a_inside, b_inside) = (va.sdf() < 0.0, vb.sdf() < 0.0);
            if a_inside == b_inside {
                continue;
            }
            // The four cells around the edge a -> a + e_axis, in turn around it: with
            // (u, v) the next two axes, the cells at a, a - e_u, a - e_u - e_v, a - e_v.
            let (eu, ev) = (unit((axis + 1) % 3), unit((axis + 2) % 3));
            let cells = [a, sub(a, eu), sub(sub(a, eu), ev), sub(a, ev)];
            let ids: Option<Vec<u32>> = cells.iter().map(|c| vertex_of.get(c).copied()).collect();
            let Some(q) = ids else {
                continue;
            };
            // That turn faces +e_axis: right when the field grows along the axis.
            let quad = if a_inside {
                [q[0], q[1], q[2], q[3]]
            } else {
                [q[3], q[2], q[1], q[0]]
            };
            mesh.triangles.push([quad[0], quad[1], quad[2]]);
            mesh.triangles.push([quad[0], quad[2], quad[3]]);
        }
    }
    mesh
}
