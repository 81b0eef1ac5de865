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
    /// The most memory the volume and its mesh may take, bytes (estimated from the blocks
    /// [`tsdf::count_blocks`] counts before anything is allocated; over it, meshing is
    /// refused).
    pub max_memory_bytes: u64,
}

/// The largest [`MeshParams::voxel_m`]: 1 m. A surfel map is a room or a building seen by
/// a depth camera (0.3-10 m range); at metre voxels no wall is thicker than one cell and
/// the mesh says nothing, and far above it the integration's box arithmetic leaves `f32`
/// (`--voxel 3e38` once made the truncation band infinite).
pub const MAX_VOXEL_M: f32 = 1.0;

/// The smallest [`MeshParams::voxel_m`]: 1 mm, finer than any depth camera resolves.
pub const MIN_VOXEL_M: f32 = 0.001;

/// Default [`MeshParams::max_memory_bytes`]: 4 GiB, half of an 8 GiB laptop. The 7-Scenes
/// map of 300 frames takes about 0.1 GiB at 1 cm voxels; a map spread thin over a large
/// space (300 k surfels over a cubic kilometre once asked for 5 GB) is refused instead of
/// dying on the allocation.
pub const DEFAULT_MAX_MEMORY_BYTES: u64 = 4 << 30;

/// Surfel weights above this are taken as corrupt and the surfel skipped: a fused map's
/// weight counts observations (at most a few thousand), and sums of weights this large over
/// overlapping surfels stay far inside `f32` (an `inf` weight once made NaN vertices).
pub const MAX_SURFEL_WEIGHT: f32 = 1e9;

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
            max_memory_bytes: DEFAULT_MAX_MEMORY_BYTES,
        }
    }
}

impl MeshParams {
    /// Checks that every setting is a positive finite number (the voxel from
    /// [`MIN_VOXEL_M`] to [`MAX_VOXEL_M`]).
    pub fn validate(&self) -> Result<()> {
        if !(MIN_VOXEL_M..=MAX_VOXEL_M).contains(&self.voxel_m) {
            return Err(Error::Argument(format!(
                "mesh voxel size {:?} m must be from {MIN_VOXEL_M} to {MAX_VOXEL_M} m \
                 (the mesh's resolution; 0.01 is the default)",
                self.voxel_m
            )));
        }
        let checks = [
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

    /// Whether surfel `i` can be integrated: a finite position, a unit normal (zero in maps
    /// read from a PLY without normals; NaN in a damaged one) and a weight in
    /// `(0, MAX_SURFEL_WEIGHT]`, and a finite radius when radii are given.
    pub fn usable(&self, i: usize) -> bool {
        let p = glam::Vec3::from(self.positions[i]);
        let n = glam::Vec3::from(self.normals[i]);
        let w = self.weights.map_or(1.0, |w| w[i]);
        let r = self.radii.map_or(0.0, |r| r[i]);
        p.is_finite()
            && (n.length() - 1.0).abs() < 1e-3
            && w > 0.0
            && w <= MAX_SURFEL_WEIGHT
            && r.is_finite()
    }

    /// How many surfels [`Surfels::usable`] turns away (meshing skips them).
    pub fn unusable(&self) -> usize {
        (0..self.positions.len())
            .filter(|&i| !self.usable(i))
            .count()
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
/// when the surfels span no surface (none, or too few to give a cell both signs). Refused,
/// before anything large is allocated, when the memory of the volume's blocks
/// ([`tsdf::count_blocks`]) exceeds `params.max_memory_bytes`.
pub fn mesh_from_surfels(surfels: &Surfels, params: &MeshParams) -> Result<Mesh> {
    params.validate()?;
    surfels.check()?;
    check_volume(surfels, params).map_err(|over| {
        Error::Argument(over.describe(
            surfels.positions.len(),
            params.voxel_m,
            "raise the memory cap or use coarser voxels",
        ))
    })?;
    let grid = tsdf::integrate(surfels, params)?;
    Ok(surface_nets::extract(&grid, params))
}

/// A volume over [`MeshParams::max_memory_bytes`], as [`check_volume`] found it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OverCap {
    /// Blocks the volume needs (counted up to [`COUNT_PAST_CAP`] times the cap's).
    pub blocks: usize,
    /// Whether `blocks` is the whole count (else the volume needs at least these).
    pub complete: bool,
    /// Their memory, bytes (blocks times [`tsdf::BYTES_PER_BLOCK`]).
    pub bytes: u64,
    /// The cap, bytes.
    pub cap: u64,
}

impl OverCap {
    /// The refusal for `surfels` surfels at `voxel_m`, ending with `remedy` (the words of
    /// the interface that set the cap and the voxel).
    pub fn describe(&self, surfels: usize, voxel_m: f32, remedy: &str) -> String {
        format!(
            "meshing {surfels} surfels at {voxel_m} m voxels needs {}{} of memory ({} blocks \
             of {} voxels, with their share of the mesh), over the cap of {}; {remedy}",
            if self.complete {
                "about "
            } else {
                "more than "
            },
            gib(self.bytes),
            self.blocks,
            tsdf::BLOCK_VOXELS,
            gib(self.cap)
        )
    }
}

/// [`check_volume`] counts blocks up to this many times the cap's before it stops: enough
/// to name the real estimate of a map a few times too large, while the count's own set
/// (about 20 bytes a block against the block's 14 KiB) stays near 2 % of the cap.
pub const COUNT_PAST_CAP: usize = 16;

/// Estimates the volume's memory before allocating it ([`tsdf::count_blocks`], stopped
/// at [`COUNT_PAST_CAP`] times the cap): `Err` when over `params.max_memory_bytes`.
pub fn check_volume(surfels: &Surfels, params: &MeshParams) -> std::result::Result<(), OverCap> {
    let cap_blocks = (params.max_memory_bytes / tsdf::BYTES_PER_BLOCK) as usize;
    let stop = cap_blocks.saturating_mul(COUNT_PAST_CAP);
    let blocks = tsdf::count_blocks(surfels, params, stop);
    if blocks <= cap_blocks {
        return Ok(());
    }
    Err(OverCap {
        blocks,
        complete: blocks <= stop,
        bytes: blocks as u64 * tsdf::BYTES_PER_BLOCK,
        cap: params.max_memory_bytes,
    })
}

/// `bytes` for a message: "1.25 GiB" (or MiB below 1 GiB).
pub fn gib(bytes: u64) -> String {
    let b = bytes as f64;
    if b >= (1u64 << 30) as f64 {
        format!("{:.2} GiB", b / (1u64 << 30) as f64)
    } else {
        format!("{:.1} MiB", b / (1u64 << 20) as f64)
    }
}

/// Meshes a fused map with `params` (see [`mesh_from_surfels`]).
pub fn mesh_from_map(map: &SurfelMap, params: &MeshParams) -> Result<Mesh> {
    mesh_from_surfels(&MapSurfels::new(map).surfels(), params)
}
