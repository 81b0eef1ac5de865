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
            intrinsics: crate::cpu::camera_intrinsics(&p.camera),
            width: p.camera.width,
            height: p.camera.height,
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
                crate::cpu::camera_intrinsics(&p.camera),
                p.camera.width,
                p.camera.height,
            )
    }
}
