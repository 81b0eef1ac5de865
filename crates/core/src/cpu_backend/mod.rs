//! The CPU reference backend: runs the CPU twins in `cpu/` over host vectors, each step in
//! the order of its plan (`crate::plan`, shared with the GPU backend), every twin through
//! its registry row (`engine.rs`, bound by the WGSL names from pools of the backend's
//! buffers).
//!
//! This is the ground the GPU backend is proven against, so it favours being obviously
//! the same as the shaders over being fast; the map grows as a `Vec` without a capacity cap
//! and is bound to the map twins as one chunk (`MapChunk { base: 0, slots: len }`: see
//! `engine.rs`). It keeps the culling blocks' boxes as the GPU backend does (recomputed
//! for the blocks fusion appended to, all of them after a compaction or an upload, before
//! the next culling step), so its cost per frame also follows what the camera sees.
//!
//! The steps whose twins spread their invocations over threads (`preprocess`, `predict`,
//! the ICP systems and candidates, `fuse`) run inside the backend's [`Threads`]
//! (`cpu::invocations`); the outputs are the same bits on any number of threads.

use crate::backend::{
    Backend, Described, FrameLevel, FrameMaps, Prediction, PreprocessSteps, PyramidLevel,
    ToDescribe,
};
use crate::backend::{NextFrame, RgbdSystems};
use crate::cpu;
use crate::cpu::binding::Pool;
use crate::cpu::invocations::Threads;
use crate::fused_view::FusedView;
use crate::layout::map::SurfelMap;
use crate::layout::{
    BoundsParams, CompactParams, DeformNode, DeformParams, Fern, FernParams, FuseParams, IcpParams,
    Keypoint, KeypointParams, ProjectParams, BLOCK_SURFELS, DESCRIPTOR_WORDS, ICP_SYSTEM_LEN,
};
use crate::plan::{self, Call, CompactCall, PredictCall};
use crate::Result;

/// Host-side state: the current frame's maps (with its pyramid), the prediction (one per
/// pyramid level) and the surfel map.
#[derive(Debug, Default)]
pub struct CpuBackend {
    frame: FrameMaps,
    /// `project_model`'s keys, or the last best-candidate fusion's (see [`FusedView`]).
    index_map: Vec<u64>,
    /// The view `index_map` was built at by the last `fuse`, while the map is as that
    /// fusion left it.
    fused_view: Option<FusedView>,
    /// The predicted vertex and normal maps per pyramid level, level 0 first.
    prediction: Vec<Prediction>,
    /// `predict_model`'s predicted intensity (level 0; see `cpu::photo_reduce`).
    pred_intensity: Vec<f32>,
    /// The frame's intensity pyramid, made by `rgbd_system` (see `systems.rs`).
    intensity: systems::IntensityPyramid,
    assoc: Vec<u64>,
    /// Per pixel, the surfel it merged into (two entries; see `fuse_merge_chosen`), filled
    /// on every frame of best-candidate association (`fuse_flags`, `fuse_prune`).
    merged: Vec<[f32; 4]>,
    /// Fusion's new-surfel flag and slot offset per pixel (`fuse_flags`, `prefix_sum`), in
    /// append order (`append_slots` entries; see `layout::APPEND_TILE_PX`).
    add_flags: Vec<u32>,
    add_offsets: Vec<u32>,
    map: SurfelMap,
    /// Compaction's keep flags, offsets and second map, kept between frames (the map and
    /// `spare` swap after each compaction, as the GPU's map chunks do).
    flags: Vec<u32>,
    offsets: Vec<u32>,
    spare: SurfelMap,
    /// The scan's per-block sums (fusion's scan's, then compaction's).
    block_sums: Vec<u32>,
    /// Per culling block, its box: entries `2b` (min), `2b + 1` (max), ordered-encoded.
    block_boxes: Vec<[u32; 4]>,
    /// Blocks from the one holding this surfel index on have stale boxes.
    bounds_dirty_from: usize,
    /// The threads the twins run on (rayon's global pool unless bounded).
    threads: Threads,
}

impl CpuBackend {
    /// An empty map.
    pub fn new() -> Self {
        Self::default()
    }

