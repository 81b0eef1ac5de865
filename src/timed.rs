//! A [`Backend`] decorator that measures the wall-clock time of every pipeline step.
//!
//! After each step it calls [`Backend::finish`], so asynchronous GPU work is charged to
//! the step that queued it. This costs the overlap between steps, so benchmarks report
//! per-stage times from one run and whole-frame times from a run without this decorator.

use std::collections::BTreeMap;
use std::time::Instant;

use crate::layout::{
    FuseParams, IcpParams, NormalParams, PreprocessParams, ProjectParams, ICP_SYSTEM_LEN,
};
use crate::map::SurfelMap;
use crate::pipeline::{Backend, BackendCounters, FrameMaps};
use crate::Result;

/// Wraps a backend; `stages` maps a step name to (calls, total seconds).
pub struct Timed<B: Backend> {
    pub inner: B,
    pub stages: BTreeMap<&'static str, (u64, f64)>,
}

impl<B: Backend> Timed<B> {
    /// Wraps `inner` with empty timings.
    pub fn new(inner: B) -> Self {
        Timed {
            inner,
            stages: BTreeMap::new(),
        }
    }

    fn time<T>(&mut self, name: &'static str, f: impl FnOnce(&mut B) -> Result<T>) -> Result<T> {
        let t0 = Instant::now();
        let out = f(&mut self.inner)?;
        self.inner.finish()?;
        let e = self.stages.entry(name).or_insert((0, 0.0));
        e.0 += 1;
        e.1 += t0.elapsed().as_secs_f64();
        Ok(out)
    }
}

impl<B: Backend> Backend for Timed<B> {
    fn name(&self) -> &'static str {
        self.inner.name()
    }
    fn preprocess(
        &mut self,
        params: &PreprocessParams,
        normal: &NormalParams,
        raw_depth: &[u16],
        raw_rgba: &[u32],
    ) -> Result<()> {
        self.time("preprocess", |b| {
            b.preprocess(params, normal, raw_depth, raw_rgba)
        })
    }
    fn predict(&mut self, params: &ProjectParams) -> Result<()> {
        self.time("predict", |b| b.predict(params))
    }
    fn icp_system(&mut self, params: &IcpParams) -> Result<[f64; ICP_SYSTEM_LEN]> {
        self.time("icp_iteration", |b| b.icp_system(params))
    }
    fn fuse(&mut self, params: &FuseParams) -> Result<usize> {
        self.time("fuse", |b| b.fuse(params))
    }
    fn surfel_count(&self) -> usize {
        self.inner.surfel_count()
    }
    fn download_map(&mut self) -> Result<SurfelMap> {
        self.inner.download_map()
    }
    fn download_frame(&mut self) -> Result<FrameMaps> {
        self.inner.download_frame()
    }
    fn download_prediction(&mut self) -> Result<crate::pipeline::Prediction> {
        self.inner.download_prediction()
    }
    fn counters(&self) -> BackendCounters {
        self.inner.counters()
    }
    fn finish(&mut self) -> Result<()> {
        self.inner.finish()
    }
}
