//! The surfel map on the GPU: a list of chunks, each three storage buffers (structure of
//! arrays) holding `slots` consecutive surfels of the map, packed exactly as [`SurfelMap`]
//! holds them on the host:
//!
//! | array | element | x, y, z | w |
//! |---|---|---|---|
//! | `position_weight` | `vec4<f32>` | position, metres, world frame | weight |
//! | `normal_frame` | `vec4<u32>` | bits of the unit normal (`bitcast<u32>`) | last_frame |
//! | `color` | `vec4<f32>` | RGB 0..255 | radius, metres |
//!
//! Map-wide surfel `i` is element `i - base` of the chunk whose `base..base + slots` holds
//! it; each chunk's [`MapChunk`] (first index, slots) sits in a small params buffer the
//! kernels bind, and every kernel that walks the map is dispatched once per chunk. Chunks
//! keep each binding under the device's storage-binding limit (128 MiB on lavapipe) and let
//! the map grow without copying it: only the last chunk is re-allocated (up to
//! `chunk_surfels`), full chunks stay where they are. Slots come in whole culling blocks
//! ([`BLOCK_SURFELS`]), so no block straddles two chunks.
//!
//! Storage buffers, not textures, as the design card asks: read-write rgba32 storage
//! textures need an adapter-specific format feature that WebGPU's core and some Metal/DX12
//! tiers lack.

use super::buffers::{GpuArray, ParamBuffer};
use super::context::GpuContext;
use crate::layout::map::SurfelMap;
use crate::layout::{MapChunk, BLOCK_SURFELS};
use crate::Result;

/// Surfels per full chunk unless the device's binding limit is smaller: 2^21 slots, 32 MiB
/// per array (96 MiB per chunk), a quarter of lavapipe's 128 MiB binding limit, so a
/// 640x480 run (1-2 M surfels) needs one or two chunks.
pub const DEFAULT_CHUNK_SURFELS: usize = 1 << 21;

/// One chunk: its three arrays and its `MapChunk` params buffer.
pub struct Chunk {
    pub info: MapChunk,
    /// `info` on the GPU (bound as `chunk` by every map kernel).
    pub info_buffer: ParamBuffer<MapChunk>,
    /// xyz metres (world frame), w = weight.
    pub position_weight: GpuArray<[f32; 4]>,
    /// xyz = bits of the unit normal, w = last_frame.
    pub normal_frame: GpuArray<[u32; 4]>,
    /// RGB 0..255, a = radius (metres).
    pub color: GpuArray<[f32; 4]>,
}

impl Chunk {
    fn new(ctx: &GpuContext, base: usize, slots: usize) -> Result<Chunk> {
        let info = MapChunk {
            base: base as u32,
            slots: slots as u32,
            _pad0: 0,
            _pad1: 0,
        };
        Ok(Chunk {
            info,
            info_buffer: ParamBuffer::new(ctx, "MapChunk", &info),
            position_weight: GpuArray::new(ctx, "surfel position+weight", slots)?,
            normal_frame: GpuArray::new(ctx, "surfel normal+last_frame", slots)?,
            color: GpuArray::new(ctx, "surfel color+radius", slots)?,
        })
    }

    /// Live surfels of this chunk when the map holds `count`.
    pub fn live(&self, count: usize) -> usize {
        count
            .saturating_sub(self.info.base as usize)
            .min(self.info.slots as usize)
    }
}

/// The surfel map as chunks of storage buffers (see the module header).
pub struct MapBuffers {
    pub chunks: Vec<Chunk>,
    chunk_surfels: usize,
}

impl MapBuffers {
    /// Slots per full chunk on this device: [`DEFAULT_CHUNK_SURFELS`], or fewer when one
    /// storage binding cannot hold that many 16-byte elements (whole blocks either way).
    pub fn device_chunk_surfels(ctx: &GpuContext) -> usize {
        let fit = (ctx.max_storage_bytes() / 16) as usize;
        let block = BLOCK_SURFELS as usize;
        (DEFAULT_CHUNK_SURFELS.min(fit) / block * block).max(block)
    }

    /// Largest map the chunked layout can index (map-wide indices are u32, whole blocks).
    pub fn max_surfels() -> usize {
        (u32::MAX / BLOCK_SURFELS * BLOCK_SURFELS) as usize
    }