    /// A backend starting from `map` (to resume from a saved map, or to start both backends
    /// from the same map; [`crate::backend::Inspect::upload_map`] does the same later).
    pub fn with_map(map: SurfelMap) -> Self {
        map.assert_consistent();
        CpuBackend {
            map,
            ..Self::default()
        }
    }

    /// An empty map whose twins run on `threads` (`--threads N`, or a batch job's share).
    pub fn with_threads(threads: Threads) -> Self {
        CpuBackend {
            threads,
            ..Self::default()
        }
    }

    /// The map without copying.
    pub fn map(&self) -> &SurfelMap {
        &self.map
    }

    /// The index map: `project_model`'s of the last `predict`, or the one the last
    /// best-candidate `fuse` built (see [`FusedView`]); one packed key per pixel.
    pub fn index_map(&self) -> &[u64] {
        &self.index_map
    }

    /// Recomputes the stale block boxes: `call`, a plan's `block_bounds` (as the GPU backend
    /// records it at the start of a culling submission), where a box is stale.
    fn refresh_bounds(&mut self, call: impl Call) {
        let n = self.map.len();
        if self.bounds_dirty_from < n {
            let blocks = n.div_ceil(BLOCK_SURFELS as usize);
            self.block_boxes.resize(2 * blocks, [0; 4]);
            let bounds = BoundsParams::stale(n, self.bounds_dirty_from);
            let mut step = Pool::new();
            step.uniform("bounds", &bounds);
            self.dispatch(call, step);
        }
        self.bounds_dirty_from = n;
    }

    /// The block boxes (for tests: every surfel must lie in its block's box).
    pub fn block_boxes(&self) -> &[[u32; 4]] {
        &self.block_boxes
    }
}

