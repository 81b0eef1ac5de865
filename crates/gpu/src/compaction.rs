//! What the GPU's `compact` step needs besides the map, allocated at its first call (the
//! assignment profile never pays for it) and re-allocated when the map grows: one keep
//! flag and one offset per surfel slot, and a second map of the same chunk sizes that
//! `compact_scatter` writes and that then swaps with the map; and the bind groups of the
//! three passes over them ([`CompactionGroups`]).

use super::bind_groups::ScanGroups;
use super::buffers::GpuArray;
use super::context::GpuContext;
use super::map_buffers::MapBuffers;
use super::pipelines::Kernels;
use super::resources::Uniforms;
use crate::Result;

pub(super) struct Compaction {
    pub flags: GpuArray<u32>,
    pub offsets: GpuArray<u32>,
    /// The scan's per-block sums over `flags` (see prefix_sum_reduce.wgsl).
    pub block_sums: GpuArray<u32>,
    pub spare: MapBuffers,
    /// The three passes' bind groups for the live map (`groups`) and for the spare one
    /// (`spare_groups`), made once each and swapped with the maps.
    pub groups: Option<CompactionGroups>,
    pub spare_groups: Option<CompactionGroups>,
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
                groups: None,
                spare_groups: None,
            })
        })
    }

    /// Follows `map`'s layout after it grew: re-makes what no longer fits. Returns whether
    /// anything changed (then every compaction bind group is dropped, and the caller drops
    /// the spare map set's other bind groups).
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
        self.groups = None;
        self.spare_groups = None;
        Ok(true)
    }
}

/// The scan's block sums for `cap` flags, every entry in use.
fn block_sums_for(ctx: &GpuContext, cap: usize) -> Result<GpuArray<u32>> {
    let blocks = crate::cpu::prefix_sum::scan_blocks(cap).max(1);
    let mut block_sums = GpuArray::new(ctx, "compact block sums", blocks)?;
    block_sums.set_len(blocks);
    Ok(block_sums)
}

/// Bind groups of `prefix_sum` and `compact_scatter` (per input chunk and output chunk no
/// later than it, and per surfel array) for one map set (the keep flags' kernel is bound
/// by its registry row: `super::bind_groups`).
pub(super) struct CompactionGroups {
    pub scan: ScanGroups,
    /// Input chunk s, output chunk d <= s (offsets[i] <= i), surfel array a (position_weight,
    /// normal_frame, color) at [`super::bind_groups::SCATTER_ATTRIBUTES`] (s (s + 1) / 2 + d) + a.
    pub scatter: Vec<wgpu::BindGroup>,
}

impl CompactionGroups {
    /// The compaction's bind groups from `map` into `c.spare`.
    pub fn new(
        ctx: &GpuContext,
        k: &Kernels,
        u: &Uniforms,
        counter: &GpuArray<u32>,
        map: &MapBuffers,
        c: &Compaction,
    ) -> CompactionGroups {
        CompactionGroups {
            scan: ScanGroups::new(
                ctx,
                k,
                [
                    ("params", u.compact.binding()),
                    ("flags", c.flags.binding()),
                    ("block_sums", c.block_sums.binding()),
                    ("offsets", c.offsets.binding()),
                    ("counter", counter.binding()),
                ],
            ),
            scatter: map
                .chunks
                .iter()
                .enumerate()
                .flat_map(|(s, from)| c.spare.chunks[..=s].iter().map(move |to| (from, to)))
                .flat_map(|(from, to)| {
                    // One bind group per surfel array, in the order of SCATTER_ATTRIBUTES.
                    [
                        (from.position_weight.binding(), to.position_weight.binding()),
                        (from.normal_frame.binding(), to.normal_frame.binding()),
                        (from.color.binding(), to.color.binding()),
                    ]
                    .map(|(surfel_array, out_surfel_array)| {
                        k.compact_scatter.bind_group(
                            ctx,
                            &[
                                ("params", u.compact.binding()),
                                ("flags", c.flags.binding()),
                                ("offsets", c.offsets.binding()),
                                ("chunk", from.info_buffer.binding()),
                                ("surfel_array", surfel_array),
                                ("out_chunk", to.info_buffer.binding()),
                                ("out_surfel_array", out_surfel_array),
                            ],
                        )
                    })
                })
                .collect(),
        }
    }
}
