//! CPU twin of `shaders/pyramid_model.wgsl`: the next coarser level of the predicted
//! (model) vertex and normal maps, the ICP source, by subsampling: coarse pixel `(u, v)` is
//! finer pixel `(2u, 2v)`, as in the frame's pyramid (`pyramid_depth`).
//!
//! Why subsampling and not an average like the frame side: the model's points are surfels
//! already averaged over many observations (the robust profile's median weight is 55), so
//! an average would remove little noise, and it would blend surfels across depth edges and
//! normals across creases. The source's pixel grid does not enter the association (ICP
//! moves each source point into the frame and projects it with the coarse intrinsics), so
//! any subset of the model's points is a valid coarse source.

use super::binding::twin;
use super::invocations::Storage;
use super::pixel_grid;
use crate::layout::PyramidParams;

twin! {
    /// A coarser level's predicted maps from its finer level's: the parameters are the
    /// shader's bindings in `@binding` order, named as there (see the declarations in
    /// `shaders/pyramid_model.wgsl` for shapes, units and frames).
    ///
    /// Of `params`, the shader uses only `width` and `height` (the coarse size); here
    /// `fine_width` is also the row length of the finer slices.
    pub fn pyramid_model(
        params: &PyramidParams,
        fine_pred_vertex: &[[f32; 4]],
        fine_pred_normal: &[[f32; 4]],
        pred_vertex: &mut [[f32; 4]],
        pred_normal: &mut [[f32; 4]],
    ) {
        let (w, h) = (params.camera.width as usize, params.camera.height as usize);
        let fine_w = params.fine_width as usize;
        assert!(
            fine_pred_vertex.len() == fine_pred_normal.len() && fine_pred_vertex.len() % fine_w == 0
        );
        assert!(pred_vertex.len() == w * h && pred_normal.len() == w * h);
        assert!(2 * w - 1 <= fine_w && 2 * h - 1 <= fine_pred_vertex.len() / fine_w);
        // The shader's entry, pixel_grid.wgsl: every pixel once, in parallel.
        let (pred_vertex, pred_normal) = (Storage::new(pred_vertex), Storage::new(pred_normal));
        pixel_grid(params.camera.width, params.camera.height, |[u, v]| {
            let (u, v) = (u as usize, v as usize);
            let fine = 2 * v * fine_w + 2 * u;
            pred_vertex.store(v * w + u, fine_pred_vertex[fine]);
            pred_normal.store(v * w + u, fine_pred_normal[fine]);
        });
    }
}
