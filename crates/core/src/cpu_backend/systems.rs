//! The CPU backend's ICP systems: the `icp_system` and `rgbd_system` plans run through the
//! engine (`icp_reduce`, `photo_reduce` over the level-0 prediction and a pyramid level's
//! frame maps into their system's f64 partials, `icp_reduce_final` summing them), with the
//! frame's intensity pyramid made as the photometric term first reads it, for [`crate::backend::Backend::icp_system`] and
//! [`crate::backend::Backend::rgbd_system`]; beside the step implementations only to keep
//! that file short.

use super::CpuBackend;
use crate::backend::PyramidLevel;
use crate::backend::RgbdSystems;
use crate::cpu::binding::Pool;
use crate::layout::{IcpParams, IntensityParams, PreprocessParams, ICP_SYSTEM_LEN};
use crate::plan::{self, Call, SystemCall};
use crate::Result;

/// The frame's intensity pyramid (`intensity_pyramid`): per level its parameters and
/// intensity patches, each level made only when RGB-D tracking first asks for it or a
/// coarser one.
#[derive(Debug, Default)]
pub(super) struct IntensityPyramid {
    pub(super) params: Vec<IntensityParams>,
    /// Per level, the intensity patches; the first `made` are of the last preprocessed
    /// frame.
    pub(super) patches: Vec<Vec<[f32; 4]>>,
    made: usize,
}

impl IntensityPyramid {
    /// A new frame of `params`' size with `pyramid`'s coarser levels: the patches are stale.
    pub fn new_frame(&mut self, params: &PreprocessParams, pyramid: &[PyramidLevel]) {
        self.params =
            PyramidLevel::intensity_params(params.camera.width, params.camera.height, pyramid);
        self.patches.resize_with(self.params.len(), Vec::new);
        for (patches, p) in self.patches.iter_mut().zip(&self.params) {
            patches.resize((p.width * p.height) as usize, [0.0; 4]);
        }
        self.made = 0;
    }
}

impl CpuBackend {
    /// Makes the frame's intensity levels up to `level` not yet made, finest first (each
    /// from the one before, level 0 from the colour map).
    fn make_intensity(&mut self, level: usize) {
        for call in plan::intensity_levels(self.intensity.made, level) {
            self.dispatch(call, Pool::new());
        }
        self.intensity.made = self.intensity.made.max(level + 1);
    }

    /// [`crate::Error::Argument`] unless pyramid level `level` was preprocessed and
    /// predicted (`what`: the step, for the message).
    pub(super) fn check_system_level(&self, level: usize, what: &str) -> Result<()> {
        let levels = 1 + self.frame.pyramid.len();
        if level >= levels.min(self.prediction.len()) {
            return Err(crate::Error::Argument(format!(
                "{what} at pyramid level {level}, but preprocess() made {levels} level(s) and \
                 predict() {}",
                self.prediction.len()
            )));
        }
        Ok(())
    }

    /// Runs an `icp_system` or `rgbd_system` plan at `params` (after
    /// [`CpuBackend::check_system_level`]), every call through the engine: per
    /// [`System`](crate::registry::System) its `partials`, one partial system of f64 sums
    /// (the CPU's reductions run as one workgroup: `cpu::icp_reduce`), and their sum
    /// `system`; the summed 29-entry systems, geometric and photometric (zero where the
    /// plan reduces none).
    pub(super) fn run_systems(&mut self, plan: Vec<SystemCall>, params: &IcpParams) -> RgbdSystems {
        let mut partials = [[0.0; ICP_SYSTEM_LEN]; 2];
        let mut systems = [[0.0; ICP_SYSTEM_LEN]; 2];
        for call in plan {
            if let SystemCall::PhotoReduce { level } = call {
                self.make_intensity(level);
            }
            let system = call.at().system as usize;
            let mut step = Pool::new();
            step.uniform("icp", params);
            step.write("partials", &mut partials[system]);
            step.write("system", &mut systems[system]);
            self.dispatch(call, step);
        }
        systems
    }

    /// The frame's intensity patches at every level (made if not yet), for parity tests.
    pub fn intensity_patches(&mut self) -> &[Vec<[f32; 4]>] {
        let levels = self.intensity.params.len();
        self.make_intensity(levels - 1);
        &self.intensity.patches
    }
}
