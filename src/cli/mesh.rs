//! `wgslam mesh`: arguments and the run function (dispatched from `cli/mod.rs`).
//!
//! Reads a surfel map PLY (a wgslam `map.ply`, or any PLY with positions and normals),
//! meshes it (`crate::mesh`), writes PLY or OBJ, and prints how far the mesh lies from the
//! map's points. Argument checking and printing only.

use std::path::PathBuf;

use web_time::Instant;

use crate::io::ply::{ply_read_bytes, read_ply};
use crate::mesh::accuracy::{measure, DistanceStats, MeshAccuracy};
use crate::mesh::write::{write_mesh, MeshFormat};
use crate::mesh::{
    check_volume, gib, mesh_from_surfels, MeshParams, Surfels, DEFAULT_MAX_MEMORY_BYTES,
    DEFAULT_VOXEL_M,
};
use crate::{Error, Result};

/// Map points within this distance of the mesh count as covered in the printed summary:
/// half the default voxel, the resolution the mesh can claim.
pub const COVERED_WITHIN_MM: f64 = 5.0;

/// `wgslam mesh MAP.ply -o MESH.ply [--voxel M]`
#[derive(Debug, Clone, clap::Args)]
pub struct MeshArgs {
    /// Surfel map to mesh (PLY with vertex x y z and nx ny nz; colours and weights are used
    /// when present).
    pub map: PathBuf,
    /// Output mesh: PLY with vertex colours, or OBJ when the name ends in .obj (written
    /// completely or not at all).
    #[arg(short = 'o', long = "out")]
    pub out: PathBuf,
    /// Voxel edge, metres: the mesh's resolution (0.001 to 1).
    #[arg(long, default_value_t = DEFAULT_VOXEL_M)]
    pub voxel: f32,
    /// Most memory, MiB, that reading the map and its volume may take: estimated before
    /// anything large is allocated, and refused above.
    #[arg(long, value_name = "MIB", default_value_t = DEFAULT_MAX_MEMORY_BYTES >> 20)]
    pub max_memory_mib: u64,
}

/// The remedy a refusal over the memory cap names, in the command's words.
const REMEDY: &str = "raise the cap with --max-memory-mib, or mesh at coarser voxels (--voxel)";

/// What `run_mesh` did, for the caller to print.
#[derive(Debug, Clone)]
pub struct MeshReport {
    pub points: usize,
    pub format: MeshFormat,
    /// Seconds spent meshing (integration and extraction, not reading or writing).
    pub mesh_s: f64,
    /// The mesh against the map's points (`None` for an empty mesh).
    pub accuracy: Option<MeshAccuracy>,
    pub vertices: usize,
    pub triangles: usize,
    /// Points left out: a non-finite position, normal or weight, a normal not unit length,
    /// a weight not positive or implausibly large ([`Surfels::usable`]).
    pub skipped: usize,
}

/// Runs `wgslam mesh`: reads, meshes, writes `args.out`, measures.
pub fn run_mesh(args: &MeshArgs) -> Result<MeshReport> {
    let params = MeshParams {
        voxel_m: args.voxel,
        max_memory_bytes: args.max_memory_mib.saturating_mul(1 << 20),
        ..MeshParams::default()
    };
    params.validate().map_err(|_| {
        Error::Argument(format!(
            "--voxel {:?} must be from {} to {} (metres; the default is {DEFAULT_VOXEL_M})",
            args.voxel,
            crate::mesh::MIN_VOXEL_M,
            crate::mesh::MAX_VOXEL_M
        ))
    })?;
    if let Some(need) = ply_read_bytes(&args.map)?.filter(|&b| b > params.max_memory_bytes) {
        return Err(Error::Argument(format!(
            "{}: reading this map takes about {} of memory, over the cap of {}; raise the \
             cap with --max-memory-mib",
            args.map.display(),
            gib(need),
            gib(params.max_memory_bytes)
        )));
    }
    let ply = read_ply(&args.map)?;
    let normals = ply.normals.as_deref().ok_or_else(|| {
        Error::format(
            &args.map,
            "the PLY has no normals (nx ny nz): a mesh needs each point's surface direction",
        )
    })?;
    let colors: Option<Vec<[f32; 3]>> = ply
        .colors
        .as_ref()
        .map(|c| c.iter().map(|c| c.map(f32::from)).collect());
    let surfels = Surfels {
        positions: &ply.positions,
        normals,
        colors: colors.as_deref(),
        // map.ply stores no radii: each surfel reaches the voxel size (scaled).
        radii: None,
        weights: ply.weights.as_deref(),
    };
    let skipped = surfels.unusable();
    check_volume(&surfels, &params).map_err(|over| {
        Error::Argument(format!(
            "{}: {}",
            args.map.display(),
            over.describe(surfels.positions.len(), args.voxel, REMEDY)
        ))
    })?;
    let start = Instant::now();
    let mesh = mesh_from_surfels(&surfels, &params)?;
    let mesh_s = start.elapsed().as_secs_f64();
    if mesh.is_empty() {
        return Err(Error::Argument(format!(
            "{}: the map's {} points ({skipped} of them unusable) make no surface at {} m \
             voxels (too few, or no normals)",
            args.map.display(),
            ply.positions.len(),
            args.voxel
        )));
    }
    write_mesh(&args.out, &mesh)?;
    let accuracy = Some(measure(
        &mesh,
        &ply.positions,
        Some(normals),
        COVERED_WITHIN_MM,
    )?);
    Ok(MeshReport {
        points: ply.positions.len(),
        format: MeshFormat::of_path(&args.out),
        mesh_s,
        accuracy,
        vertices: mesh.positions.len(),
        triangles: mesh.triangles.len(),
        skipped,
    })
}

/// The printed summary of a mesh's accuracy (also `run --mesh`'s).
pub fn accuracy_lines(a: &MeshAccuracy) -> Vec<String> {
    let s = |d: DistanceStats| {
        format!(
            "mean {:.2} / median {:.2} / p95 {:.2} mm",
            d.mean_mm, d.median_mm, d.p95_mm
        )
    };
    let mut lines = vec![format!(
        "mesh vertex to map point: {}",
        s(a.vertex_to_points)
    )];
    if let Some(p) = a.vertex_to_plane {
        lines.push(format!("mesh vertex to its plane: {}", s(p)));
    }
    lines.push(format!(
        "map point to mesh: {}; {:.1} % within {} mm",
        s(a.points_to_mesh),
        a.covered_fraction * 100.0,
        a.covered_within_mm
    ));
    lines
}

/// `wgslam mesh`: runs and prints.
pub fn execute(args: MeshArgs) -> Result<()> {
    let r = run_mesh(&args)?;
    if r.skipped > 0 {
        println!(
            "note: skipped {} of {} points: a non-finite position, normal or weight, a normal \
             not of unit length, or a weight not in (0, {:e}]",
            r.skipped,
            r.points,
            crate::mesh::MAX_SURFEL_WEIGHT
        );
    }
    println!(
        "meshed {} points at {} m voxels in {:.2} s: {} vertices, {} triangles ({:?})",
        r.points, args.voxel, r.mesh_s, r.vertices, r.triangles, r.format
    );
    if let Some(a) = r.accuracy {
        for line in accuracy_lines(&a) {
            println!("{line}");
        }
    }
    println!("wrote {}", args.out.display());
    Ok(())
}
