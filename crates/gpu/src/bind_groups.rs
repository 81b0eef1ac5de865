//! The GPU backend's bind groups: every kernel's resources, bound by the names of the WGSL
//! variables, made once per set of buffers and re-made only when a buffer they refer to is
//! re-created (a new frame size, a grown map). The frame's buffers and each map chunk's
//! arrays are pools of named resources (`("normal_depth", ...)`) from which a kernel takes
//! what its WGSL declares; so are each pyramid level's maps (with, at level 0, the vertex
//! maps a plan call chooses: `wgslam_core::registry::At`), and so are each reduced system's
//! buffers. What differs per kernel of no `generic` row (its `params`, its own buffers) is
//! bound explicitly. The kernels that walk the map get one bind group per map chunk.

use std::collections::BTreeMap;

use super::buffers::GpuArray;
use super::context::GpuContext;
use super::images::GpuImage;
use super::kernel::Kernel;
use super::map_buffers::{Chunk, MapBuffers};
use super::pipelines::{GenericRow, Kernels, LevelParams, RowParams};
use super::resources::{FrameBuffers, SystemBuffers, Uniforms};
use crate::layout::DeformNode;
use wgslam_core::registry::{At, KernelId, Scanned, Shape, System};

/// The bind groups of the per-frame steps for one map set.
pub(super) struct BindGroups {
    /// The registry's `generic` kernels' bind groups by kernel id and [`At`] (a
    /// `PerLevel` kernel's level and vertex maps, a reduction's level and system, a scan's
    /// flags, else `At::FRAME`): one per map chunk, or one over the frame, the level, the
    /// system or the flags (see `wgslam_core::registry::Shape`).
    pub generic: BTreeMap<(KernelId, At), Groups>,
}

/// A kernel's bind groups at one [`At`]: one, or one per map chunk.
type Groups = Vec<wgpu::BindGroup>;

/// What the bind groups refer to besides the kernels: the buffers a backend owns.
pub(super) struct Resources<'a> {
    pub uniforms: &'a Uniforms,
    /// The frame's buffers, `None` before the first `preprocess`.
    pub frame: Option<&'a FrameBuffers>,
    pub map: &'a MapBuffers,
    /// A loop closure's node table (`deform_surfels`' `nodes`).
    pub nodes: &'a GpuArray<DeformNode>,
    /// Compaction's arrays over every map slot, by the names its kernels declare them with
    /// (`flags`, the keep flags; `offsets`, their prefix sum; the scan's `block_sums`), made
    /// at the first `compact`.
    pub compaction: OnDemand<'a>,
    /// Compaction's spare map (the map set the survivors are copied into), made at the
    /// first `compact`.
    pub spare: Option<&'a MapBuffers>,
    /// The buffers of the steps that make their own (relocalisation's ferns and
    /// keypoints), bound by the rows over the frame's pool (`OverFrame`, `PerItem`).
    pub steps: OnDemand<'a>,
    /// Per culling block its box (see `block_bounds.wgsl`).
    pub block_boxes: &'a GpuArray<[u32; 4]>,
    /// Per reduced system, in `System::ALL`'s order, its partial systems and their sum.
    pub systems: &'a [SystemBuffers; 2],
    /// The surfel counter: the scan's total.
    pub counter: &'a GpuArray<u32>,
}

/// A pool of named resources (see [`super::kernel::Kernel::bind_group_from`]).
type Pool<'a> = Vec<(&'static str, wgpu::BindingResource<'a>)>;

/// Resources a step makes at its first call, by the names the kernels declare them with:
/// `None` until made. A row that binds one not yet made has no bind group: the step drops
/// the bind groups when it makes its buffers, and they are made again with them.
pub(super) type OnDemand<'a> = Vec<(&'static str, Option<wgpu::BindingResource<'a>>)>;

/// The made resources of `on_demand` as pool entries, or `None` when `kernel` binds one
/// not yet made.
fn made<'a>(kernel: &Kernel, on_demand: OnDemand<'a>) -> Option<Pool<'a>> {
    let mut pool = Vec::new();
    for (name, resource) in on_demand {
        match resource {
            Some(resource) => pool.push((name, resource)),
            None if kernel.binds(name) => return None,
            None => {}
        }
    }
    Some(pool)
}