impl Backend for CpuBackend {
    fn name(&self) -> &'static str {
        "cpu"
    }

    fn preprocess(&mut self, steps: &PreprocessSteps, depth: &[u16], rgba: &[u32]) -> Result<()> {
        // The step's twins on this backend's threads (`cpu::invocations::Threads`).
        self.threads.clone().install(|| {
            self.intensity.new_frame(&steps.params, &steps.pyramid);
            size_frame(&mut self.frame, steps);
            for call in plan::preprocess(steps.bilateral.as_ref(), steps.pyramid.len()) {
                let mut step = Pool::new();
                step.read("raw_depth", depth);
                step.read("raw_rgba", rgba);
                preprocess_uniforms(steps, call.at().level, &mut step);
                self.dispatch(call, step);
            }
            Ok(())
        })
    }

    fn predict(&mut self, params: &ProjectParams, pyramid: &[PyramidLevel]) -> Result<()> {
        // The step's twins on this backend's threads (`cpu::invocations::Threads`).
        self.threads.clone().install(|| {
            let mut params = *params;
            params.surfel_count = self.map.len() as u32;
            let n = (params.camera.width * params.camera.height) as usize;
            let project = !self.fused_view.is_some_and(|v| v.is_view_of(&params));
            if project {
                // The index map is about to hold another view (a relocalisation attempt
                // predicts at a keyframe's pose): the fused one is gone.
                self.fused_view = None;
            }
            self.prediction
                .resize_with(1 + pyramid.len(), Default::default);
            // The coarser levels' predicted maps (`pyramid_model`'s).
            for (p, (vertex, normal)) in pyramid.iter().zip(&mut self.prediction[1..]) {
                let n = (p.down.camera.width * p.down.camera.height) as usize;
                vertex.resize(n, cpu::INVALID);
                normal.resize(n, cpu::INVALID);
            }
            for call in plan::predict(project, pyramid.len()) {
                let mut step = Pool::new();
                step.uniform("project", &params);
                match call {
                    PredictCall::BlockBounds => self.refresh_bounds(call),
                    PredictCall::ClearIndexMap => {
                        crate::cpu::invocations::par_fill(&mut self.index_map, n, 0);
                    }
                    PredictCall::ProjectModel => self.dispatch(call, step),
                    PredictCall::PredictModel => {
                        let (pred_vertex, pred_normal) = &mut self.prediction[0];
                        pred_vertex.resize(n, cpu::INVALID);
                        pred_normal.resize(n, cpu::INVALID);
                        self.pred_intensity
                            .resize(n, cpu::photo_reduce::INTENSITY_NONE);
                        self.dispatch(call, step);
                    }
                    PredictCall::PyramidModel { level } => {
                        step.uniform("pyramid", &pyramid[level - 1].down);
                        self.dispatch(call, step);
                    }
                }
            }
            Ok(())
        })
    }

    fn icp_system(&mut self, level: usize, params: &IcpParams) -> Result<[f64; ICP_SYSTEM_LEN]> {
        // The step's twins on this backend's threads (`cpu::invocations::Threads`).
        self.threads.clone().install(|| {
            self.check_system_level(level, "ICP")?;
            let [geometric, _] = self.run_systems(plan::icp_system(level), params);
            Ok(geometric)
        })
    }

    fn rgbd_system(&mut self, level: usize, params: &IcpParams) -> Result<RgbdSystems> {
        // The step's twins on this backend's threads (`cpu::invocations::Threads`).
        self.threads.clone().install(|| {
            self.check_system_level(level, "RGB-D ICP")?;
            Ok(self.run_systems(plan::rgbd_system(level), params))
        })
    }

    fn count_candidates(&mut self, params: &IcpParams) -> Result<u64> {
        // The step's twins on this backend's threads (`cpu::invocations::Threads`).
        self.threads.clone().install(|| {
            if self.prediction.is_empty() {
                return Err(crate::Error::Argument(
                    "count_candidates() before predict()".into(),
                ));
            }
            // One workgroup's count: the total.
            let mut counts = [0u32];
            let mut step = Pool::new();
            step.uniform("icp", params);
            step.write("counts", &mut counts);
            self.dispatch(plan::count_candidates(), step);
            Ok(counts[0] as u64)
        })
    }

    fn encode_ferns(&mut self, params: &FernParams, ferns: &[Fern]) -> Result<Vec<u32>> {
        let mut codes = vec![0; params.fern_count as usize];
        let mut step = Pool::new();
        step.uniform("ferns", params);
        step.read("ferns", ferns);
        step.write("codes", &mut codes);
        self.dispatch(plan::encode_ferns(), step);
        Ok(codes)
    }

    fn detect_keypoints(&mut self, params: &KeypointParams) -> Result<(Vec<Keypoint>, u32)> {
        let mut keypoints = vec![bytemuck::Zeroable::zeroed(); params.capacity as usize];
        let mut counter = [0u32];
        let mut step = Pool::new();
        step.uniform("keypoints", params);
        step.write("keypoints", &mut keypoints);
        step.write("counter", &mut counter);
        self.dispatch(plan::detect_keypoints(), step);
        keypoints.truncate(counter[0].min(params.capacity) as usize);
        Ok((keypoints, counter[0]))
    }

    fn describe_keypoints(&mut self, what: ToDescribe) -> Result<Described> {
        let ToDescribe {
            params,
            keypoints,
            pattern,
        } = what;
        let n = params.count as usize;
        let mut words = vec![0u32; n * DESCRIPTOR_WORDS];
        let mut points = vec![[0.0f32; 4]; n];
        let mut step = Pool::new();
        step.uniform("keypoints", params);
        step.read("keypoints", keypoints);
        step.read("pattern", pattern);
        step.write("descriptors", &mut words);
        step.write("points", &mut points);
        self.dispatch(plan::describe_keypoints(), step);
        let descriptors = words
            .chunks_exact(DESCRIPTOR_WORDS)
            .map(|c| c.try_into().expect("chunks of DESCRIPTOR_WORDS"))
            .collect();
        Ok((descriptors, points))
    }

    fn fuse(&mut self, params: &FuseParams, _next: Option<NextFrame<'_>>) -> Result<()> {
        // Nothing to upload ahead: `preprocess` reads the images where they are.
        // The step's twins on this backend's threads (`cpu::invocations::Threads`).
        self.threads.clone().install(|| self.fuse_step(params));
        Ok(())
    }

    fn compact(&mut self, params: &CompactParams) -> Result<usize> {
        let n = self.map.len();
        let mut params = *params;
        params.surfel_count = n as u32;
        let mut counter = 0u32;
        for call in plan::compact() {
            let mut step = Pool::new();
            step.uniform("compact", &params);
            match call {
                CompactCall::Flags => {
                    self.flags.resize(n, 0);
                    self.dispatch(call, step);
                }
                CompactCall::ScanReduce | CompactCall::ScanBlocks | CompactCall::Scan => {
                    self.scan_call(call, n, &mut counter);
                }
                // The second map, as large as the first (as on the GPU), cut to the survivors;
                // one call per surfel array, as the kernel is dispatched (`engine.rs`).
                CompactCall::Scatter => {
                    self.spare.resize(n);
                    self.dispatch(call, step);
                    self.spare.resize(counter as usize);
                }
            }
        }
        std::mem::swap(&mut self.map, &mut self.spare);
        // Every surfel may have moved to another block, and to another index.
        self.bounds_dirty_from = 0;
        self.fused_view = None;
        Ok(self.map.len())
    }

    fn deform(&mut self, nodes: &[DeformNode]) -> Result<()> {
        let n = self.map.len();
        if nodes.is_empty() || n == 0 {
            return Ok(());
        }
        let params = DeformParams {
            surfel_count: n as u32,
            node_count: nodes.len() as u32,
            _pad0: 0,
            _pad1: 0,
        };
        let mut step = Pool::new();
        step.uniform("deform", &params);
        step.read("nodes", nodes);
        self.dispatch(plan::deform(), step);
        // Every surfel may have left its block's box; the fused view is of the old map.
        self.bounds_dirty_from = 0;
        self.fused_view = None;
        Ok(())
    }

    fn frame_level(&mut self, level: usize) -> Result<Prediction> {
        let f = &self.frame;
        Ok(match level {
            0 => (f.vertex.clone(), f.normal_depth.clone()),
            l => {
                let lv = f.pyramid.get(l - 1).unwrap_or_else(|| {
                    panic!(
                        "frame_level({l}): the pyramid has {} levels",
                        1 + f.pyramid.len()
                    )
                });
                (lv.vertex.clone(), lv.normal_depth.clone())
            }
        })
    }

    fn set_prediction(&mut self, level: usize, (vertex, normal): &Prediction) -> Result<()> {
        let prediction = self
            .prediction
            .get_mut(level)
            .unwrap_or_else(|| panic!("set_prediction({level}) before a predict() of that level"));
        assert_eq!(
            vertex.len(),
            prediction.0.len(),
            "prediction size at level {level}"
        );
        prediction.0.copy_from_slice(vertex);
        prediction.1.copy_from_slice(normal);
        Ok(())
    }

    fn surfel_count(&mut self) -> Result<usize> {
        Ok(self.map.len())
    }
}

