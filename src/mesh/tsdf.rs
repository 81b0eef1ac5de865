//! A truncated signed distance field in a sparse voxel grid (blocks of 8x8x8 voxels in a
//! hash map), integrated from surfels on the CPU.
//!
//! Voxel `(i, j, k)` has its centre at `(i, j, k) * voxel_m`, world frame, metres. Each
//! surfel (centre `p`, unit normal `n`, radius `r`, weight `w`) adds to every voxel centre
//! `x` with `|n . (x - p)| <= truncation` and lateral distance `l` from its axis below the
//! support `s = support_scale * max(r, voxel_m)`: the signed distance `n . (x - p)` (metres,
//! positive on the side the normal points to) with the weight `w * (1 - l^2 / s^2)`, and
//! its colour with the same weight. A voxel's value is the weighted mean.

use std::collections::{HashMap, HashSet};
use std::hash::{BuildHasherDefault, Hasher};

use glam::Vec3;

use super::{MeshParams, Surfels};
use crate::{Error, Result};

/// Voxels per block side.
pub const BLOCK: i32 = 8;
pub const BLOCK_VOXELS: usize = (BLOCK * BLOCK * BLOCK) as usize;

/// Memory one block costs, bytes, as [`super::check_volume`] estimates it: its voxels
/// (`BLOCK_VOXELS` x 20 bytes), and 4 KiB for its entry in the block map and its share of
/// the mesh (a surface crosses about 64 of a block's 512 voxels, one plane of 8 x 8, each
/// giving a vertex, its colour, its entry in the vertex map and two triangles: about
/// 60 bytes each).
pub const BYTES_PER_BLOCK: u64 = (BLOCK_VOXELS * std::mem::size_of::<Voxel>()) as u64 + 4096;

/// Voxel indices must stay within this magnitude (block keys pack 21 bits per axis): at
/// 1 cm voxels, +-80 km.
pub const MAX_VOXEL_INDEX: i32 = (1 << 20) * BLOCK - 1;

/// A surfel's radius counts up to this many voxels: its box of voxels then holds at most
/// about `(2 * 1.5 * 32)^3`, 0.9 million, and a damaged radius (1e30 m) cannot make one
/// surfel's loop run for hours. A fused map's radii are a few millimetres to centimetres,
/// below it at any voxel from 1 mm.
pub const MAX_RADIUS_VOXELS: f32 = 32.0;

/// Surfel `i`'s radius, metres, clamped to [`MAX_RADIUS_VOXELS`].
fn radius(surfels: &Surfels, params: &MeshParams, i: usize) -> f32 {
    let r = surfels.radii.map_or(0.0, |r| r[i]);
    r.min(MAX_RADIUS_VOXELS * params.voxel_m)
}

/// What a voxel accumulates.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Voxel {
    /// Sum of weight x signed distance (metres).
    pub sdf_sum: f32,
    /// Sum of weights (0: never touched).
    pub weight: f32,
    /// Sum of weight x colour (RGB 0..255).
    pub color_sum: [f32; 3],
}

impl Voxel {
    /// The mean signed distance, metres (meaningless when `weight` is 0).
    pub fn sdf(&self) -> f32 {
        self.sdf_sum / self.weight
    }

    /// The mean colour, RGB 0..255.
    pub fn color(&self) -> Vec3 {
        Vec3::from(self.color_sum) / self.weight
    }
}

/// Hashes the packed block keys (already well spread: one multiply).
#[derive(Default)]
pub struct KeyHasher(u64);

impl Hasher for KeyHasher {
    fn finish(&self) -> u64 {
        self.0 ^ (self.0 >> 29)
    }
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = (self.0 ^ b as u64).wrapping_mul(0x0100_0000_01b3);
        }
    }
    fn write_u64(&mut self, x: u64) {
        self.0 = (self.0 ^ x).wrapping_mul(0x9e37_79b9_7f4a_7c15);
    }
}

/// The sparse grid: blocks allocated where a surfel reaches.
#[derive(Debug, Clone)]
pub struct SparseGrid {
    /// Voxel edge, metres.
    pub voxel_m: f32,
    blocks: HashMap<u64, u32, BuildHasherDefault<KeyHasher>>,
    /// `BLOCK_VOXELS` voxels per block, in the order blocks were allocated; within a block
    /// x fastest, then y, then z.
    voxels: Vec<Voxel>,
    /// Block coordinates, in allocation order.
    block_coords: Vec<[i32; 3]>,
}

fn pack(b: [i32; 3]) -> u64 {
    let f = |c: i32| (c + (1 << 20)) as u64 & 0x1f_ffff;
    f(b[0]) | f(b[1]) << 21 | f(b[2]) << 42
}

fn split(v: [i32; 3]) -> ([i32; 3], usize) {
    let b = v.map(|c| c.div_euclid(BLOCK));
    let l = v.map(|c| c.rem_euclid(BLOCK) as usize);
    (b, l[0] + BLOCK as usize * (l[1] + BLOCK as usize * l[2]))
}

impl SparseGrid {
    /// An empty grid.
    pub fn new(voxel_m: f32) -> SparseGrid {
        SparseGrid {
            voxel_m,
            blocks: HashMap::default(),
            voxels: Vec::new(),
            block_coords: Vec::new(),
        }
    }

    /// The voxel at index `v`, if its block exists.
    pub fn get(&self, v: [i32; 3]) -> Option<&Voxel> {
        let (b, l) = split(v);
        let at = *self.blocks.get(&pack(b))? as usize;
        Some(&self.voxels[at * BLOCK_VOXELS + l])
    }

