//! The kernels' parameter structs (`crates/core/src/layout/mod.rs`) for one frame, made from the tracker's
//! [`SlamParams`](crate::slam::params::SlamParams), intrinsics and pose: the one place
//! where the pipeline's settings become what the shaders read. The settings are
//! [`ValidParams`](crate::slam::params::ValidParams), checked once before the tracker was
//! made: nothing here guards against a value out of range again.

use crate::cpu::photo_reduce::{PHOTO_GRADIENT_MIN, PHOTO_HUBER};
use glam::DMat4;

use crate::geometry::camera::Intrinsics;
use crate::geometry::se3;
use crate::layout::{
    gpu_mat4, BilateralParams, Camera, CompactParams, FuseParams, IcpParams, NormalParams,
    PreprocessParams, ProjectParams, PyramidParams,
};
use crate::slam::backend::{Backend, PreprocessSteps, PyramidLevel};
use crate::slam::params::{FusionSettings, UnstableRemoval};
use crate::slam::pipeline::Slam;

/// `IcpParams::cos_normal_threshold` that turns the angle gate off (below -1).
const ANGLE_GATE_OFF: f32 = -2.0;

impl<B: Backend> Slam<B> {
    /// Parameters of every kernel of `preprocess`: [`Slam::preprocess_params`],
    /// [`Slam::bilateral_params`], [`Slam::normal_params`] and [`Slam::pyramid_levels`].
    pub fn preprocess_steps(&self) -> PreprocessSteps {
        PreprocessSteps {
            params: self.preprocess_params(),
            bilateral: self.bilateral_params(),
            normal: self.normal_params(),
            pyramid: self.pyramid_levels(),
        }
    }

    /// Parameters of `depth_to_vertex`.
    pub fn preprocess_params(&self) -> PreprocessParams {
        PreprocessParams {
            camera: Camera::new(&self.intrinsics),
            raw_width: self.raw_intrinsics.width,
            raw_height: self.raw_intrinsics.height,
            stride: self.params.input.downsample,
            depth_scale: self.params.input.depth_scale,
            min_depth_m: self.params.input.min_depth_m,
            max_depth_m: self.params.input.max_depth_m,
            _pad0: 0,
            _pad1: 0,
        }
    }

    /// Parameters of `bilateral_filter`, or `None` when
    /// [`SlamParams::bilateral`](crate::slam::params::SlamParams::bilateral) is off.
    pub fn bilateral_params(&self) -> Option<BilateralParams> {
        let b = self.params.bilateral?;
        Some(BilateralParams {
            camera: Camera::new(&self.intrinsics),
            radius_px: b.radius_px,
            sigma_space_px: b.sigma_space_px,
            sigma_depth_m: b.sigma_depth_m,
            sigma_depth_per_m2: b.sigma_depth_per_m2,
            filter_points: b.filter_points as u32,
            _pad0: 0,
            _pad1: 0,
            _pad2: 0,
        })
    }

    /// Parameters of `vertex_to_normal`.
    pub fn normal_params(&self) -> NormalParams {
        NormalParams {
            width: self.intrinsics.width,
            height: self.intrinsics.height,
            max_depth_jump_m: self.params.normals.max_depth_jump_m,
            _pad: 0,
        }
    }

    /// Pyramid levels of [`IcpSettings::level_iters`](crate::slam::params::IcpSettings::level_iters) (one per entry).
    pub fn levels(&self) -> usize {
        self.params.icp.level_iters.len()
    }

    /// Intrinsics of pyramid level `level`: level 0 is [`Slam::intrinsics`], each coarser
    /// level halves the one before (coarse pixel `(u, v)` samples finer pixel `(2u, 2v)`).
    pub fn level_intrinsics(&self, level: usize) -> Intrinsics {
        (0..level).fold(self.intrinsics, |k, _| k.downsampled(2))
    }

