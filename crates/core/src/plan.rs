//! Each pipeline step's kernel plan, written once: the ordered list of kernel invocations
//! (and buffer clears) that a step runs; likewise the renderer's ([`render`]) and scan
//! registration's ([`scan_correspondences`]), whose callers bind their kernels over pools of
//! their own (`crate::cpu_backend::run_call` on the CPU, `wgslam_gpu::row_kernels` on the
//! GPU). Both backends execute the same plan, the CPU by
//! calling the twins in `crates/core/src/cpu/` in its order, the GPU by recording one compute pass per
//! invocation (once per map chunk for the kernels that walk the map), so the order of a
//! step's kernels cannot differ between them. A call names its kernel by its registry id
//! ([`Call::kernel`]); `wgslam compare` and the parity tests by its [`Call::name`].
//!
//! Not here: which buffers a kernel reads and writes (each backend binds its own; the
//! GPU's bind groups are made by the WGSL variables' names).

use crate::layout::scan::SCAN_BRUTE_CHUNK;
use crate::layout::{BilateralParams, FuseParams, ASSOCIATION_BEST_CANDIDATE};
use crate::registry::{At, KernelId, Scanned, System};

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

/// What every step's call enum tells: the kernel it runs (by its registry id), and its name
/// for timings and messages. Implemented by `step_calls!` for every call enum.
pub trait Call: Copy + std::fmt::Debug {
    /// The kernel the call runs, or `None` for a clear.
    fn kernel(self) -> Option<KernelId>;
    /// The kernel's name (`shaders/<kernel>.wgsl`, `crates/core/src/cpu/<kernel>.rs`), or
    /// `clear` for a clear.
    fn name(self) -> &'static str;
    /// Where the kernel runs: the pyramid level and the vertex maps of a
    /// `registry::Shape::PerLevel` kernel, else [`At::FRAME`].
    fn at(self) -> At;
    /// Whether a key kernel's call runs every pass of its portable variant (on a device
    /// without 64-bit atomics), or its first alone (a call whose later passes would write
    /// nothing the step keeps: [`FuseCall::FuseAdd`] without `index_words`). True for every
    /// other call.
    fn every_key_pass(self) -> bool;
}

/// A call's kernel: `clear` for a clear, else the registry id of that name.
macro_rules! kernel_of {
    (clear) => {
        None
    };
    ($kernel:ident) => {
        Some(KernelId::$kernel)
    };
}