    /// The voxel at index `v`, its block allocated if missing.
    pub fn get_mut(&mut self, v: [i32; 3]) -> &mut Voxel {
        let (b, l) = split(v);
        let next = self.block_coords.len() as u32;
        let at = *self.blocks.entry(pack(b)).or_insert(next) as usize;
        if at == next as usize {
            self.block_coords.push(b);
            self.voxels
                .resize(self.voxels.len() + BLOCK_VOXELS, Voxel::default());
        }
        &mut self.voxels[at * BLOCK_VOXELS + l]
    }

    /// Number of allocated blocks.
    pub fn block_count(&self) -> usize {
        self.block_coords.len()
    }

    /// Every voxel touched by some surfel, with its index, block by block in allocation
    /// order (deterministic for a given input).
    pub fn touched(&self) -> impl Iterator<Item = ([i32; 3], &Voxel)> + '_ {
        self.block_coords
            .iter()
            .enumerate()
            .flat_map(move |(bi, b)| {
                let base = b.map(|c| c * BLOCK);
                self.voxels[bi * BLOCK_VOXELS..(bi + 1) * BLOCK_VOXELS]
                    .iter()
                    .enumerate()
                    .filter(|(_, v)| v.weight > 0.0)
                    .map(move |(l, v)| {
                        let l = l as i32;
                        let local = [l % BLOCK, (l / BLOCK) % BLOCK, l / (BLOCK * BLOCK)];
                        (
                            [base[0] + local[0], base[1] + local[1], base[2] + local[2]],
                            v,
                        )
                    })
            })
    }
}

/// The voxels surfel `i` reaches, with the weight it gives each and its signed distance:
/// `visit(voxel, k, d)` (see the module header). Not called for an unusable surfel.
fn footprint(
    surfels: &Surfels,
    params: &MeshParams,
    i: usize,
    mut visit: impl FnMut([i32; 3], f32, f32) -> bool,
) {
    let voxel = params.voxel_m;
    let trunc = params.truncation_voxels * voxel;
    let p = Vec3::from(surfels.positions[i]);
    let n = Vec3::from(surfels.normals[i]);
    let w = surfels.weights.map_or(1.0, |w| w[i]);
    let r = radius(surfels, params, i);
    let support = params.support_scale * r.max(voxel);
    // The box around the disc's support and the truncation band.
    let reach = support.max(trunc);
    let lo = ((p - reach) / voxel).ceil().as_ivec3();
    let hi = ((p + reach) / voxel).floor().as_ivec3();
    for z in lo.z..=hi.z {
        for y in lo.y..=hi.y {
            for x in lo.x..=hi.x {
                let q = Vec3::new(x as f32, y as f32, z as f32) * voxel - p;
                let d = n.dot(q);
                let lateral_sq = q.length_squared() - d * d;
                if d.abs() > trunc || lateral_sq >= support * support {
                    continue;
                }
                let k = w * (1.0 - lateral_sq / (support * support));
                if !visit([x, y, z], k, d) {
                    return;
                }
            }
        }
    }
}

/// Refuses a surfel past [`MAX_VOXEL_INDEX`] voxels from the origin.
fn check_reach(surfels: &Surfels, params: &MeshParams, i: usize) -> Result<()> {
    let voxel = params.voxel_m;
    let p = Vec3::from(surfels.positions[i]);
    // The box reaches at most this far past the position (see `footprint`).
    let r = radius(surfels, params, i);
    let reach = (params.support_scale * r.max(voxel)).max(params.truncation_voxels * voxel);
    if p.abs().max_element() + reach > MAX_VOXEL_INDEX as f32 * voxel {
        return Err(Error::Argument(format!(
            "surfel {i} at {p} m is too far from the origin to mesh at {voxel} m voxels"
        )));
    }
    Ok(())
}

/// The blocks [`integrate`] would allocate, counted without allocating them; the count
/// stops as soon as it passes `stop_above` (so its own memory stays bounded).
pub fn count_blocks(surfels: &Surfels, params: &MeshParams, stop_above: usize) -> usize {
    let mut seen: HashSet<u64, BuildHasherDefault<KeyHasher>> = HashSet::default();
    for i in 0..surfels.positions.len() {
        if !surfels.usable(i) || check_reach(surfels, params, i).is_err() {
            continue;
        }
        footprint(surfels, params, i, |v, _, _| {
            seen.insert(pack(split(v).0));
            seen.len() <= stop_above
        });
        if seen.len() > stop_above {
            break;
        }
    }
    seen.len()
}

/// Integrates every surfel into a new grid (see the module header). Surfels that
/// [`Surfels::usable`] turns away (a non-finite position, normal, weight or radius, a
/// normal that is not unit length, a weight not positive or above
/// [`super::MAX_SURFEL_WEIGHT`]) are skipped; a position past [`MAX_VOXEL_INDEX`] voxels
/// from the origin is an error.
pub fn integrate(surfels: &Surfels, params: &MeshParams) -> Result<SparseGrid> {
    let mut grid = SparseGrid::new(params.voxel_m);
    for i in 0..surfels.positions.len() {
        if !surfels.usable(i) {
            continue;
        }
        check_reach(surfels, params, i)?;
        let c = surfels
            .colors
            .map_or(Vec3::splat(128.0), |c| Vec3::from(c[i]));
        footprint(surfels, params, i, |v, k, d| {
            let v = grid.get_mut(v);
            v.sdf_sum += k * d;
            v.weight += k;
            let cs = Vec3::from(v.color_sum) + k * c;
            v.color_sum = cs.into();
            true
        });
    }
    Ok(grid)
}
