//! Triangle meshes from the fused surfel map: a truncated signed distance field (TSDF)
//! integrated from the surfels into a sparse voxel grid on the CPU ([`tsdf`]), its zero
//! level set extracted by surface nets ([`surface_nets`]), written as PLY with vertex
//! colours or OBJ ([`write`]) and measured against the map it came from ([`accuracy`]).
//!
//! Not a SLAM stage: nothing here runs per frame or on the GPU; it turns a finished map
//! (in memory, or a `map.ply` read back) into a mesh that MeshLab, Blender or Open3D open.
//! Everything works on slices and returns values, so the browser build can make a mesh
//! and offer its bytes ([`write::ply_bytes`]) without touching a file.
//!
//! Why a TSDF from surfels: each surfel already carries what a depth pixel gives a TSDF
//! (a point on the surface, its normal, its footprint radius and a confidence), so the
//! integration needs no frames and no poses; averaging the signed distances of
//! overlapping surfels smooths the layers that repeated fusion leaves, and truncation
//! keeps the work proportional to the surface area. Surface nets (one vertex per cell
//! with a sign change, one quad per crossed edge) needs no lookup tables and gives a
//! closed, consistently oriented surface wherever the field is known on both sides.
//!
//! Frames and units: the mesh is in the map's world frame, metres; colours RGB 0..255.

pub mod accuracy;
pub mod surface_nets;
pub mod tsdf;
pub mod write;

use crate::layout::map::SurfelMap;
use crate::{Error, Result};

/// A triangle mesh in the world frame: `positions` (metres) and `colors` (RGB 0..255) have
/// one entry per vertex; `triangles` index them, counter-clockwise seen from the side the
/// surfel normals point to (the side the camera saw).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Mesh {
    pub positions: Vec<[f32; 3]>,
    pub colors: Vec<[u8; 3]>,
    pub triangles: Vec<[u32; 3]>,
}

impl Mesh {
    /// True when the mesh has no triangle.
    pub fn is_empty(&self) -> bool {
        self.triangles.is_empty()
    }
}

/// Settings of [`mesh_from_surfels`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MeshParams {
    /// Edge of one voxel, metres: the mesh's resolution (vertices about one voxel apart).
    pub voxel_m: f32,
    /// Signed distances are kept within this many voxels of a surfel's plane.
    pub truncation_voxels: f32,
    /// A surfel reaches voxels within `support_scale * max(radius, voxel_m)` of its centre
    /// along its plane.
    pub support_scale: f32,
    /// Cells whose eight corners have less accumulated weight than this make no vertex
    /// (voxels touched only by the thin edge of one surfel's footprint).
    pub min_weight: f32,
}

/// Default [`MeshParams::voxel_m`]: 1 cm. Measured with `wgslam mesh` on the maps of the
/// bundled frames and of 7-Scenes 0..299 (docs/meshes.md): at 1 cm the median distance of
/// a vertex to its nearest surfel's plane is 0.01 / 0.29 mm and 99 / 91 % of the map lies
/// within 5 mm of the mesh; at 5 mm the surface breaks up on the bundled map (its surfels
/// are 1-2 cm apart: 0.7 triangles per vertex instead of 1.9); at 2 cm the 7-Scenes
/// mesh's 95th percentile to the planes grows from 5.6 to 9.6 mm and its coverage falls
/// to 87 %.
pub const DEFAULT_VOXEL_M: f32 = 0.01;

impl Default for MeshParams {
    fn default() -> Self {
        MeshParams {
            voxel_m: DEFAULT_VOXEL_M,
            truncation_voxels: 3.0,
            support_scale: 1.5,
            min_weight: 0.5,
        }
    }
}

impl MeshParams {
    /// Checks that every setting is a positive finite number (the voxel at least 1 mm).
    pub fn validate(&self) -> Result<()> {
        let checks = [
            ("voxel size", self.voxel_m, 0.001),
            ("truncation", self.truncation_voxels, 1.0),
            ("support scale", self.support_scale, f32::MIN_POSITIVE),
            ("minimum weight", self.min_weight, 0.0),
        ];
        for (what, v, lo) in checks {
            if !(v.is_finite() && v >= lo) {
                return Err(Error::Argument(format!(
                    "mesh {what} {v} must be a finite number of at least {lo}"
                )));
            }
        }
        Ok(())
    }
}

/// Surfels to mesh: one entry per surfel in every slice.
#[derive(Debug, Clone, Copy)]
pub struct Surfels<'a> {
    /// Centres, world frame, metres.
    pub positions: &'a [[f32; 3]],
    /// Unit normals, world frame, pointing to the side the camera saw.
    pub normals: &'a [[f32; 3]],
    /// Colours, RGB 0..255 (grey without).
    pub colors: Option<&'a [[f32; 3]]>,
    /// Disc radii, metres (without, or where 0: the voxel size).
    pub radii: Option<&'a [f32]>,
    /// Confidences (without: 1 each).
    pub weights: Option<&'a [f32]>,
}

impl Surfels<'_> {
    /// Checks that every present slice has one entry per surfel.
    pub fn check(&self) -> Result<()> {
        let n = self.positions.len();
        let lens = [
            ("normals", Some(self.normals.len())),
            ("colors", self.colors.map(<[_]>::len)),
            ("radii", self.radii.map(<[_]>::len)),
            ("weights", self.weights.map(<[_]>::len)),
        ];
        for (what, len) in lens {
            if let Some(len) = len.filter(|&l| l != n) {
                return Err(Error::Argument(format!(
                    "{what} has {len} entries for {n} surfels"
                )));
            }
        }
        Ok(())
    }
}

/// The attributes of a [`SurfelMap`] as slices for [`Surfels`].
#[derive(Debug, Clone, Default)]
pub struct MapSurfels {
    pub positions: Vec<[f32; 3]>,
    pub normals: Vec<[f32; 3]>,
    pub colors: Vec<[f32; 3]>,
    pub radii: Vec<f32>,
    pub weights: Vec<f32>,
}

impl MapSurfels {
    /// Unpacks `map`.
    pub fn new(map: &SurfelMap) -> MapSurfels {
        map.assert_consistent();
        let n = map.len();
        MapSurfels {
            positions: (0..n).map(|i| map.position(i)).collect(),
            normals: (0..n).map(|i| map.normal(i)).collect(),
            colors: (0..n).map(|i| map.color(i)).collect(),
            radii: (0..n).map(|i| map.radius(i)).collect(),
            weights: (0..n).map(|i| map.weight(i)).collect(),
        }
    }

    /// The surfels to mesh.
    pub fn surfels(&self) -> Surfels<'_> {
        Surfels {
            positions: &self.positions,
            normals: &self.normals,
            colors: Some(&self.colors),
            radii: Some(&self.radii),
            weights: Some(&self.weights),
        }
    }
}

/// Meshes `surfels`: integrates the TSDF, then extracts its zero level set. An empty mesh
/// when the surfels span no surface (none, or too few to give a cell both signs).
pub fn mesh_from_surfels(surfels: &Surfels, params: &MeshParams) -> Result<Mesh> {
    params.validate()?;
    surfels.check()?;
    let grid = tsdf::integrate(surfels, params)?;
    Ok(surface_nets::extract(&grid, params))
}

/// Meshes a fused map with `params` (see [`mesh_from_surfels`]).
pub fn mesh_from_map(map: &SurfelMap, params: &MeshParams) -> Result<Mesh> {
    mesh_from_surfels(&MapSurfels::new(map).surfels(), params)
}