    /// Chunks with room for `capacity` surfels, full chunks of `chunk_surfels` slots (a
    /// multiple of [`BLOCK_SURFELS`]) and a smaller last one, zero-filled.
    pub fn new(ctx: &GpuContext, capacity: usize, chunk_surfels: usize) -> Result<MapBuffers> {
        assert!(
            chunk_surfels > 0 && chunk_surfels % BLOCK_SURFELS as usize == 0,
            "chunk_surfels {chunk_surfels} must be a positive multiple of {BLOCK_SURFELS}"
        );
        let mut map = MapBuffers {
            chunks: Vec::new(),
            chunk_surfels,
        };
        map.grow(ctx, capacity.max(1), 0)?;
        Ok(map)
    }

    /// Slots in all chunks.
    pub fn capacity(&self) -> usize {
        self.chunks.iter().map(|c| c.info.slots as usize).sum()
    }

    /// Slots per full chunk.
    pub fn chunk_surfels(&self) -> usize {
        self.chunk_surfels
    }

    /// Makes room for `new_capacity` surfels keeping the first `keep`: the last chunk grows
    /// (x1.5, a GPU-side copy of its live surfels, at most `chunk_surfels`) and new chunks
    /// follow it. No-op when already large enough. Returns whether any chunk was re-made
    /// or added (bind groups must then be rebuilt).
    pub fn grow(&mut self, ctx: &GpuContext, new_capacity: usize, keep: usize) -> Result<bool> {
        let block = BLOCK_SURFELS as usize;
        let mut changed = false;
        while self.capacity() < new_capacity {
            let missing = new_capacity - self.capacity();
            let full = self.chunk_surfels;
            match self.chunks.last_mut() {
                Some(last) if (last.info.slots as usize) < full => {
                    let slots = last.info.slots as usize;
                    let grown = (slots * 3 / 2).max(slots + missing).min(full);
                    let grown = grown.div_ceil(block) * block;
                    let live = last.live(keep);
                    last.position_weight.set_len(live);
                    last.position_weight.grow(ctx, grown)?;
                    last.normal_frame.set_len(live);
                    last.normal_frame.grow(ctx, grown)?;
                    last.color.set_len(live);
                    last.color.grow(ctx, grown)?;
                    last.info.slots = grown as u32;
                    last.info_buffer.write(ctx, &last.info);
                }
                _ => {
                    let base = self.capacity();
                    let slots = missing.min(full).div_ceil(block) * block;
                    self.chunks.push(Chunk::new(ctx, base, slots)?);
                }
            }
            changed = true;
        }
        Ok(changed)
    }

    /// Makes this map's chunks the same sizes as `other`'s (the compaction's spare set
    /// follows the live map), keeping nothing. Returns whether anything changed.
    pub fn match_layout(&mut self, ctx: &GpuContext, other: &MapBuffers) -> Result<bool> {
        let same = self.chunks.len() == other.chunks.len()
            && self
                .chunks
                .iter()
                .zip(&other.chunks)
                .all(|(a, b)| a.info == b.info);
        if same {
            return Ok(false);
        }
        // Full chunks that already match are kept; the rest are re-made.
        let keep = self
            .chunks
            .iter()
            .zip(&other.chunks)
            .take_while(|(a, b)| a.info == b.info)
            .count();
        self.chunks.truncate(keep);
        for c in &other.chunks[keep..] {
            self.chunks.push(Chunk::new(
                ctx,
                c.info.base as usize,
                c.info.slots as usize,
            )?);
        }
        Ok(true)
    }

    /// The first `n` surfels, downloaded chunk by chunk: the arrays are `SurfelMap`'s
    /// packing, so this is a plain copy.
    pub fn download(&self, ctx: &GpuContext, n: usize) -> Result<SurfelMap> {
        let mut map = SurfelMap::default();
        for c in &self.chunks {
            let live = c.live(n);
            if live == 0 {
                break;
            }
            map.position_weight
                .extend(c.position_weight.read_back_range(ctx, 0..live)?);
            map.normal_frame
                .extend(c.normal_frame.read_back_range(ctx, 0..live)?);
            map.color.extend(c.color.read_back_range(ctx, 0..live)?);
        }
        Ok(map)
    }

    /// Writes `map` into slots `0..map.len()` as it is (the caller grows first).
    pub fn upload(&mut self, ctx: &GpuContext, map: &SurfelMap) -> Result<()> {
        let n = map.len();
        for c in &mut self.chunks {
            let live = c.live(n);
            if live == 0 {
                break;
            }
            let r = c.info.base as usize..c.info.base as usize + live;
            c.position_weight
                .write_at(ctx, 0, &map.position_weight[r.clone()])?;
            c.normal_frame
                .write_at(ctx, 0, &map.normal_frame[r.clone()])?;
            c.color.write_at(ctx, 0, &map.color[r])?;
        }
        Ok(())
    }
}
