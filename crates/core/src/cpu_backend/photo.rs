//! The CPU backend's photometric system (`photo_reduce` over the level-0 prediction and
//! a pyramid level's frame maps, with the frame's intensity pyramid made at the first call
//! of a frame), for [`crate::backend::Backend::rgbd_system`]; beside the step
//! implementations only to keep that file short.

use super::CpuBackend;
use crate::backend::PyramidLevel;
use crate::cpu;
use crate::layout::{IcpParams, IntensityParams, PreprocessParams, ICP_SYSTEM_LEN};
use crate::plan::{self, IntensityCall};

/// The frame's intensity pyramid (`intensity_pyramid`): per level its parameters and
/// intensity patches, each level made only when RGB-D tracking first asks for it or a
/// coarser one.
#[derive(Debug, Default)]
pub(super) struct IntensityPyramid {
    params: Vec<IntensityParams>,
    /// Per level, the intensity patches; the first `made` are of the last preprocessed
    /// frame.
    patches: Vec<Vec<[f32; 4]>>,
    made: usize,
}

impl IntensityPyramid {
    /// A new frame of `params`' size with `pyramid`'s coarser levels: the patches are stale.
    pub fn new_frame(&mut self, params: &PreprocessParams, pyramid: &[PyramidLevel]) {
        self.params =
            PyramidLevel::intensity_params(params.camera.width, params.camera.height, pyramid);
        self.patches.resize_with(self.params.len(), Vec::new);
        self.made = 0;
    }

    /// Makes the levels up to `level` not yet made from `color` (the frame's colour map),
    /// finest first (each from the one before).
    fn make(&mut self, color: &[[f32; 4]], level: usize) {
        for call in plan::intensity_levels(self.made, level) {
            let IntensityCall::IntensityPyramid { level: l } = call;
            let p = &self.params[l];
            let (finer, this) = self.patches.split_at_mut(l);
            let fine = match finer.last() {
                Some(f) => f.as_slice(),
                None => color,
            };
            let out = &mut this[0];
            out.resize((p.width * p.height) as usize, [0.0; 4]);
            cpu::intensity_pyramid::intensity_pyramid(p, fine, out);
        }
        self.made = self.made.max(level + 1);
    }
}

impl CpuBackend {
    /// `photo_reduce` at `params` over pyramid `level` (after `icp_system(level, ..)`
    /// checked that the level and a prediction exist): the summed 29-entry photometric
    /// system.
    pub(super) fn photo_system(
        &mut self,
        level: usize,
        params: &IcpParams,
    ) -> [f64; ICP_SYSTEM_LEN] {
        self.intensity.make(&self.frame.color, level);
        let (pred_vertex, _) = &self.prediction[0];
        let normal_depth = match level {
            0 => &self.frame.normal_depth,
            l => &self.frame.pyramid[l - 1].normal_depth,
        };
        cpu::photo_reduce::photo_reduce(
            params,
            pred_vertex,
            &self.pred_intensity,
            normal_depth,
            &self.intensity.patches[level],
        )
    }

    /// The frame's intensity patches at every level (made if not yet), for parity tests.
    pub fn intensity_patches(&mut self) -> &[Vec<[f32; 4]>] {
        let levels = self.intensity.params.len();
        self.intensity.make(&self.frame.color, levels - 1);
        &self.intensity.patches
    }
}
