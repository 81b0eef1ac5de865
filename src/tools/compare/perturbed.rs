//! The CPU backend with its twins' arithmetic perturbed as a conformant GPU may round
//! ([`crate::cpu::arith`]): a third backend for [`super::compare`] that needs no GPU
//! (`wgslam compare --perturbed-cpu`), so the tolerances are shown to hold for any legal
//! rounding, not only lavapipe's. With a [`Plant`] it also carries a planted bug, for the
//! tests that prove the comparison still catches real ones.

use crate::cpu::arith::{self, Arith};
use crate::layout::map::SurfelMap;
use crate::layout::{
    CompactParams, DeformNode, Fern, FernParams, FuseParams, IcpParams, Keypoint, KeypointParams,
    ProjectParams, ICP_ATB_OFFSET, ICP_SYSTEM_LEN,
};
use crate::slam::backend::{
    Backend, Described, Inspect, NextFrame, Prediction, PreprocessSteps, PyramidLevel, RgbdSystems,
    ToDescribe,
};
use crate::slam::cpu_backend::CpuBackend;
use crate::Result;

/// Seed of `wgslam compare --perturbed-cpu`'s perturbation.
pub const DEFAULT_SEED: u64 = 0x33;

/// A bug planted in a [`PerturbedCpu`] (test-only: a comparison must fail with each).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Plant {
    /// Fusion's depth gate (`candidate_off_ray`'s distance along the pixel's ray,
    /// best-candidate association) 1 % wider than it is ([`arith::with_wide_depth_gate`]).
    /// The depth gate rather than the off-ray one: a surfel whose centre projects into a
    /// pixel lies at most about half a pixel's footprint off its ray, and its radius is at
    /// least 1.4 footprints, so the off-ray gate 1 % wide changed no decision on the
    /// bundled frames 1..6 (measured, exact arithmetic): a bug no output shows.
    FusionGateOnePercent,
    /// The sign of one entry of the ICP system's right-hand side flipped: row
    /// `SIGN_FLIPPED_ROW` (3) of `Aᵀb` (translation along camera x).
    SystemRowSign,
    /// One merge in [`arith::SKIPPED_MERGE_EVERY`] skipped (`merged_surfel` returns the
    /// surfel as it was; see [`arith::with_skipped_merges`]).
    SkippedMerge,
    /// Every `every`-th surfel of an uploaded map moved `shift_um` micrometres along world
    /// x: a map the backend received wrong (the frame maps, made from the raw frame alone,
    /// stay right).
    ShiftedUpload { shift_um: u32, every: usize },
}

/// The row of `Aᵀb` whose sign [`Plant::SystemRowSign`] flips.
pub const SIGN_FLIPPED_ROW: usize = 3;

/// The CPU backend whose twins run in `arith` mode, optionally with a planted bug. Every
/// step and copy goes to the inner [`CpuBackend`] with the mode set on this thread.
pub struct PerturbedCpu {
    inner: CpuBackend,
    arith: Arith,
    plant: Option<Plant>,
}

impl PerturbedCpu {
    /// The CPU backend with its arithmetic perturbed by `seed` (see [`Arith::Perturbed`]).
    pub fn new(seed: u64) -> Self {
        Self::with(Arith::Perturbed { seed }, None)
    }

    /// The CPU backend in `arith` mode with a planted bug, if any (test-only).
    pub fn with(arith: Arith, plant: Option<Plant>) -> Self {
        PerturbedCpu {
            inner: CpuBackend::new(),
            arith,
            plant,
        }
    }

    /// Runs `f` on the inner backend in this backend's mode (and its planted merge bug).
    fn run<R>(&mut self, f: impl FnOnce(&mut CpuBackend) -> R) -> R {
        let inner = &mut self.inner;
        arith::with(self.arith, || match self.plant {
            Some(Plant::SkippedMerge) => arith::with_skipped_merges(|| f(inner)),
            Some(Plant::FusionGateOnePercent) => arith::with_wide_depth_gate(|| f(inner)),
            _ => f(inner),
        })
    }
}