    /// Parameters that make the coarser pyramid levels `1..levels()` (empty with one level).
    pub fn pyramid_levels(&self) -> Vec<PyramidLevel> {
        let s = self.params.icp.pyramid;
        (1..self.levels())
            .map(|level| {
                let (fine, coarse) = (
                    self.level_intrinsics(level - 1),
                    self.level_intrinsics(level),
                );
                PyramidLevel {
                    down: PyramidParams::halving(
                        &fine,
                        s.radius_px,
                        s.max_depth_diff_m,
                        s.max_depth_diff_per_m2,
                    ),
                    normal: NormalParams {
                        width: coarse.width,
                        height: coarse.height,
                        ..self.normal_params()
                    },
                }
            })
            .collect()
    }

    /// Parameters of `project_model`/`predict_model` at a world-to-camera pose.
    pub fn project_params(&self, t_world_to_cam: &DMat4) -> ProjectParams {
        ProjectParams {
            t_world_to_cam: gpu_mat4(t_world_to_cam),
            camera: Camera::new(&self.intrinsics),
            surfel_count: 0, // Filled in by the backend (`Backend::predict`, `fuse`, `compact`).
            _pad0: 0,
            _pad1: 0,
            _pad2: 0,
        }
    }

    /// ICP's angle gate at pyramid `level`, degrees: `icp.full_res_normal_deg` where the
    /// level's pixels are the sensor's own (no downsampling, level 0) and that is set,
    /// else `icp.normal_deg`.
    fn icp_normal_deg(&self, level: usize) -> f32 {
        let icp = &self.params.icp;
        let full_res = level == 0 && self.params.input.downsample == 1;
        match full_res && icp.full_res_normal_deg > 0.0 {
            true => icp.full_res_normal_deg,
            false => icp.normal_deg,
        }
    }

    /// The angle gate at level 0 of the second attempt from the last pose, degrees:
    /// `icp.full_res_retry_normal_deg` where level 0's pixels are the sensor's own and it
    /// is wider than the first attempt's gate there; else `None`, no second attempt
    /// (`Slam::process`).
    pub fn wide_gate_deg(&self) -> Option<f32> {
        let retry = self.params.icp.full_res_retry_normal_deg;
        let full_res = self.params.input.downsample == 1;
        (full_res && retry > self.icp_normal_deg(0)).then_some(retry)
    }

    /// Parameters of `icp_reduce` at the current estimate on pyramid level `level`.
    pub fn icp_params(&self, level: usize, t_world_to_cam: &DMat4) -> IcpParams {
        let k = self.level_intrinsics(level);
        IcpParams {
            t_world_to_cam: gpu_mat4(t_world_to_cam),
            camera: Camera::new(&k),
            dist_m: self.params.icp.dist_m,
            cos_normal_threshold: cos_of_gate(self.icp_normal_deg(level)),
            huber_m: self.params.icp.huber_m,
            noise_weighting: self.params.icp.noise_weight as u32,
            photo_depth_gate_m: self.params.icp.dist_m,
            photo_huber: PHOTO_HUBER,
            photo_gradient_min: PHOTO_GRADIENT_MIN,
            photo_source_step: 1 << level,
            photo_source_width: self.intrinsics.width,
            _pad0: 0,
            _pad1: 0,
            _pad2: 0,
        }
    }

    /// Parameters of `fuse_merge`/`fuse_add` (count and capacity filled by the backend).
    pub fn fuse_params(&self, t_world_to_cam: &DMat4, frame_id: u32) -> FuseParams {
        FuseParams {
            t_world_to_cam: gpu_mat4(t_world_to_cam),
            t_cam_to_world: gpu_mat4(&se3::inverse_rigid(t_world_to_cam)),
            camera: Camera::new(&self.intrinsics),
            surfel_count: 0, // Filled in by the backend (`Backend::predict`, `fuse`, `compact`).
            frame_id,
            dist_m: self.params.fusion.dist_m,
            cos_normal_threshold: self.params.fusion.normal_deg.to_radians().cos(),
            capacity: 0,
            association: self.params.fusion.association.code(),
            confidence_sigma: self.params.fusion.confidence_sigma,
            prune_scale: self.prune_scale(frame_id),
            dist_confident_m: confident_gate_m(&self.params.fusion),
            _pad0: 0,
            _pad1: 0,
            _pad2: 0,
        }
    }

