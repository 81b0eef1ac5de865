//! What the GPU's `compact` step needs besides the map, allocated at its first call (the
//! assignment profile never pays for it) and re-allocated when the map grows: one keep
//! flag and one offset per surfel slot, and a second map of the same chunk sizes that
//! the copy of the survivors writes and that then swaps with the map. The step's kernels
//! are bound by their registry rows, over [`bindings`] and the spare map.

use super::bind_groups::OnDemand;
use super::buffers::GpuArray;
use super::context::GpuContext;
use super::map_buffers::MapBuffers;
use crate::Result;

pub(super) struct Compaction {
    pub flags: GpuArray<u32>,
    pub offsets: GpuArray<u32>,
    /// The scan's per-block sums over `flags`.
    pub block_sums: GpuArray<u32>,
    pub spare: MapBuffers,
}

impl Compaction {
    /// Flags, offsets and a spare map for `map` (all `map.capacity()` slots).
    pub fn new(ctx: &GpuContext, map: &MapBuffers) -> Result<Compaction> {
        let cap = map.capacity();
        ctx.scoped("allocating the compaction buffers", || {
            let mut flags = GpuArray::new(ctx, "compact flags", cap)?;
            flags.set_len(cap);
            let mut offsets = GpuArray::new(ctx, "compact offsets", cap)?;
            offsets.set_len(cap);
            let block_sums = block_sums_for(ctx, cap)?;
            let mut spare = MapBuffers::new(ctx, 1, map.chunk_surfels())?;
            spare.match_layout(ctx, map)?;
            Ok(Compaction {
                flags,
                offsets,
                block_sums,
                spare,
            })
        })
    }

    /// Follows `map`'s layout after it grew: re-makes what no longer fits. Returns whether
    /// anything changed (then the caller drops the bind groups).
    pub fn follow(&mut self, ctx: &GpuContext, map: &MapBuffers) -> Result<bool> {
        let cap = map.capacity();
        let relaid = self.spare.match_layout(ctx, map)?;
        if self.flags.capacity() >= cap && !relaid {
            return Ok(false);
        }
        if self.flags.capacity() < cap {
            self.flags = GpuArray::new(ctx, "compact flags", cap)?;
            self.offsets = GpuArray::new(ctx, "compact offsets", cap)?;
            self.block_sums = block_sums_for(ctx, cap)?;
        }
        self.flags.set_len(cap);
        self.offsets.set_len(cap);
        Ok(true)
    }
}

/// The scan's block sums for `cap` flags, every entry in use.
fn block_sums_for(ctx: &GpuContext, cap: usize) -> Result<GpuArray<u32>> {
    let blocks = crate::layout::scan_blocks(cap).max(1);
    let mut block_sums = GpuArray::new(ctx, "compact block sums", blocks)?;
    block_sums.set_len(blocks);
    Ok(block_sums)
}

/// Compaction's arrays over every map slot by the names its kernels declare them with
/// (`flags`, `offsets`, and the scan's `block_sums`), `None` before the first `compact` (see
/// `super::bind_groups::OnDemand`).
pub(super) fn bindings(c: Option<&Compaction>) -> OnDemand<'_> {
    vec![
        ("flags", c.map(|c| c.flags.binding())),
        ("offsets", c.map(|c| c.offsets.binding())),
        ("block_sums", c.map(|c| c.block_sums.binding())),
    ]
}