/// The frame's maps and association buffers, by the names the kernels declare them with.
/// `vertex_map` is the unfiltered vertex map, as `depth_to_vertex` writes it and
/// `bilateral_filter` reads it; the pyramid's kernels bind [`level_pool`]'s.
fn frame_pool<'a>(f: &'a FrameBuffers) -> Pool<'a> {
    vec![
        ("raw_depth", f.raw_depth.binding()),
        ("raw_rgba", f.raw_rgba.binding()),
        ("vertex_map", f.vertex.binding()),
        ("filtered_vertex", f.filtered_vertex.binding()),
        ("normal_depth", f.normal_depth.binding()),
        ("color_map", f.color.binding()),
        ("index_map", f.index_map.binding()),
        ("pred_vertex", f.pred_vertex.binding()),
        ("pred_normal", f.pred_normal.binding()),
        ("pred_intensity", f.pred_intensity.binding()),
        ("assoc", f.assoc.binding()),
        ("merged", f.merged.binding()),
        // Fusion's new-surfel flags and their prefix sum (compaction binds its own).
        ("flags", f.add_flags.binding()),
        ("offsets", f.add_offsets.binding()),
    ]
}

/// Pyramid level `at.level`'s maps by the names the `generic_levels` kernels (and the
/// reductions) declare them with, and its finer level's as `fine_*`: level 0's are the
/// frame's, its `vertex_map` and `point_map` the vertex maps `at` chooses (see [`At`]),
/// which level 1's `fine_vertex` is too. Its intensity patches are `intensity_patch`, the
/// finer level's `fine_map` (at level 0 the colour map, which the intensity pyramid starts
/// from). At every level, level 0's prediction is `level0_pred_vertex` and
/// `pred_intensity` (the photometric term's source).
fn level_pool(f: &FrameBuffers, at: At) -> Pool<'_> {
    let level0 = |filtered: bool| match filtered {
        true => &f.filtered_vertex,
        false => &f.vertex,
    };
    let maps: Vec<(&'static str, &GpuImage)> = match at.level.checked_sub(1) {
        None => vec![
            ("vertex_map", level0(at.filtered)),
            ("point_map", level0(at.filtered_points)),
            ("normal_depth", &f.normal_depth),
            ("pred_vertex", &f.pred_vertex),
            ("pred_normal", &f.pred_normal),
            ("intensity_patch", &f.intensity.patch),
            ("fine_map", &f.color),
        ],
        Some(l) => {
            let level = &f.levels[l];
            // The finer level's maps: level 0's, or the previous coarser level's.
            let (fine_vertex, fine_pred, fine_map) = match l.checked_sub(1) {
                None => (
                    level0(at.filtered),
                    [&f.pred_vertex, &f.pred_normal],
                    &f.intensity.patch,
                ),
                Some(p) => {
                    let p = &f.levels[p];
                    (
                        &p.vertex,
                        [&p.pred_vertex, &p.pred_normal],
                        &p.intensity.patch,
                    )
                }
            };
            vec![
                ("vertex_map", &level.vertex),
                ("point_map", &level.vertex),
                ("normal_depth", &level.normal_depth),
                ("pred_vertex", &level.pred_vertex),
                ("pred_normal", &level.pred_normal),
                ("fine_vertex", fine_vertex),
                ("fine_pred_vertex", fine_pred[0]),
                ("fine_pred_normal", fine_pred[1]),
                ("intensity_patch", &level.intensity.patch),
                ("fine_map", fine_map),
            ]
        }
    };
    let mut pool: Pool = maps
        .into_iter()
        .map(|(name, map)| (name, map.binding()))
        .collect();
    pool.extend([
        ("level0_pred_vertex", f.pred_vertex.binding()),
        ("pred_intensity", f.pred_intensity.binding()),
    ]);
    pool
}

/// Reduced system `system`'s buffers: its per-workgroup partial systems (`partials`) and
/// their sum (`system`).
fn system_pool(systems: &[SystemBuffers; 2], system: System) -> Pool<'_> {
    let b = &systems[system as usize];
    vec![
        ("partials", b.partials.binding()),
        ("system", b.sum.binding()),
    ]
}

/// One map chunk's arrays and the culling blocks' boxes.
fn chunk_pool<'a>(ch: &'a Chunk, block_boxes: &'a GpuArray<[u32; 4]>) -> Pool<'a> {
    vec![
        ("chunk", ch.info_buffer.binding()),
        ("position_weight", ch.position_weight.binding()),
        ("normal_frame", ch.normal_frame.binding()),
        ("color", ch.color.binding()),
        ("block_boxes", block_boxes.binding()),
    ]
}

