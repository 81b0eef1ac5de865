//! How well a mesh fits the points it was made from: the distance of each mesh vertex to
//! the nearest map point (does the mesh invent surface?) and of each map point to the mesh
//! (does the mesh cover the map?), as mean, median and 95th percentile in millimetres.
//!
//! With the points' normals (surfels), each vertex's distance to the nearest surfel's
//! plane is given too: on a map whose points are a centimetre apart, the distance to the
//! nearest point mostly measures that spacing, the distance to its plane how far the mesh
//! is off the surface.
//!
//! Point-to-mesh distances are exact distances to the triangles around the point's
//! nearest mesh vertex (a KD-tree over the vertices): exact where the nearest triangle
//! touches the nearest vertex, which holds on meshes whose triangles are about as large as
//! their vertex spacing (surface nets). A map point near a hole's rim measures its
//! distance to the rim.

use glam::Vec3;
use serde::Serialize;

use super::Mesh;
use crate::scan::nn::{KdTreeTarget, NearestNeighbours};
use crate::{Error, Result};

/// Summary of one set of distances, millimetres.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct DistanceStats {
    pub mean_mm: f64,
    pub median_mm: f64,
    pub p95_mm: f64,
}

impl DistanceStats {
    /// The summary of the finite values of `metres` (at least one); non-finite ones are
    /// left out, so one damaged point cannot make the mean 1e21 mm.
    pub fn of_metres(mut metres: Vec<f64>) -> DistanceStats {
        metres.retain(|d| d.is_finite());
        assert!(!metres.is_empty(), "no finite distances to summarise");
        metres.sort_by(f64::total_cmp);
        let at = |q: f64| metres[((metres.len() - 1) as f64 * q).round() as usize] * 1e3;
        DistanceStats {
            mean_mm: metres.iter().sum::<f64>() / metres.len() as f64 * 1e3,
            median_mm: at(0.5),
            p95_mm: at(0.95),
        }
    }
}

/// A mesh measured against a point set.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct MeshAccuracy {
    pub vertices: usize,
    pub triangles: usize,
    /// Mesh vertex to nearest point.
    pub vertex_to_points: DistanceStats,
    /// Mesh vertex to the plane of the nearest point (given normals).
    pub vertex_to_plane: Option<DistanceStats>,
    /// Point to nearest mesh triangle (see the module header).
    pub points_to_mesh: DistanceStats,
    /// Fraction of the points within `covered_within_mm` of the mesh.
    pub covered_fraction: f64,
    pub covered_within_mm: f64,
}

/// The closest point to `p` on the segment from `a` to `b`.
fn closest_on_segment(p: Vec3, a: Vec3, b: Vec3) -> Vec3 {
    let ab = b - a;
    let len_sq = ab.length_squared();
    if len_sq <= f32::MIN_POSITIVE {
        return a;
    }
    a + ab * ((p - a).dot(ab) / len_sq).clamp(0.0, 1.0)
}

/// The closest point to `p` on triangle `(a, b, c)`: `p`'s projection onto the triangle's
/// plane when it falls inside, else the closest point of the nearest edge (for a convex
/// polygon the nearest point then lies on its boundary).
pub fn closest_on_triangle(p: Vec3, a: Vec3, b: Vec3, c: Vec3) -> Vec3 {
    let edges = [(a, b), (b, c), (c, a)];
    let n = (b - a).cross(c - a);
    let n_sq = n.length_squared();
    if n_sq > f32::MIN_POSITIVE {
        let q = p - n * ((p - a).dot(n) / n_sq);
        if edges
            .iter()
            .all(|&(u, v)| n.dot((v - u).cross(q - u)) >= 0.0)
        {
            return q;
        }
    }
    edges
        .iter()
        .map(|&(u, v)| closest_on_segment(p, u, v))
        .min_by(|x, y| x.distance_squared(p).total_cmp(&y.distance_squared(p)))
        .expect("three edges")
}

/// The points (and normals) of `points` whose position (and normal) is finite: the ones
/// a measurement can use (a NaN point made the nearest-neighbour search panic).
fn finite_points(
    points: &[[f32; 3]],
    normals: Option<&[[f32; 3]]>,
) -> (Vec<[f32; 3]>, Option<Vec<[f32; 3]>>) {
    let finite = |p: &[f32; 3]| p.iter().all(|c| c.is_finite());
    let keep: Vec<usize> = (0..points.len())
        .filter(|&i| finite(&points[i]) && normals.is_none_or(|n| finite(&n[i])))
        .collect();
    (
        keep.iter().map(|&i| points[i]).collect(),
        normals.map(|n| keep.iter().map(|&i| n[i]).collect()),
    )
}

