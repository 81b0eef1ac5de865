//! [`FusedView`]: the view the last best-candidate fusion built the next prediction's index
//! map at, so `predict` can skip `project_model` there. Both backends keep one.

use crate::layout::{FuseParams, GpuMat4, ProjectParams, ASSOCIATION_BEST_CANDIDATE};

/// The view a best-candidate `fuse` projected the map from. Its `fuse_select` builds
/// `project_model`'s index map at that view on the way (every surfel whose centre lands in
/// the image, nearest first) and its `fuse_add` adds the new surfels, so a backend keeps
/// the view until the map changes otherwise (`compact`, `upload_map`, the next `fuse`) and
/// its `predict` skips `project_model` when asked for the same view, as it is on every
/// tracked frame: the next frame is predicted at the pose the last one was fused at. The
/// one difference from projecting afresh: a surfel merged this frame keys the pixel its
/// centre projected to before the merge moved it (by a fraction of its radius), with its
/// depth from then; `predict_model` reads its merged position and normal either way.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FusedView {
    t_world_to_cam: GpuMat4,
    /// fx, fy, cx, cy (pixels).
    intrinsics: [f32; 4],
    width: u32,
    height: u32,
}

impl FusedView {
    /// The view of a fusion, if its association builds the index map (best candidate).
    pub fn of_fuse(p: &FuseParams) -> Option<Self> {
        (p.association == ASSOCIATION_BEST_CANDIDATE).then_some(Self {
            t_world_to_cam: p.t_world_to_cam,
            intrinsics: [p.fx, p.fy, p.cx, p.cy],
            width: p.width,
            height: p.height,
        })
    }

    /// Whether `predict(p)` asks for this view (bit for bit).
    pub fn is_view_of(&self, p: &ProjectParams) -> bool {
        let FusedView {
            t_world_to_cam,
            intrinsics,
            width,
            height,
        } = *self;
        (t_world_to_cam, intrinsics, width, height)
            == (
                p.t_world_to_cam,
                [p.fx, p.fy, p.cx, p.cy],
                p.width,
                p.height,
            )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::camera::Intrinsics;
    use crate::geometry::se3;
    use crate::slam::cpu_backend::CpuBackend;
    use crate::slam::params::{Profile, SlamParams};
    use crate::slam::pipeline::Slam;

    /// `predict` reuses a fusion's index map only for the very view it was built at, and
    /// only after best-candidate association (the only one whose `fuse_select` builds it).
    #[test]
    fn fused_view_matches_only_its_own_view() {
        let robust = Slam::new(
            CpuBackend::new(),
            Intrinsics::ICL_NUIM,
            SlamParams::profile(Profile::Robust),
        );
        let t = se3::exp(&[0.01, -0.02, 0.03, 0.1, 0.2, -0.3]);
        let view = FusedView::of_fuse(&robust.fuse_params(&t, 5)).expect("best candidate");
        assert!(view.is_view_of(&robust.project_params(&t)));
        let moved = se3::exp(&[0.01, -0.02, 0.03, 0.1, 0.2, -0.3001]);
        assert!(!view.is_view_of(&robust.project_params(&moved)));
        let mut other_size = robust.project_params(&t);
        other_size.width /= 2;
        assert!(!view.is_view_of(&other_size));
        let assignment = Slam::new(
            CpuBackend::new(),
            Intrinsics::ICL_NUIM,
            SlamParams::profile(Profile::Assignment),
        );
        assert_eq!(FusedView::of_fuse(&assignment.fuse_params(&t, 5)), None);
    }
}
