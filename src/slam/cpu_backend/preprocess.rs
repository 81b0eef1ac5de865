//! The CPU backend's `preprocess` step: the plan's kernels (`plan::preprocess`) over the
//! frame's maps, from the raw depth and colour to `normal_depth` and the pyramid's levels.

use crate::cpu;
use crate::layout::{BilateralParams, NormalParams, PreprocessParams};
use crate::slam::backend::{FrameLevel, FrameMaps, PyramidLevel};
use crate::slam::plan::{self, PreprocessCall};

/// `Backend::preprocess` on the CPU: `f` made from `raw_depth` and `raw_rgba` (see the
/// trait for the arguments).
pub(super) fn preprocess(
    f: &mut FrameMaps,
    params: &PreprocessParams,
    bilateral: Option<&BilateralParams>,
    normal: &NormalParams,
    pyramid: &[PyramidLevel],
    raw_depth: &[u16],
    raw_rgba: &[u32],
) {
    let n = (params.width * params.height) as usize;
    f.vertex.resize(n, cpu::INVALID);
    f.color.resize(n, cpu::INVALID);
    f.normal_depth.resize(n, cpu::INVALID);
    f.pyramid.resize_with(pyramid.len(), FrameLevel::default);
    // `filtered_vertex` is empty without the filter (see `FrameMaps`).
    if bilateral.is_none() {
        f.filtered_vertex.clear();
    }
    let filter_points = bilateral.is_some_and(|b| b.filter_points != 0);
    for call in plan::preprocess(bilateral.is_some(), filter_points, pyramid.len()) {
        match call {
            PreprocessCall::DepthToVertex => cpu::depth_to_vertex::depth_to_vertex(
                params,
                raw_depth,
                raw_rgba,
                &mut f.vertex,
                &mut f.color,
            ),
            PreprocessCall::BilateralFilter => {
                let b = bilateral.expect("the plan filters only with filter params");
                f.filtered_vertex.resize(n, cpu::INVALID);
                cpu::bilateral_filter::bilateral_filter(b, &f.vertex, &mut f.filtered_vertex);
            }
            // The normals see the filtered map when the filter is on, and so do the
            // points (through normal_depth, ICP and fusion) with `filtered_points`;
            // `vertex` stays unfiltered either way.
            PreprocessCall::VertexToNormal {
                level: 0,
                filtered,
                filtered_points,
            } => {
                let map = |filtered| match filtered {
                    true => &f.filtered_vertex,
                    false => &f.vertex,
                };
                cpu::vertex_to_normal::vertex_to_normal(
                    normal,
                    map(filtered),
                    &mut f.normal_depth,
                    map(filtered_points),
                );
            }
            PreprocessCall::VertexToNormal { level, .. } => {
                let l = &mut f.pyramid[level - 1];
                cpu::vertex_to_normal::vertex_to_normal(
                    &pyramid[level - 1].normal,
                    &l.vertex,
                    &mut l.normal_depth,
                    &l.vertex,
                );
            }
            // Each coarser level from the finer one's vertex map (level 0's: the one
            // the normals were made from).
            PreprocessCall::PyramidDepth { level, filtered } => {
                let p = &pyramid[level - 1];
                let (finer, coarser) = f.pyramid.split_at_mut(level - 1);
                let fine_vertex = match finer.last() {
                    Some(l) => &l.vertex,
                    None if filtered => &f.filtered_vertex,
                    None => &f.vertex,
                };
                let l = &mut coarser[0];
                let n = (p.down.width * p.down.height) as usize;
                l.vertex.resize(n, cpu::INVALID);
                l.normal_depth.resize(n, cpu::INVALID);
                cpu::pyramid_depth::pyramid_depth(&p.down, fine_vertex, &mut l.vertex);
            }
        }
    }
}