impl BindGroups {
    /// Every per-frame step's bind groups over `r` (before the first frame only those of
    /// the rows over the map alone: [`Shape::PerSurfel`], [`Shape::PerChunkPair`], and the
    /// scans over compaction's keep flags).
    pub fn new(ctx: &GpuContext, k: &Kernels, r: &Resources) -> BindGroups {
        let u = r.uniforms;
        let rows = k.generic(u);
        BindGroups {
            generic: rows
                .iter()
                .flat_map(|row| {
                    let groups = match r.frame {
                        Some(f) => row_groups(ctx, r, f, row),
                        None => map_row_groups(ctx, r, row),
                    };
                    groups.into_iter().map(move |(at, g)| ((row.id, at), g))
                })
                .collect(),
        }
    }
}

/// The bind groups, by [`At`], of a `generic` `row` over the map alone
/// ([`Shape::PerSurfel`], [`Shape::PerChunkPair`]): per map chunk (per pair of chunks and
/// surfel array) its pool and the arrays over every map slot or the whole map (the loop
/// closure's node table `nodes`; compaction's arrays, made on demand: this pool has no
/// frame's `flags`), with the row's `params`; a scan's over compaction's keep flags
/// ([`scan_groups`]). None for a row of another shape, or one that binds what is not made
/// yet.
fn map_row_groups(ctx: &GpuContext, r: &Resources, row: &GenericRow) -> Vec<(At, Groups)> {
    let RowParams::Frame(params) = &row.params else {
        return Vec::new();
    };
    let kernel = &row.passes[0];
    if let Shape::PerScanBlock | Shape::OneWorkgroup = row.shape {
        return scan_groups(ctx, r, None, kernel, params);
    }
    let Some(compaction) = made(kernel, r.compaction.clone()) else {
        return Vec::new();
    };
    // Map chunk `ch`'s pool with the map-wide arrays.
    let pool_of = |ch| {
        let mut pool = vec![("params", params.clone())];
        pool.extend(chunk_pool(ch, r.block_boxes));
        pool.push(("nodes", r.nodes.binding()));
        pool.extend(compaction.iter().cloned());
        pool
    };
    let groups = match (row.shape, r.spare) {
        (Shape::PerSurfel, _) => r
            .map
            .chunks
            .iter()
            .map(|ch| kernel.bind_group_from(ctx, &pool_of(ch)))
            .collect(),
        (Shape::PerChunkPair, Some(spare)) => r
            .map
            .chunks
            .iter()
            .enumerate()
            .flat_map(|(s, from)| spare.chunks[..=s].iter().map(move |to| (from, to)))
            .flat_map(|(from, to)| {
                surfel_arrays(from)
                    .into_iter()
                    .zip(surfel_arrays(to))
                    .map(move |(array, out_array)| (from, to, array, out_array))
            })
            .map(|(from, to, array, out_array)| {
                let mut pool = vec![
                    ("surfel_array", array),
                    ("out_chunk", to.info_buffer.binding()),
                    ("out_surfel_array", out_array),
                ];
                pool.extend(pool_of(from));
                kernel.bind_group_from(ctx, &pool)
            })
            .collect(),
        _ => return Vec::new(),
    };
    vec![(At::FRAME, groups)]
}

/// A map chunk's surfel arrays, [`SURFEL_ARRAYS`] of them: `position_weight`,
/// `normal_frame`, `color` (a [`Shape::PerChunkPair`] row binds one at a time).
fn surfel_arrays(ch: &Chunk) -> [wgpu::BindingResource<'_>; SURFEL_ARRAYS] {
    [
        ch.position_weight.binding(),
        ch.normal_frame.binding(),
        ch.color.binding(),
    ]
}

