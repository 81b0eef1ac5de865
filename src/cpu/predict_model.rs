//! CPU twin of `shaders/predict_model.wgsl`: turns the index map into the predicted
//! (model) vertex and normal maps, in the WORLD frame, used as the ICP source.

use super::{surfel_texel, INVALID};
use crate::layout::ProjectParams;

/// Bindings (as in the shader header; map arrays in the packing of `map::SurfelMap`):
/// - 0 `params`: `ProjectParams` (only width and height are used)
/// - 1 `index_map`: the u64 keys of `project_model` (the GPU reads each as `vec2<u32>`, low
///   word = surfel index first); 0 means no surfel
/// - 2 `position_weight`: surfel xyz (world frame) + weight
/// - 3 `normal_frame`: bits of the surfel normal (world frame) + last frame
/// - 4 `pred_vertex` (out): width x height, world frame, w = 1 / 0
/// - 5 `pred_normal` (out): width x height, world frame, w = 1 / 0
pub fn predict_model(
    params: &ProjectParams,
    index_map: &[u64],
    position_weight: &[[f32; 4]],
    normal_frame: &[[u32; 4]],
    pred_vertex: &mut [[f32; 4]],
    pred_normal: &mut [[f32; 4]],
) {
    let n = (params.width * params.height) as usize;
    assert!(index_map.len() == n && pred_vertex.len() == n && pred_normal.len() == n);
    for pix in 0..n {
        let key = index_map[pix];
        let mut vertex = INVALID;
        let mut normal = INVALID;
        if key != 0 {
            let surfel = surfel_texel((key & 0xffff_ffff) as u32);
            let p = position_weight[surfel];
            let nf = normal_frame[surfel];
            let n = nf.map(f32::from_bits);
            vertex = [p[0], p[1], p[2], 1.0];
            normal = [n[0], n[1], n[2], 1.0];
        }
        pred_vertex[pix] = vertex;
        pred_normal[pix] = normal;
    }
}