impl Backend for PerturbedCpu {
    fn name(&self) -> &'static str {
        match (self.arith, self.plant) {
            (_, Some(_)) => "cpu-planted-bug",
            (Arith::Exact, None) => "cpu",
            (Arith::Perturbed { .. }, None) => "cpu-perturbed",
        }
    }
    fn preprocess(&mut self, steps: &PreprocessSteps, depth: &[u16], rgba: &[u32]) -> Result<()> {
        self.run(|b| b.preprocess(steps, depth, rgba))
    }
    fn preprocess_staged(&mut self, steps: &PreprocessSteps, frame_id: u32) -> Result<bool> {
        self.run(|b| b.preprocess_staged(steps, frame_id))
    }
    fn predict(&mut self, params: &ProjectParams, pyramid: &[PyramidLevel]) -> Result<()> {
        self.run(|b| b.predict(params, pyramid))
    }
    fn icp_system(&mut self, level: usize, params: &IcpParams) -> Result<[f64; ICP_SYSTEM_LEN]> {
        let mut system = self.run(|b| b.icp_system(level, params))?;
        if self.plant == Some(Plant::SystemRowSign) {
            system[ICP_ATB_OFFSET + SIGN_FLIPPED_ROW] *= -1.0;
        }
        Ok(system)
    }
    fn rgbd_system(&mut self, level: usize, params: &IcpParams) -> Result<RgbdSystems> {
        let mut systems = self.run(|b| b.rgbd_system(level, params))?;
        if self.plant == Some(Plant::SystemRowSign) {
            systems[0][ICP_ATB_OFFSET + SIGN_FLIPPED_ROW] *= -1.0;
        }
        Ok(systems)
    }
    fn count_candidates(&mut self, params: &IcpParams) -> Result<u64> {
        self.run(|b| b.count_candidates(params))
    }
    fn encode_ferns(&mut self, params: &FernParams, ferns: &[Fern]) -> Result<Vec<u32>> {
        self.run(|b| b.encode_ferns(params, ferns))
    }
    fn detect_keypoints(&mut self, params: &KeypointParams) -> Result<(Vec<Keypoint>, u32)> {
        self.run(|b| b.detect_keypoints(params))
    }
    fn describe_keypoints(&mut self, what: ToDescribe) -> Result<Described> {
        self.run(|b| b.describe_keypoints(what))
    }
    fn fuse(&mut self, params: &FuseParams, next: Option<NextFrame<'_>>) -> Result<()> {
        self.run(|b| b.fuse(params, next))
    }
    fn compact(&mut self, params: &CompactParams) -> Result<usize> {
        self.run(|b| b.compact(params))
    }
    fn deform(&mut self, nodes: &[DeformNode]) -> Result<()> {
        self.run(|b| b.deform(nodes))
    }
    fn frame_level(&mut self, level: usize) -> Result<Prediction> {
        self.run(|b| b.frame_level(level))
    }
    fn set_prediction(&mut self, level: usize, prediction: &Prediction) -> Result<()> {
        self.run(|b| b.set_prediction(level, prediction))
    }
    fn surfel_count(&mut self) -> Result<usize> {
        self.inner.surfel_count()
    }
}

impl Inspect for PerturbedCpu {
    fn download_map(&mut self) -> Result<SurfelMap> {
        self.inner.download_map()
    }
    fn upload_map(&mut self, map: &SurfelMap) -> Result<()> {
        let Some(Plant::ShiftedUpload { shift_um, every }) = self.plant else {
            return self.run(|b| b.upload_map(map));
        };
        let mut map = map.clone();
        for p in map.position_weight.iter_mut().step_by(every) {
            p[0] += shift_um as f32 * 1e-6;
        }
        self.run(|b| b.upload_map(&map))
    }
    wgslam_core::inspect_through!(inner);
}
