//! A [`Backend`] decorator that watches the pipeline's steps: wall-clock time per step
//! (for `wgslam bench`), and the ICP systems and the surfel count after fusion of the
//! current frame (for `wgslam compare`).
//!
//! With timing on, it calls [`Backend::finish`] after each step, so asynchronous GPU work
//! is charged to the step that queued it. This costs the overlap between steps, so
//! benchmarks report per-stage times from one run and whole-frame times from a run without
//! timing. With timing off, it only records and adds no synchronisation. This is the one
//! place that forwards the [`Backend`] trait step by step (besides `Box<dyn Backend>`).

use std::collections::BTreeMap;
use web_time::Instant;

use crate::layout::map::SurfelMap;
use crate::layout::{
    CompactParams, DeformNode, Fern, FernParams, FuseParams, IcpParams, Keypoint, KeypointParams,
    ProjectParams, ICP_SYSTEM_LEN,
};
use crate::slam::backend::{
    Backend, Described, Inspect, NextFrame, Prediction, PreprocessSteps, PyramidLevel, RgbdSystems,
    ToDescribe,
};
use crate::Result;

/// Wraps a backend. `stages` maps a step name to (calls, total seconds) when timing;
/// `frame_systems` holds the pyramid level and 29-float ICP system of every iteration of
/// the frame in flight, in order (cleared
/// by `preprocess`, so after a frame it holds that frame's iterations); `fused_surfels` the
/// surfel count after `fuse` in that frame (before `compact`), `None` if it did not fuse.
pub struct Instrumented<B: Backend> {
    pub inner: B,
    pub stages: BTreeMap<&'static str, (u64, f64)>,
    pub frame_systems: Vec<(usize, [f64; ICP_SYSTEM_LEN])>,
    pub fused_surfels: Option<usize>,
    timing: bool,
}

impl<B: Backend> Instrumented<B> {
    /// Times every step (and records the ICP systems).
    pub fn timed(inner: B) -> Self {
        Instrumented {
            inner,
            stages: BTreeMap::new(),
            frame_systems: Vec::new(),
            fused_surfels: None,
            timing: true,
        }
    }

    /// Records the ICP systems only: no timing, no extra synchronisation.
    pub fn recording(inner: B) -> Self {
        Instrumented {
            timing: false,
            ..Self::timed(inner)
        }
    }

    /// Forgets the last frame's ICP systems and fused count (`preprocess` does it; a frame
    /// skipped before `preprocess`, e.g. one without depth, would otherwise show the last).
    pub fn clear_frame(&mut self) {
        self.frame_systems.clear();
        self.fused_surfels = None;
    }

    fn step<T>(&mut self, name: &'static str, f: impl FnOnce(&mut B) -> Result<T>) -> Result<T> {
        if !self.timing {
            return f(&mut self.inner);
        }
        let t0 = Instant::now();
        let out = f(&mut self.inner)?;
        self.record(name, t0)?;
        Ok(out)
    }

    /// Counts a call of step `name` begun at `t0`, once its work has finished (when timing).
    fn record(&mut self, name: &'static str, t0: Instant) -> Result<()> {
        if self.timing {
            self.inner.finish()?;
            let e = self.stages.entry(name).or_insert((0, 0.0));
            e.0 += 1;
            e.1 += t0.elapsed().as_secs_f64();
        }
        Ok(())
    }
}

impl<B: Backend> Backend for Instrumented<B> {
    fn name(&self) -> &'static str {
        self.inner.name()
    }
    fn preprocess(&mut self, steps: &PreprocessSteps, depth: &[u16], rgba: &[u32]) -> Result<()> {
        self.clear_frame();
        self.step("preprocess", |b| b.preprocess(steps, depth, rgba))
    }
    fn preprocess_staged(&mut self, steps: &PreprocessSteps, frame_id: u32) -> Result<bool> {
        // A `preprocess` call when it ran; else the `preprocess` that follows is the call.
        let t0 = Instant::now();
        let staged = self.inner.preprocess_staged(steps, frame_id)?;
        if staged {
            self.clear_frame();
            self.record("preprocess", t0)?;
        }
        Ok(staged)
    }
    fn predict(&mut self, params: &ProjectParams, pyramid: &[PyramidLevel]) -> Result<()> {
        self.step("predict", |b| b.predict(params, pyramid))
    }
    fn icp_system(&mut self, level: usize, params: &IcpParams) -> Result<[f64; ICP_SYSTEM_LEN]> {
        let system = self.step("icp_iteration", |b| b.icp_system(level, params))?;
        self.frame_systems.push((level, system));
        Ok(system)
    }
    fn rgbd_system(&mut self, level: usize, params: &IcpParams) -> Result<RgbdSystems> {
        let systems = self.step("icp_iteration", |b| b.rgbd_system(level, params))?;
        self.frame_systems.push((level, systems[0]));
        Ok(systems)
    }
    fn count_candidates(&mut self, params: &IcpParams) -> Result<u64> {
        // Timed under its kernel's name, as before the step was renamed.
        self.step("icp_candidates", |b| b.count_candidates(params))
    }
    fn encode_ferns(&mut self, params: &FernParams, ferns: &[Fern]) -> Result<Vec<u32>> {
        self.step("encode_ferns", |b| b.encode_ferns(params, ferns))
    }
    fn detect_keypoints(&mut self, params: &KeypointParams) -> Result<(Vec<Keypoint>, u32)> {
        self.step("detect_keypoints", |b| b.detect_keypoints(params))
    }
    fn describe_keypoints(&mut self, what: ToDescribe) -> Result<Described> {
        self.step("describe_keypoints", |b| b.describe_keypoints(what))
    }
    fn fuse(&mut self, params: &FuseParams, next: Option<NextFrame<'_>>) -> Result<()> {
        self.step("fuse", |b| b.fuse(params, next))?;
        // For `compare`'s per-frame check: on a GPU without timing a wait for the fusion,
        // which the plain frame loop does not make (see `Backend::fuse`).
        self.fused_surfels = Some(self.inner.surfel_count()?);
        Ok(())
    }
    fn compact(&mut self, params: &CompactParams) -> Result<usize> {
        self.step("compact", |b| b.compact(params))
    }
    fn deform(&mut self, nodes: &[DeformNode]) -> Result<()> {
        self.step("deform", |b| b.deform(nodes))
    }
    fn frame_level(&mut self, level: usize) -> Result<Prediction> {
        self.step("loop_snapshot", |b| b.frame_level(level))
    }
    fn set_prediction(&mut self, level: usize, prediction: &Prediction) -> Result<()> {
        self.step("loop_prediction", |b| b.set_prediction(level, prediction))
    }
    fn surfel_count(&mut self) -> Result<usize> {
        self.inner.surfel_count()
    }
    fn finish(&mut self) -> Result<()> {
        self.inner.finish()
    }
}

impl<B: Backend + Inspect> Inspect for Instrumented<B> {
    fn download_map(&mut self) -> Result<SurfelMap> {
        self.inner.download_map()
    }
    fn upload_map(&mut self, map: &SurfelMap) -> Result<()> {
        self.inner.upload_map(map)
    }
    wgslam_core::inspect_through!(inner);
}