/// The bind groups, by [`At`], of a `generic` `row` once the frame `f` exists: as its
/// [`Shape`] says (see `wgslam_core::registry::Shape`).
fn row_groups(
    ctx: &GpuContext,
    r: &Resources,
    f: &FrameBuffers,
    row: &GenericRow,
) -> Vec<(At, Groups)> {
    let u = r.uniforms;
    let frame = frame_pool(f);
    // A key kernel's passes share the first's layout.
    let kernel = &row.passes[0];
    // `kernel` with `params` over the steps' buffers and the frame's pool; none when it
    // binds a step's buffer not yet made.
    let over_frame = |params: wgpu::BindingResource| {
        let mut pool = vec![("params", params)];
        pool.extend(made(kernel, r.steps.clone())?);
        pool.extend(frame.iter().cloned());
        Some(kernel.bind_group_from(ctx, &pool))
    };
    // `kernel` with its `params` over each map chunk's pool and the frame's: one bind
    // group per chunk.
    let per_chunk = |params: &wgpu::BindingResource| {
        r.map
            .chunks
            .iter()
            .map(|ch| {
                let mut pool = vec![("params", params.clone())];
                pool.extend(chunk_pool(ch, r.block_boxes));
                pool.extend(frame.iter().cloned());
                kernel.bind_group_from(ctx, &pool)
            })
            .collect::<Vec<_>>()
    };
    // `kernel` with each level's `params` (where the level has them) over each of the
    // level's pools.
    let per_level = |params_of: LevelParams| {
        (0..=f.levels.len())
            .filter_map(|level| Some((level, params_of(&f.level_uniforms(u, level))?)))
            .flat_map(|(level, params)| {
                At::choices(level).into_iter().map(move |at| {
                    let mut pool = vec![("params", params.clone())];
                    pool.extend(level_pool(f, at));
                    (at, vec![kernel.bind_group_from(ctx, &pool)])
                })
            })
            .collect::<Vec<_>>()
    };
    // `kernel` with `params` over each system's buffers, and for a reduction (`levels`)
    // over each pyramid level's pool: one bind group per system (and level).
    let per_system = |params: &wgpu::BindingResource, levels: bool| {
        let levels = if levels { 0..=f.levels.len() } else { 0..=0 };
        levels
            .flat_map(|level| System::ALL.map(|system| At::of_system(level, system)))
            .map(|at| {
                let mut pool = vec![("params", params.clone())];
                pool.extend(system_pool(r.systems, at.system));
                pool.extend(level_pool(f, at));
                (at, vec![kernel.bind_group_from(ctx, &pool)])
            })
            .collect::<Vec<_>>()
    };
    match (row.shape, &row.params) {
        (Shape::PerLevel, RowParams::Level(params_of)) => per_level(*params_of),
        (Shape::OverFrame | Shape::PerItem | Shape::PerCount, RowParams::Frame(p)) => {
            over_frame(p.clone())
                .map(|g| (At::FRAME, vec![g]))
                .into_iter()
                .collect()
        }
        (Shape::PerChunk | Shape::PerBlock | Shape::PerStaleBlock, RowParams::Frame(p)) => {
            vec![(At::FRAME, per_chunk(p))]
        }
        (Shape::PerSurfel | Shape::PerChunkPair, RowParams::Frame(_)) => {
            map_row_groups(ctx, r, row)
        }
        (Shape::PerScanBlock | Shape::OneWorkgroup, RowParams::Frame(p)) => {
            scan_groups(ctx, r, Some(f), kernel, p)
        }
        (Shape::Reduce, RowParams::Frame(p)) => per_system(p, true),
        (Shape::PerSystem, RowParams::Frame(p)) => per_system(p, false),
        (shape, _) => panic!(
            "kernel `{}`: a {shape:?} row in the wrong group of the registry \
             (`generic_levels` rows are `PerLevel`, no other row is)",
            kernel.name
        ),
    }
}

/// The surfel arrays of a map chunk ([`surfel_arrays`]): a [`Shape::PerChunkPair`] row has
/// this many bind groups per pair of chunks, one pass each.
pub(super) const SURFEL_ARRAYS: usize = 3;

/// The bind groups, by [`At`] (its [`Scanned`]), of a scan's `kernel` with its `params`:
/// over fusion's new-surfel flags (the frame's `flags`, `offsets` and `block_sums`; none
/// before the first frame, `f` `None`) and over compaction's keep flags (theirs, made on
/// demand), each with the surfel counter `counter`.
fn scan_groups(
    ctx: &GpuContext,
    r: &Resources,
    f: Option<&FrameBuffers>,
    kernel: &Kernel,
    params: &wgpu::BindingResource,
) -> Vec<(At, Groups)> {
    let new_surfels = f.map(|f| {
        vec![
            ("flags", f.add_flags.binding()),
            ("offsets", f.add_offsets.binding()),
            ("block_sums", f.add_block_sums.binding()),
        ]
    });
    let keep_flags = made(kernel, r.compaction.clone());
    [
        (Scanned::NewSurfels, new_surfels),
        (Scanned::KeepFlags, keep_flags),
    ]
    .into_iter()
    .filter_map(|(scanned, flags)| {
        let mut pool = vec![("params", params.clone()), ("counter", r.counter.binding())];
        pool.extend(flags?);
        Some((
            At::of_scan(scanned),
            vec![kernel.bind_group_from(ctx, &pool)],
        ))
    })
    .collect()
}