/// Measures `mesh` against `points` (metres, the mesh's frame) and, when given, their unit
/// `normals` (one per point); `covered_within_mm` is the distance up to which a point
/// counts as covered. Points with a non-finite position or normal are left out.
pub fn measure(
    mesh: &Mesh,
    points: &[[f32; 3]],
    normals: Option<&[[f32; 3]]>,
    covered_within_mm: f64,
) -> Result<MeshAccuracy> {
    if normals.is_some_and(|n| n.len() != points.len()) {
        return Err(Error::Argument("one normal per point needed".into()));
    }
    let (points, normals) = finite_points(points, normals);
    let (points, normals) = (&points[..], normals.as_deref());
    if mesh.is_empty() || points.is_empty() {
        return Err(Error::Argument(
            "cannot measure an empty mesh or against no points with finite coordinates".into(),
        ));
    }
    if mesh.positions.iter().flatten().any(|c| !c.is_finite()) {
        return Err(Error::Argument(
            "cannot measure a mesh with a non-finite vertex".into(),
        ));
    }
    let to_points = KdTreeTarget::new(points)?;
    let mut nn = vec![(0u32, 0f32); mesh.positions.len()];
    to_points.nearest(&mesh.positions, &mut nn)?;
    let vertex_to_points =
        DistanceStats::of_metres(nn.iter().map(|x| (x.1 as f64).sqrt()).collect());
    let vertex_to_plane = normals.map(|normals| {
        let d = mesh.positions.iter().zip(&nn).map(|(v, &(i, _))| {
            let i = i as usize;
            let off = Vec3::from(*v) - Vec3::from(points[i]);
            off.dot(Vec3::from(normals[i])).abs() as f64
        });
        DistanceStats::of_metres(d.collect())
    });

    // Triangles around each vertex (CSR).
    let mut start = vec![0usize; mesh.positions.len() + 1];
    for t in &mesh.triangles {
        for &i in t {
            start[i as usize + 1] += 1;
        }
    }
    for i in 0..mesh.positions.len() {
        start[i + 1] += start[i];
    }
    let mut fill = start.clone();
    let mut around = vec![0u32; start[mesh.positions.len()]];
    for (ti, t) in mesh.triangles.iter().enumerate() {
        for &i in t {
            around[fill[i as usize]] = ti as u32;
            fill[i as usize] += 1;
        }
    }
    let to_vertices = KdTreeTarget::new(&mesh.positions)?;
    let mut nv = vec![(0u32, 0f32); points.len()];
    to_vertices.nearest(points, &mut nv)?;
    let v = |i: u32| Vec3::from(mesh.positions[i as usize]);
    let dists: Vec<f64> = points
        .iter()
        .zip(&nv)
        .map(|(p, &(vi, d_sq))| {
            let p = Vec3::from(*p);
            let best = around[start[vi as usize]..start[vi as usize + 1]]
                .iter()
                .map(|&ti| {
                    let t = mesh.triangles[ti as usize];
                    closest_on_triangle(p, v(t[0]), v(t[1]), v(t[2])).distance_squared(p)
                })
                .fold(d_sq, f32::min);
            (best as f64).sqrt()
        })
        .collect();
    let covered = dists
        .iter()
        .filter(|&&d| d * 1e3 <= covered_within_mm)
        .count();
    Ok(MeshAccuracy {
        vertices: mesh.positions.len(),
        triangles: mesh.triangles.len(),
        vertex_to_points,
        vertex_to_plane,
        points_to_mesh: DistanceStats::of_metres(dists),
        covered_fraction: covered as f64 / points.len() as f64,
        covered_within_mm,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Float slack of the closest-point checks, metres (values of order 1).
    const EPS: f32 = 1e-6;

    #[test]
    fn closest_point_inside_on_edges_and_at_corners() {
        let (a, b, c) = (Vec3::ZERO, Vec3::X, Vec3::Y);
        let near = |p: Vec3, want: Vec3| {
            let got = closest_on_triangle(p, a, b, c);
            assert!(got.distance(want) < EPS, "{p}: got {got}, want {want}");
        };
        near(Vec3::new(0.2, 0.3, 0.7), Vec3::new(0.2, 0.3, 0.0)); // above the inside
        near(Vec3::new(0.5, -1.0, 0.3), Vec3::new(0.5, 0.0, 0.0)); // beyond edge ab
        near(Vec3::new(1.0, 1.0, -0.2), Vec3::new(0.5, 0.5, 0.0)); // beyond edge bc
        near(Vec3::new(-1.0, -1.0, 0.0), a); // beyond corner a
        near(Vec3::new(2.0, -0.5, 0.0), b); // beyond corner b
                                            // A degenerate triangle (all on a line) measures to the segment.
        let got = closest_on_triangle(Vec3::new(0.5, 1.0, 0.0), a, b, b);
        assert!(got.distance(Vec3::new(0.5, 0.0, 0.0)) < EPS, "{got}");
    }

    #[test]
    fn distance_stats_percentiles() {
        let s = DistanceStats::of_metres((1..=100).map(|i| i as f64 * 1e-3).collect());
        assert_eq!((s.median_mm.round(), s.p95_mm.round()), (51.0, 95.0));
        assert!((s.mean_mm - 50.5).abs() < 1e-9);
    }
}