    /// `fuse_prune`'s radius scale for `frame_id`: [`FusionSettings::prune_scale`](crate::slam::params::FusionSettings::prune_scale) on the
    /// frames the unstable-surfel removal runs after ([`Slam::removal_after`]), 0 (off) on
    /// the others; every frame when there is no removal.
    fn prune_scale(&self, frame_id: u32) -> f32 {
        if self.params.fusion.unstable_removal.is_none() || self.removal_after(frame_id).is_some() {
            self.params.fusion.prune_scale
        } else {
            0.0
        }
    }

    /// The unstable-surfel removal's settings when it runs after fusing `frame_id`
    /// ([`UnstableRemoval::every_frames`]), else `None`.
    fn removal_after(&self, frame_id: u32) -> Option<UnstableRemoval> {
        self.params
            .fusion
            .unstable_removal
            .filter(|r| frame_id % r.every_frames == 0)
    }

    /// Parameters of the compaction kernels after fusing `frame_id` (count filled by the
    /// backend), or `None` when [`FusionSettings::unstable_removal`](crate::slam::params::FusionSettings::unstable_removal) is off or does not run
    /// after this frame ([`UnstableRemoval::every_frames`]).
    pub fn compact_params(&self, frame_id: u32) -> Option<CompactParams> {
        let r = self.removal_after(frame_id)?;
        Some(CompactParams {
            surfel_count: 0, // Filled in by the backend (`Backend::predict`, `fuse`, `compact`).
            frame_id,
            stable_weight: r.stable_weight,
            max_age_frames: r.max_age_frames,
        })
    }
}

/// The confident surfels' depth gate as `FuseParams` carries it: `dist_confident_m`, or
/// `dist_m` where it is 0 (one gate for every surfel) or larger (a gate narrows with weight,
/// it never widens: `--fuse-dist 0.03` alone narrows every surfel's gate).
fn confident_gate_m(f: &FusionSettings) -> f32 {
    match f.dist_confident_m {
        d if d > 0.0 => d.min(f.dist_m),
        _ => f.dist_m,
    }
}

/// `icp_reduce`'s `cos_normal_threshold` for an angle gate of `deg` degrees; 180 or more
/// turns the gate off.
pub fn cos_of_gate(deg: f32) -> f32 {
    match deg {
        deg if deg >= 180.0 => ANGLE_GATE_OFF,
        deg => deg.to_radians().cos(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cpu::fuse_depth_gate;
    use crate::slam::params::{Profile, SlamParams};

    /// A surfel seen once keeps the wide gate, one fused many times nears the narrow one;
    /// with one gate (the assignment, or a narrow gate at or above `dist_m`) every surfel
    /// has exactly `dist_m`.
    #[test]
    fn a_surfels_depth_gate_narrows_with_its_weight() {
        let robust = SlamParams::profile(Profile::Robust).fusion;
        assert_eq!(
            confident_gate_m(&robust),
            robust.dist_m,
            "off in the profile"
        );
        let narrowing = FusionSettings {
            dist_confident_m: 0.04,
            ..robust
        };
        let mut p: FuseParams = bytemuck::Zeroable::zeroed();
        p.dist_m = narrowing.dist_m;
        p.dist_confident_m = confident_gate_m(&narrowing);
        assert_eq!(p.dist_confident_m, 0.04);
        assert_eq!(
            fuse_depth_gate(&p, 0.3),
            0.05,
            "below weight 1: the wide gate"
        );
        assert_eq!(fuse_depth_gate(&p, 1.0), 0.05);
        assert!((fuse_depth_gate(&p, 2.0) - 0.045).abs() < 1e-7);
        assert!((fuse_depth_gate(&p, 1e4) - 0.04).abs() < 1e-6);
        let assignment = SlamParams::profile(Profile::Assignment).fusion;
        let too_wide = FusionSettings {
            dist_confident_m: 0.07,
            ..robust
        };
        for f in [assignment, robust, too_wide] {
            p.dist_m = f.dist_m;
            p.dist_confident_m = confident_gate_m(&f);
            for w in [0.0, 1.0, 3.0, 1e6] {
                assert_eq!(fuse_depth_gate(&p, w), f.dist_m, "weight {w}");
            }
        }
    }
}
