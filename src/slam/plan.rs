//! Each pipeline step's kernel plan, written once: the ordered list of kernel invocations
//! (and buffer clears) that a step runs. Both backends execute the same plan, the CPU by
//! calling the twins in `src/cpu/` in its order, the GPU by recording one compute pass per
//! invocation (once per map chunk for the kernels that walk the map), so the order of a
//! step's kernels cannot differ between them. `wgslam compare` and the parity tests name
//! kernels by [`Call::kernel`].
//!
//! Not here: which buffers a kernel reads and writes (each backend binds its own; the
//! GPU's bind groups are made by the WGSL variables' names) and ICP's per-iteration
//! reduction (`icp_reduce`, then on the GPU `icp_reduce_final` over the per-workgroup
//! partials; the CPU twin of `icp_reduce` sums in one pass), which is one fixed kernel
//! pair rather than a plan.

use crate::layout::{FuseParams, ASSOCIATION_BEST_CANDIDATE};

/// A per-frame buffer that a step zeroes before its kernels accumulate into it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Buffer {
    /// The packed depth/index key per pixel (`project_model`, or `fuse_select` and
    /// `fuse_add` building the next prediction's).
    IndexMap,
    /// Fusion's per-pixel association key (`fuse_select`, `fuse_merge`).
    Assoc,
    /// The surfel each pixel merged into (`fuse_merge_chosen`), two entries per pixel.
    Merged,
}

/// One step of a plan: a kernel (named after `shaders/<kernel>.wgsl` and
/// `src/cpu/<kernel>.rs`) with which of its inputs it reads where a kernel runs on more
/// than one set of maps, or a clear.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Call {
    /// Zero a buffer.
    Clear(Buffer),
    /// `block_bounds` over the blocks whose boxes are stale (fusion appended to them, or
    /// the map was compacted or uploaded); nothing when none are. Every culling step
    /// starts with it.
    BlockBounds,
    /// `depth_to_vertex`: raw depth and colour -> `vertex`, `color`.
    DepthToVertex,
    /// `bilateral_filter`: `vertex` -> `filtered_vertex`.
    BilateralFilter,
    /// `vertex_to_normal` at pyramid level `level`: at level 0 from `filtered_vertex` when
    /// `filtered`, else from `vertex`; at a coarser level from that level's vertex map.
    VertexToNormal { level: usize, filtered: bool },
    /// `pyramid_depth` making level `level >= 1` from level `level - 1`'s vertex map (at
    /// level 1 the filtered one when `filtered`).
    PyramidDepth { level: usize, filtered: bool },
    /// `project_model`: the map -> `index_map` at the predicted view.
    ProjectModel,
    /// `predict_model`: `index_map` and the map -> level 0's `pred_vertex`, `pred_normal`.
    PredictModel,
    /// `pyramid_model` making level `level >= 1`'s predicted maps from level `level - 1`'s.
    PyramidModel { level: usize },
    /// `fuse_select`: each pixel chooses a surfel (best-candidate association).
    FuseSelect,
    /// `fuse_merge_chosen`: each chosen surfel merges its pixel's measurement.
    FuseMergeChosen,
    /// `fuse_prune`: surfels this frame did not refresh retire next to a merged twin.
    FusePrune,
    /// `fuse_merge`: every surfel merges with the pixel it projects to (projective).
    FuseMerge,
    /// `fuse_flags`: which pixels become new surfels, in append order.
    FuseFlags,
    /// `prefix_sum` over `fuse_flags`' flags: each new surfel's slot, and how many.
    FuseScan,
    /// `fuse_add`: append the new surfels.
    FuseAdd,
    /// `compact_flags`: keep or remove each surfel.
    CompactFlags,
    /// `prefix_sum` over the keep flags: each survivor's slot, and how many.
    CompactScan,
    /// `compact_scatter`: copy each survivor into the second map.
    CompactScatter,
}

impl Call {
    /// The kernel's name (`shaders/<kernel>.wgsl`), or `clear` for a clear.
    pub fn kernel(self) -> &'static str {
        match self {
            Call::Clear(_) => "clear",
            Call::BlockBounds => "block_bounds",
            Call::DepthToVertex => "depth_to_vertex",
            Call::BilateralFilter => "bilateral_filter",
            Call::VertexToNormal { .. } => "vertex_to_normal",
            Call::PyramidDepth { .. } => "pyramid_depth",
            Call::ProjectModel => "project_model",
            Call::PredictModel => "predict_model",
            Call::PyramidModel { .. } => "pyramid_model",
            Call::FuseSelect => "fuse_select",
            Call::FuseMergeChosen => "fuse_merge_chosen",
            Call::FusePrune => "fuse_prune",
            Call::FuseMerge => "fuse_merge",
            Call::FuseFlags => "fuse_flags",
            Call::FuseScan | Call::CompactScan => "prefix_sum",
            Call::FuseAdd => "fuse_add",
            Call::CompactFlags => "compact_flags",
            Call::CompactScatter => "compact_scatter",
        }
    }
}

