//! CPU twin of `shaders/depth_to_vertex.wgsl`: raw 16-bit depth and RGB8 to a camera-frame
//! vertex map (metres) and a colour map, downsampled by keeping every `stride`-th pixel.
//!
//! Output pixel `(u, v)` reads raw pixel `(stride u, stride v)`; `params.camera` holds the
//! downsampled intrinsics, so back-projecting `(u, v)` with them equals back-projecting the
//! raw pixel with the raw intrinsics. Invalid depth (0 or outside the depth range) gives the
//! invalid entry `[0; 4]`.

use super::binding::twin;
use super::invocations::Storage;
use super::{back_project, pixel_grid, valid_entry, INVALID};
use crate::layout::PreprocessParams;

twin! {
    /// Raw depth and colour to the frame's vertex and colour maps: the parameters are the
    /// shader's bindings in `@binding` order, named as there (see the declarations in
    /// `shaders/depth_to_vertex.wgsl` for shapes, units and frames).
    ///
    /// `raw_depth` holds the r16uint texture's texels as `u16`, and `raw_rgba` the rgba8uint
    /// texture's texels packed as `r | g << 8 | b << 16 | a << 24`.
    pub fn depth_to_vertex(
        params: &PreprocessParams,
        raw_depth: &[u16],
        raw_rgba: &[u32],
        vertex_map: &mut [[f32; 4]],
        color_map: &mut [[f32; 4]],
    ) {
        let (w, h) = (params.camera.width as usize, params.camera.height as usize);
        assert_eq!(vertex_map.len(), w * h, "vertex_map has the wrong size");
        assert_eq!(color_map.len(), w * h, "color_map has the wrong size");
        assert_eq!(
            raw_depth.len(),
            (params.raw_width * params.raw_height) as usize
        );
        let (vertex_map, color_map) = (Storage::new(vertex_map), Storage::new(color_map));
        // The shader's entry, pixel_grid.wgsl: every pixel once.
        pixel_grid(params.camera.width, params.camera.height, |[u, v]| {
            convert_at(params, raw_depth, raw_rgba, &vertex_map, &color_map, u, v);
        });
    }
}

/// Converts output pixel `(u, v)`. Mirrors `convert_at` in depth_to_vertex.wgsl.
fn convert_at(
    params: &PreprocessParams,
    raw_depth: &[u16],
    raw_rgba: &[u32],
    vertex_map: &Storage<[f32; 4]>,
    color_map: &Storage<[f32; 4]>,
    u: u32,
    v: u32,
) {
    let texel = (v * params.camera.width + u) as usize;
    let raw = (v * params.stride * params.raw_width + u * params.stride) as usize;
    let z = super::arith::div(raw_depth[raw] as f32, params.depth_scale);
    let c = raw_rgba[raw];
    color_map.store(
        texel,
        [
            (c & 255) as f32,
            ((c >> 8) & 255) as f32,
            ((c >> 16) & 255) as f32,
            255.0,
        ],
    );
    let mut vertex = INVALID;
    if z > 0.0 && z >= params.min_depth_m && z <= params.max_depth_m {
        let cam = super::camera_intrinsics(&params.camera);
        vertex = valid_entry(back_project(cam, [u, v], z));
    }
    vertex_map.store(texel, vertex);
}