/// Declares a step's call enum and its kernels: one variant per kernel invocation (or
/// clear) the step may plan, so each backend's `match` over a step's plan is exhaustive
/// without a catch-all, and [`Call`] for it.
macro_rules! step_calls {
    ($(#[$doc:meta])* $name:ident {
        $($(#[$vdoc:meta])* $variant:ident $({ $($field:ident: $ty:ty),* })? $(($inner:ty))? => $kernel:ident,)*
    } $(at($call:ident) $at:block)? $(every_key_pass($kcall:ident) $kp:block)?) => {
        $(#[$doc])*
        #[derive(Debug, Clone, Copy, PartialEq, Eq)]
        pub enum $name {
            $($(#[$vdoc])* $variant $({ $($field: $ty),* })? $(($inner))?,)*
        }

        impl Call for $name {
            fn kernel(self) -> Option<KernelId> {
                match self {
                    $($name::$variant { .. } => kernel_of!($kernel),)*
                }
            }

            fn name(self) -> &'static str {
                match self {
                    $($name::$variant { .. } => stringify!($kernel),)*
                }
            }

            #[allow(unreachable_code)]
            fn at(self) -> At {
                $(let $call = self; return $at;)?
                At::FRAME
            }

            #[allow(unreachable_code)]
            fn every_key_pass(self) -> bool {
                $(let $kcall = self; return $kp;)?
                true
            }
        }
    };
}

step_calls! {
    /// One call of the `preprocess` plan.
    PreprocessCall {
        /// `depth_to_vertex`: raw depth and colour -> `vertex`, `color`.
        DepthToVertex => depth_to_vertex,
        /// `bilateral_filter`: `vertex` -> `filtered_vertex`.
        BilateralFilter => bilateral_filter,
        /// `vertex_to_normal` at pyramid level `level`: at level 0 the normals from
        /// `filtered_vertex` when `filtered`, else from `vertex`, and the points
        /// (`point_map`) from `filtered_vertex` when `filtered_points`, else from `vertex`;
        /// at a coarser level both from that level's vertex map.
        VertexToNormal { level: usize, filtered: bool, filtered_points: bool } => vertex_to_normal,
        /// `pyramid_depth` making level `level >= 1` from level `level - 1`'s vertex map (at
        /// level 1 the filtered one when `filtered`).
        PyramidDepth { level: usize, filtered: bool } => pyramid_depth,
    }
    at(call) {
        match call {
            PreprocessCall::VertexToNormal { level, filtered, filtered_points } => At {
                level,
                filtered,
                filtered_points,
                ..At::FRAME
            },
            PreprocessCall::PyramidDepth { level, filtered } => At {
                level,
                filtered,
                ..At::FRAME
            },
            _ => At::FRAME,
        }
    }
}

step_calls! {
    /// One call of the `predict` plan.
    PredictCall {
        /// `block_bounds` over the blocks whose boxes are stale (fusion appended to them, or
        /// the map was compacted or uploaded); nothing when none are. Every culling step
        /// starts with it.
        BlockBounds => block_bounds,
        /// Zero the index map ([`Buffer::IndexMap`]).
        ClearIndexMap => clear,
        /// `project_model`: the map -> `index_map` at the predicted view.
        ProjectModel => project_model,
        /// `predict_model`: `index_map` and the map -> level 0's `pred_vertex`, `pred_normal`.
        PredictModel => predict_model,
        /// `pyramid_model` making level `level >= 1`'s predicted maps from level
        /// `level - 1`'s.
        PyramidModel { level: usize } => pyramid_model,
    }
    at(call) {
        match call {
            PredictCall::PyramidModel { level } => At::of_level(level),
            _ => At::FRAME,
        }
    }
}

step_calls! {
    /// One call of the `fuse` plan.
    FuseCall {
        /// Zero a buffer.
        Clear(Buffer) => clear,
        /// `block_bounds`, as in [`PredictCall::BlockBounds`].
        BlockBounds => block_bounds,
        /// `fuse_select`: each pixel chooses a surfel (best-candidate association).
        FuseSelect => fuse_select,
        /// `fuse_merge_chosen`: each chosen surfel merges its pixel's measurement.
        FuseMergeChosen => fuse_merge_chosen,
        /// `fuse_prune`: surfels this frame did not refresh retire next to a merged twin.
        FusePrune => fuse_prune,
        /// `fuse_merge`: every surfel merges with the pixel it projects to (projective).
        FuseMerge => fuse_merge,
        /// `fuse_flags`: which pixels become new surfels, in append order.
        FuseFlags => fuse_flags,
        /// The scan over `fuse_flags`' flags: the sum of each block of flags,
        FuseScanReduce => prefix_sum_reduce,
        /// the blocks' offsets and the total (how many new surfels),
        FuseScanBlocks => prefix_sum_blocks,
        /// and each new surfel's slot.
        FuseScan => prefix_sum,
        /// `fuse_add`: append the new surfels; with `index_words` (best-candidate
        /// association, which builds the next prediction's index map) also every pass of
        /// the portable kernel (its second only sets index words, which projective
        /// association leaves alone).
        FuseAdd { index_words: bool } => fuse_add,
    }
    at(call) {
        match call {
            FuseCall::FuseScanReduce | FuseCall::FuseScanBlocks | FuseCall::FuseScan => {
                At::of_scan(Scanned::NewSurfels)
            }
            _ => At::FRAME,
        }
    }
    every_key_pass(call) {
        match call {
            FuseCall::FuseAdd { index_words } => index_words,
            _ => true,
        }
    }
}

step_calls! {
    /// One call of the plan that makes the frame's intensity pyramid (RGB-D tracking's
    /// photometric term reads it; each level is made as a `rgbd_system` first reads it or a
    /// coarser one).
    IntensityCall {
        /// `intensity_pyramid` making level `level` (level 0 from the colour map, a
        /// coarser level from level `level - 1`'s intensity patches).
        IntensityPyramid { level: usize } => intensity_pyramid,
    }
    at(call) {
        match call {
            IntensityCall::IntensityPyramid { level } => At::of_level(level),
        }
    }
}

step_calls! {
    /// One call of the `icp_system` and `rgbd_system` plans: one ICP iteration's
    /// normal-equation systems at a pyramid level.
    SystemCall {
        /// `icp_reduce` at pyramid level `level`: the geometric (point-to-plane) rows into
        /// per-workgroup partial systems (on the CPU one partial, its sums f64).
        IcpReduce { level: usize } => icp_reduce,
        /// `photo_reduce` at pyramid level `level`: the photometric rows (against level 0's
        /// prediction) likewise.
        PhotoReduce { level: usize } => photo_reduce,
        /// `icp_reduce_final`: the system's partial systems summed into one (on the CPU
        /// its one f64 partial, given back unchanged).
        SumPartials(System) => icp_reduce_final,
    }
    at(call) {
        match call {
            SystemCall::IcpReduce { level } => At::of_system(level, System::Geometric),
            SystemCall::PhotoReduce { level } => At::of_system(level, System::Photometric),
            SystemCall::SumPartials(system) => At::of_system(0, system),
        }
    }
}

step_calls! {
    /// One call of the `compact` plan.
    CompactCall {
        /// `compact_flags`: keep or remove each surfel.
        Flags => compact_flags,
        /// The scan over the keep flags: the sum of each block of flags,
        ScanReduce => prefix_sum_reduce,
        /// the blocks' offsets and the total (how many survive),
        ScanBlocks => prefix_sum_blocks,
        /// and each survivor's slot.
        Scan => prefix_sum,
        /// `compact_scatter`: copy each survivor into the second map.
        Scatter => compact_scatter,
    }
    at(call) {
        match call {
            CompactCall::ScanReduce | CompactCall::ScanBlocks | CompactCall::Scan => {
                At::of_scan(Scanned::KeepFlags)
            }
            _ => At::FRAME,
        }
    }
}

step_calls! {
    /// The steps of one kernel each (relocalisation, tracking health, loop closure): the
    /// plan of such a step is its one call, [`encode_ferns`], [`count_candidates`],
    /// [`detect_keypoints`], [`describe_keypoints`] or [`deform`].
    Single {
        /// `fern_encode`: one code per fern from the frame's level-0 maps.
        FernEncode => fern_encode,
        /// `icp_candidates`: per workgroup, the pixels with an ICP candidate at level 0.
        IcpCandidates => icp_candidates,
        /// `keypoint_detect`: corners of the frame's colour map with a valid depth.
        KeypointDetect => keypoint_detect,
        /// `keypoint_describe`: a binary descriptor and a camera-frame point per keypoint.
        KeypointDescribe => keypoint_describe,
        /// `deform_surfels`: every live surfel moved by the loop closure's deformation.
        DeformSurfels => deform_surfels,
    }
}

step_calls! {
    /// One call of scan registration's correspondence plan ([`scan_correspondences`]), over
    /// the caller's pool (`registry::Shape::bound_by_caller`): its `queries`, the target's
    /// `targets` or hashed grid (`grid_points`, `bucket_start`), each query's nearest
    /// neighbour (`results`, read back as `nn`) and the per-workgroup `partials`.
    ScanCall {
        /// `nn_brute` over target points `begin..end`, continuing from the results of the
        /// range before (the ranges in order make the nearest of all).
        NnBrute { begin: u32, end: u32 } => nn_brute,
        /// `nn_grid`: each query's nearest target point through the hashed grid.
        NnGrid => nn_grid,
        /// `cross_covariance`: the inlier pairs into per-workgroup partials.
        CrossCovariance => cross_covariance,
    }
}

step_calls! {
    /// One call of the renderer's plan ([`render`]), over the caller's pool: the cloud's
    /// `positions`, `normals`, `colors`, `weights`, the picture's `index_map` and `out_rgba`.
    RenderCall {
        /// Zero the index map.
        ClearIndexMap => clear,
        /// `render_splat`: the nearest surfel's key per pixel.
        RenderSplat => render_splat,
        /// `render_resolve`: each pixel's colour from its key (or a neighbour's).
        RenderResolve => render_resolve,
    }
}

/// Scan registration's correspondences against a target of `n_targets` points: each
/// query's nearest neighbour, through the hashed grid (`grid`) or by brute force in ranges
/// of `SCAN_BRUTE_CHUNK` targets (one call each, in order: a dispatch stays short); then,
/// with `reduce`, the inlier pairs' cross-covariance.
pub fn scan_correspondences(grid: bool, n_targets: u32, reduce: bool) -> Vec<ScanCall> {
    let mut plan = match grid {
        true => vec![ScanCall::NnGrid],
        false => (0..n_targets)
            .step_by(SCAN_BRUTE_CHUNK as usize)
            .map(|begin| ScanCall::NnBrute {
                begin,
                end: (begin + SCAN_BRUTE_CHUNK).min(n_targets),
            })
            .collect(),
    };
    if reduce {
        plan.push(ScanCall::CrossCovariance);
    }
    plan
}

/// A picture of a cloud: a cleared index map, the splats' keys, the pixels.
pub fn render() -> Vec<RenderCall> {
    vec![
        RenderCall::ClearIndexMap,
        RenderCall::RenderSplat,
        RenderCall::RenderResolve,
    ]
}

/// `encode_ferns`: `fern_encode`.
pub const fn encode_ferns() -> Single {
    Single::FernEncode
}

/// `count_candidates`: `icp_candidates`.
pub const fn count_candidates() -> Single {
    Single::IcpCandidates
}

/// `detect_keypoints`: `keypoint_detect`.
pub const fn detect_keypoints() -> Single {
    Single::KeypointDetect
}

/// `describe_keypoints`: `keypoint_describe`.
pub const fn describe_keypoints() -> Single {
    Single::KeypointDescribe
}

/// `deform`: `deform_surfels`.
pub const fn deform() -> Single {
    Single::DeformSurfels
}

/// `preprocess`: `depth_to_vertex`, with the filter (`bilateral`) `bilateral_filter`, then
/// `vertex_to_normal` (normals from the filtered vertex map with the filter, points from it
/// too only with its `filter_points`); then for each of the `coarser_levels` pyramid levels 1,
/// 2, ... `pyramid_depth` and `vertex_to_normal`.
pub fn preprocess(
    bilateral: Option<&BilateralParams>,
    coarser_levels: usize,
) -> Vec<PreprocessCall> {
    let filtered = bilateral.is_some();
    let filter_points = bilateral.is_some_and(|b| b.filter_points != 0);
    let mut plan = vec![PreprocessCall::DepthToVertex];
    if filtered {
        plan.push(PreprocessCall::BilateralFilter);
    }
    plan.push(PreprocessCall::VertexToNormal {
        level: 0,
        filtered,
        filtered_points: filtered && filter_points,
    });
    for level in 1..=coarser_levels {
        plan.push(PreprocessCall::PyramidDepth { level, filtered });
        plan.push(PreprocessCall::VertexToNormal {
            level,
            filtered: false,
            filtered_points: false,
        });
    }
    plan
}

/// `predict`: unless the last fusion left the index map of this very view (`project`
/// false, see [`crate::fused_view::FusedView`]), fresh block boxes, a cleared index
/// map and `project_model`; then `predict_model` and `pyramid_model` per coarser level.
pub fn predict(project: bool, coarser_levels: usize) -> Vec<PredictCall> {
    let mut plan = Vec::new();
    if project {
        plan.extend([
            PredictCall::BlockBounds,
            PredictCall::ClearIndexMap,
            PredictCall::ProjectModel,
        ]);
    }
    plan.push(PredictCall::PredictModel);
    plan.extend((1..=coarser_levels).map(|level| PredictCall::PyramidModel { level }));
    plan
}

/// `fuse` with `params`: cleared association buffers (and, with best-candidate
/// association, the merged surfels and the index map it builds), fresh block boxes; then
/// best candidate `fuse_select`, `fuse_merge_chosen` and with a prune scale `fuse_prune`,
/// or projective `fuse_merge`; then `fuse_flags`, their prefix sum (three kernels) and
/// `fuse_add`.
pub fn fuse(params: &FuseParams) -> Vec<FuseCall> {
    let best_candidate = params.association == ASSOCIATION_BEST_CANDIDATE;
    let mut plan = vec![FuseCall::Clear(Buffer::Assoc)];
    if best_candidate {
        plan.extend([
            FuseCall::Clear(Buffer::Merged),
            FuseCall::Clear(Buffer::IndexMap),
        ]);
    }
    plan.push(FuseCall::BlockBounds);
    if best_candidate {
        plan.extend([FuseCall::FuseSelect, FuseCall::FuseMergeChosen]);
        if params.prune_scale > 0.0 {
            plan.push(FuseCall::FusePrune);
        }
    } else {
        plan.push(FuseCall::FuseMerge);
    }
    plan.extend([
        FuseCall::FuseFlags,
        FuseCall::FuseScanReduce,
        FuseCall::FuseScanBlocks,
        FuseCall::FuseScan,
        FuseCall::FuseAdd {
            index_words: best_candidate,
        },
    ]);
    plan
}

/// The frame's intensity pyramid up to `level` where the first `made` levels are made
/// since the frame's `preprocess`: `intensity_pyramid` at levels `made..=level`, finest
/// first (none when `made > level`).
pub fn intensity_levels(made: usize, level: usize) -> Vec<IntensityCall> {
    (made..=level)
        .map(|level| IntensityCall::IntensityPyramid { level })
        .collect()
}

/// `icp_system` at pyramid level `level`: `icp_reduce`, then the sum of its partials.
pub fn icp_system(level: usize) -> Vec<SystemCall> {
    vec![
        SystemCall::IcpReduce { level },
        SystemCall::SumPartials(System::Geometric),
    ]
}

/// `rgbd_system` at pyramid level `level` (after the intensity pyramid's
/// [`intensity_levels`]): `icp_system`'s, then `photo_reduce` and the sum of its partials.
pub fn rgbd_system(level: usize) -> Vec<SystemCall> {
    let mut plan = icp_system(level);
    plan.extend([
        SystemCall::PhotoReduce { level },
        SystemCall::SumPartials(System::Photometric),
    ]);
    plan
}

/// `compact`: keep flags, their prefix sum (three kernels), and the copy of the survivors.
pub fn compact() -> Vec<CompactCall> {
    vec![
        CompactCall::Flags,
        CompactCall::ScanReduce,
        CompactCall::ScanBlocks,
        CompactCall::Scan,
        CompactCall::Scatter,
    ]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::layout::ASSOCIATION_PROJECTIVE;

    /// The plans name the kernels of their steps in the order the README and the pipeline's
    /// table give.
    #[test]
    fn plans_list_each_steps_kernels_in_order() {
        macro_rules! names {
            ($plan:expr) => {
                $plan.into_iter().map(|c| c.name()).collect::<Vec<_>>()
            };
        }
        assert_eq!(
            names!(preprocess(Some(&bytemuck::Zeroable::zeroed()), 1)),
            [
                "depth_to_vertex",
                "bilateral_filter",
                "vertex_to_normal",
                "pyramid_depth",
                "vertex_to_normal"
            ]
        );
        assert_eq!(
            names!(predict(true, 0)),
            ["block_bounds", "clear", "project_model", "predict_model"]
        );
        assert_eq!(
            names!(predict(false, 1)),
            ["predict_model", "pyramid_model"]
        );
        let mut p: FuseParams = bytemuck::Zeroable::zeroed();
        p.association = ASSOCIATION_BEST_CANDIDATE;
        p.prune_scale = 0.5;
        assert_eq!(
            names!(fuse(&p)),
            [
                "clear",
                "clear",
                "clear",
                "block_bounds",
                "fuse_select",
                "fuse_merge_chosen",
                "fuse_prune",
                "fuse_flags",
                "prefix_sum_reduce",
                "prefix_sum_blocks",
                "prefix_sum",
                "fuse_add"
            ]
        );
        p.association = ASSOCIATION_PROJECTIVE;
        assert_eq!(
            names!(fuse(&p)),
            [
                "clear",
                "block_bounds",
                "fuse_merge",
                "fuse_flags",
                "prefix_sum_reduce",
                "prefix_sum_blocks",
                "prefix_sum",
                "fuse_add"
            ]
        );
        assert_eq!(names!(icp_system(1)), ["icp_reduce", "icp_reduce_final"]);
        assert_eq!(
            names!(rgbd_system(0)),
            [
                "icp_reduce",
                "icp_reduce_final",
                "photo_reduce",
                "icp_reduce_final"
            ]
        );
        assert_eq!(
            names!(compact()),
            [
                "compact_flags",
                "prefix_sum_reduce",
                "prefix_sum_blocks",
                "prefix_sum",
                "compact_scatter"
            ]
        );
        assert_eq!(
            names!(render()),
            ["clear", "render_splat", "render_resolve"]
        );
        assert_eq!(
            names!(scan_correspondences(true, 5, true)),
            ["nn_grid", "cross_covariance"]
        );
        let brute = scan_correspondences(false, SCAN_BRUTE_CHUNK * 2 + 1, false);
        assert_eq!(
            brute.iter().map(|c| (c.name(), *c)).collect::<Vec<_>>(),
            [0, 1, 2].map(|i| {
                let begin = i * SCAN_BRUTE_CHUNK;
                let end = (begin + SCAN_BRUTE_CHUNK).min(SCAN_BRUTE_CHUNK * 2 + 1);
                ("nn_brute", ScanCall::NnBrute { begin, end })
            })
        );
    }

    /// Every place a plan runs a `PerLevel` kernel is one the GPU engine binds
    /// ([`At::choices`]), with and without the filter and its filtered points.
    #[test]
    fn every_planned_level_is_a_bound_choice() {
        let mut b: BilateralParams = bytemuck::Zeroable::zeroed();
        for filter_points in [0, 1] {
            b.filter_points = filter_points;
            for bilateral in [None, Some(&b)] {
                for levels in 0..4 {
                    let ats = preprocess(bilateral, levels).into_iter().map(|c| c.at());
                    let ats = ats.chain(predict(true, levels).into_iter().map(|c| c.at()));
                    let ats = ats.chain(intensity_levels(0, levels).into_iter().map(|c| c.at()));
                    for at in ats {
                        assert!(
                            At::choices(at.level).contains(&at.choice()),
                            "{at:?} ({bilateral:?}, {levels} levels)"
                        );
                    }
                }
            }
        }
    }
}
