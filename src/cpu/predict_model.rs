//! CPU twin of `shaders/predict_model.wgsl`: turns the index map into the predicted
//! (model) vertex and normal maps, in the WORLD frame, used as the ICP source.

use super::INVALID;
use crate::layout::ProjectParams;

/// Bindings: 0 `params` (only width/height used), 1 `index_map`, 2 `positions`,
/// 3 `normals`, 4 `pred_vertex` (out, world frame), 5 `pred_normal` (out, world frame).
pub fn predict_model(
    params: &ProjectParams,
    index_map: &[u64],
    positions: &[[f32; 4]],
    normals: &[[f32; 4]],
    pred_vertex: &mut [[f32; 4]],
    pred_normal: &mut [[f32; 4]],
) {
    let n = (params.width * params.height) as usize;
    assert!(index_map.len() == n && pred_vertex.len() == n && pred_normal.len() == n);
    for pix in 0..n {
        let key = index_map[pix];
        if key == 0 {
            pred_vertex[pix] = INVALID;
            pred_normal[pix] = INVALID;
            continue;
        }
        let i = (key & 0xffff_ffff) as usize;
        let p = positions[i];
        let nn = normals[i];
        pred_vertex[pix] = [p[0], p[1], p[2], 1.0];
        pred_normal[pix] = [nn[0], nn[1], nn[2], 1.0];
    }
}