/// `preprocess`: `depth_to_vertex`, with the filter `bilateral_filter`, then
/// `vertex_to_normal` (from the filtered vertex map with the filter); then for each of the
/// `coarser_levels` pyramid levels 1, 2, ... `pyramid_depth` and `vertex_to_normal`.
pub fn preprocess(filtered: bool, coarser_levels: usize) -> Vec<Call> {
    let mut plan = vec![Call::DepthToVertex];
    if filtered {
        plan.push(Call::BilateralFilter);
    }
    plan.push(Call::VertexToNormal { level: 0, filtered });
    for level in 1..=coarser_levels {
        plan.push(Call::PyramidDepth { level, filtered });
        plan.push(Call::VertexToNormal {
            level,
            filtered: false,
        });
    }
    plan
}

/// `predict`: unless the last fusion left the index map of this very view (`project`
/// false, see [`crate::slam::fused_view::FusedView`]), fresh block boxes, a cleared index
/// map and `project_model`; then `predict_model` and `pyramid_model` per coarser level.
pub fn predict(project: bool, coarser_levels: usize) -> Vec<Call> {
    let mut plan = Vec::new();
    if project {
        plan.extend([
            Call::BlockBounds,
            Call::Clear(Buffer::IndexMap),
            Call::ProjectModel,
        ]);
    }
    plan.push(Call::PredictModel);
    plan.extend((1..=coarser_levels).map(|level| Call::PyramidModel { level }));
    plan
}

/// `fuse` with `params`: cleared association buffers (and, with best-candidate
/// association, the merged surfels and the index map it builds), fresh block boxes; then
/// best candidate `fuse_select`, `fuse_merge_chosen` and with a prune scale `fuse_prune`,
/// or projective `fuse_merge`; then `fuse_flags`, their prefix sum and `fuse_add`.
pub fn fuse(params: &FuseParams) -> Vec<Call> {
    let best_candidate = params.association == ASSOCIATION_BEST_CANDIDATE;
    let mut plan = vec![Call::Clear(Buffer::Assoc)];
    if best_candidate {
        plan.extend([Call::Clear(Buffer::Merged), Call::Clear(Buffer::IndexMap)]);
    }
    plan.push(Call::BlockBounds);
    if best_candidate {
        plan.extend([Call::FuseSelect, Call::FuseMergeChosen]);
        if params.prune_radius_scale > 0.0 {
            plan.push(Call::FusePrune);
        }
    } else {
        plan.push(Call::FuseMerge);
    }
    plan.extend([Call::FuseFlags, Call::FuseScan, Call::FuseAdd]);
    plan
}

/// `compact`: keep flags, their prefix sum, and the copy of the survivors.
pub fn compact() -> Vec<Call> {
    vec![Call::CompactFlags, Call::CompactScan, Call::CompactScatter]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::layout::ASSOCIATION_PROJECTIVE;

    /// The plans name the kernels of their steps in the order the README and the pipeline's
    /// table give.
    #[test]
    fn plans_list_each_steps_kernels_in_order() {
        let names = |plan: Vec<Call>| plan.into_iter().map(Call::kernel).collect::<Vec<_>>();
        assert_eq!(
            names(preprocess(true, 1)),
            [
                "depth_to_vertex",
                "bilateral_filter",
                "vertex_to_normal",
                "pyramid_depth",
                "vertex_to_normal"
            ]
        );
        assert_eq!(
            names(predict(true, 0)),
            ["block_bounds", "clear", "project_model", "predict_model"]
        );
        assert_eq!(names(predict(false, 1)), ["predict_model", "pyramid_model"]);
        let mut p: FuseParams = bytemuck::Zeroable::zeroed();
        p.association = ASSOCIATION_BEST_CANDIDATE;
        p.prune_radius_scale = 0.5;
        assert_eq!(
            names(fuse(&p)),
            [
                "clear",
                "clear",
                "clear",
                "block_bounds",
                "fuse_select",
                "fuse_merge_chosen",
                "fuse_prune",
                "fuse_flags",
                "prefix_sum",
                "fuse_add"
            ]
        );
        p.association = ASSOCIATION_PROJECTIVE;
        assert_eq!(
            names(fuse(&p)),
            [
                "clear",
                "block_bounds",
                "fuse_merge",
                "fuse_flags",
                "prefix_sum",
                "fuse_add"
            ]
        );
        assert_eq!(
            names(compact()),
            ["compact_flags", "prefix_sum", "compact_scatter"]
        );
    }
}