/// Sizes the frame's maps for `steps` before its kernels write them: level 0's (the
/// filtered vertex map empty without the filter: see `FrameMaps`) and the pyramid's.
fn size_frame(f: &mut FrameMaps, steps: &PreprocessSteps) {
    let n = (steps.params.camera.width * steps.params.camera.height) as usize;
    let filtered = if steps.bilateral.is_some() { n } else { 0 };
    for (map, n) in [
        (&mut f.vertex, n),
        (&mut f.filtered_vertex, filtered),
        (&mut f.normal_depth, n),
        (&mut f.color, n),
    ] {
        map.resize(n, cpu::INVALID);
    }
    f.pyramid
        .resize_with(steps.pyramid.len(), FrameLevel::default);
    for (p, level) in steps.pyramid.iter().zip(&mut f.pyramid) {
        let n = (p.down.camera.width * p.down.camera.height) as usize;
        level.vertex.resize(n, cpu::INVALID);
        level.normal_depth.resize(n, cpu::INVALID);
    }
}

/// `steps`' uniforms at pyramid level `level`, named as the registry's rows name them:
/// the frame's (`preprocess`, `bilateral`) and the level's (`normal`, and above level 0
/// `pyramid`, which makes it from the finer one).
fn preprocess_uniforms<'a>(steps: &'a PreprocessSteps, level: usize, pool: &mut Pool<'a>) {
    pool.uniform("preprocess", &steps.params);
    if let Some(bilateral) = &steps.bilateral {
        pool.uniform("bilateral", bilateral);
    }
    match level.checked_sub(1) {
        None => pool.uniform("normal", &steps.normal),
        Some(l) => {
            pool.uniform("normal", &steps.pyramid[l].normal);
            pool.uniform("pyramid", &steps.pyramid[l].down);
        }
    }
}

mod engine;
pub use engine::run_call;
mod fuse;
mod inspect;
mod systems;

#[cfg(test)]
mod tests;
