//! CPU twin of `shaders/fuse_prune.wgsl`: duplicate removal of best-candidate fusion
//! (robust profile), after `fuse_merge_chosen`. A surfel this frame did not refresh
//! retires (weight 0, last frame 0, which the unstable-surfel removal drops at its first
//! run after frame `max_age_frames`) when the pixel it projects to merged its measurement
//! into a surfel (`fuse_merge_chosen`'s `merged` entry) that lies within
//! `prune_scale` times the larger of their radii, faces the same way
//! ([`PRUNE_COS_NORMAL`]) and is at least as confident: a layered copy of the surface the
//! merged surfel now stands for (Keller et al. 2013 merge such surfels). Without it, noisy
//! depth leaves copies that different pixels keep refreshing, and the camera sees a denser
//! map on every revisit (see `ROBUST_PRUNE_RADIUS_SCALE`). Called once per map chunk; the
//! merged surfel may be in any chunk, as its copy is per pixel.

use super::binding::twin;
use super::invocations::Storage;
use super::{normal_of, project_to_texel, transform_point, visible_surfels, xyz};
use crate::layout::{FuseParams, MapChunk};

/// Cosine of the largest angle between the normals of a pruned surfel and the chosen one:
/// 45 degrees (Keller et al. 2013's merge of similar surfels). Mirrors `PRUNE_COS_NORMAL`
/// in the shader.
pub const PRUNE_COS_NORMAL: f32 = std::f32::consts::FRAC_1_SQRT_2;

twin! {
    /// Retires the chunk's visible surfels that duplicate the surfel their pixel merged into:
    /// the parameters are the shader's bindings in `@binding` order, named as there (see the
    /// declarations in `shaders/fuse_prune.wgsl` for shapes, units and frames).
    pub fn fuse_prune(
        params: &FuseParams,
        chunk: &MapChunk,
        block_boxes: &[[u32; 4]],
        position_weight: &mut [[f32; 4]],
        normal_frame: &mut [[u32; 4]],
        color: &[[f32; 4]],
        merged: &[[f32; 4]],
    ) {
        let cam = super::camera_intrinsics(&params.camera);
        // Each invocation writes its own surfel only.
        let (position_weight, normal_frame) = (Storage::new(position_weight), Storage::new(normal_frame));
        visible_surfels(params, chunk, block_boxes, |_, slot| {
            prune_surfel(
                params,
                &position_weight,
                &normal_frame,
                color,
                merged,
                slot as usize,
                cam,
            );
        });
    }
}

/// Retires the surfel at `slot` in the chunk's arrays if it duplicates the surfel its
/// pixel merged into.
fn prune_surfel(
    params: &FuseParams,
    position_weight: &Storage<[f32; 4]>,
    normal_frame: &Storage<[u32; 4]>,
    color: &[[f32; 4]],
    merged: &[[f32; 4]],
    slot: usize,
    cam: [f32; 4],
) {
    let nf = normal_frame.load(slot);
    if nf[3] == params.frame_id {
        return;
    }
    let pw = position_weight.load(slot);
    let Some(centre) = project_to_texel(
        cam,
        params.camera.width,
        params.camera.height,
        transform_point(&params.t_world_to_cam, xyz(pw)),
    ) else {
        return;
    };
    let pix = (centre[1] * params.camera.width + centre[0]) as usize;
    let pw_t = merged[2 * pix];
    if pw_t[3] <= 0.0 {
        return;
    }
    let nr_t = merged[2 * pix + 1];
    let reach = params.prune_scale * color[slot][3].max(nr_t[3]);
    if xyz(pw).distance(xyz(pw_t)) < reach
        && normal_of(nf).dot(xyz(nr_t)) > PRUNE_COS_NORMAL
        && pw[3] <= pw_t[3]
    {
        position_weight.store(slot, [pw[0], pw[1], pw[2], 0.0]);
        normal_frame.store(slot, [nf[0], nf[1], nf[2], 0]);
    }
}
