//! CPU twin of `shaders/predict_model.wgsl`: turns the index map into the predicted
//! (model) vertex and normal maps, in the WORLD frame, used as the ICP source, and the
//! predicted intensity (0..1) of the photometric term (`photo_reduce`). Called once
//! per map chunk: each call writes the pixels whose surfel the chunk holds, and the first
//! chunk's call also the pixels with no surfel.

use super::binding::twin;
use super::invocations::{par_for_each_invocation, Storage};
use super::photo_reduce::INTENSITY_NONE;
use super::{intensity_of, INVALID};
use crate::layout::{MapChunk, ProjectParams};

twin! {
    /// The predicted maps of the pixels whose surfel the chunk holds: the parameters are
    /// the shader's bindings in `@binding` order, named as there (see the declarations in
    /// `shaders/predict_model.wgsl` for shapes, units and frames).
    pub fn predict_model(
        params: &ProjectParams,
        index_map: &[u64],
        chunk: &MapChunk,
        position_weight: &[[f32; 4]],
        normal_frame: &[[u32; 4]],
        color: &[[f32; 4]],
        pred_vertex: &mut [[f32; 4]],
        pred_normal: &mut [[f32; 4]],
        pred_intensity: &mut [f32],
    ) {
        let n = (params.camera.width * params.camera.height) as usize;
        assert!(index_map.len() == n && pred_vertex.len() == n && pred_normal.len() == n);
        assert_eq!(pred_intensity.len(), n);
        let (pred_vertex, pred_normal) = (Storage::new(pred_vertex), Storage::new(pred_normal));
        let pred_intensity = Storage::new(pred_intensity);
        // One invocation per pixel, on every thread (each writes its own pixel).
        par_for_each_invocation(n, |pix| {
            let key = index_map[pix];
            let mut vertex = INVALID;
            let mut normal = INVALID;
            let mut intensity = INTENSITY_NONE;
            if key != 0 {
                let slot = ((key & 0xffff_ffff) as u32).wrapping_sub(chunk.base);
                if slot >= chunk.slots {
                    return;
                }
                let p = position_weight[slot as usize];
                let nf = normal_frame[slot as usize];
                let n = nf.map(f32::from_bits);
                vertex = [p[0], p[1], p[2], 1.0];
                normal = [n[0], n[1], n[2], 1.0];
                intensity = intensity_of(color[slot as usize]);
            } else if chunk.base != 0 {
                return;
            }
            pred_vertex.store(pix, vertex);
            pred_normal.store(pix, normal);
            pred_intensity.store(pix, intensity);
        });
    }
}
