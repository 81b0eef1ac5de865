//! CPU twin of `shaders/vertex_to_normal.wgsl`: the `normal_depth` map from the vertex map,
//! normals by central differences, oriented towards the camera, each with the depth of
//! the point map's pixel.
//!
//! `n = normalize((V(u+1,v) - V(u-1,v)) x (V(u,v+1) - V(u,v-1)))`, flipped so that
//! `n . V(u,v) < 0` (it faces the camera, whatever the sign of fy). Invalid on the image
//! border, where any of the five vertices is invalid, where a neighbour's depth differs by
//! more than `max_depth_jump_m` (an occlusion edge), or where the cross product vanishes.
//!
//! The output texel is `(n, z)`: the unit normal (camera frame) with the depth `z`
//! (metres, > 0) of the point map's pixel in w, or all zero where the normal or the point
//! is invalid. A valid texel implies a valid point, so later twins (`icp_reduce`,
//! `fuse_merge`, `fuse_add`) read this one texel and rebuild the point with
//! [`super::back_project`], the function `depth_to_vertex` made it with, bit for bit.
//!
//! The point map is the vertex map itself, except at level 0 with the bilateral filter
//! when `bilateral.filter_points` is off (the robust profile): there the normals come from
//! the filtered map and the points keep the raw depth (the unfiltered map), as
//! KinectFusion and ElasticFusion fuse the raw depth. The filter's average is biased at
//! slants and edges, where its window is one-sided, and noise that stays in the points
//! averages out in ICP's sums and in the surfels' weighted means. Measured (release, CPU,
//! ATE after alignment; filtered points -> raw points): ICL-NUIM kt2 frames 1..200 noisy
//! 6.58 -> 5.54 mm at 320x240 and 7.60 -> 6.10 mm at 640x480, noise-free 0.216 -> 0.110 mm
//! and 0.095 -> 0.083 mm; 7-Scenes kitchen 0..299 20.80 -> 20.78 mm; SUN3D office frag2
//! 7.99 -> 8.04 mm (docs/robust-profile.md).

use super::binding::twin;
use super::invocations::Storage;
use super::{is_valid, pixel_grid, xyz, INVALID};
use crate::layout::NormalParams;

/// The normal of pixel `(u, v)` with the point's depth in w, or [`INVALID`] (the rules of
/// the module header). Mirrors `normal_at` in vertex_to_normal.wgsl.
pub fn normal_at(
    params: &NormalParams,
    vertex_map: &[[f32; 4]],
    point_map: &[[f32; 4]],
    u: u32,
    v: u32,
) -> [f32; 4] {
    if u == 0 || v == 0 || u + 1 >= params.width || v + 1 >= params.height {
        return INVALID;
    }
    let w = params.width as usize;
    let load = |u: u32, v: u32| vertex_map[v as usize * w + u as usize];
    let c = load(u, v);
    let l = load(u - 1, v);
    let r = load(u + 1, v);
    let t = load(u, v - 1);
    let b = load(u, v + 1);
    if !(is_valid(c) && is_valid(l) && is_valid(r) && is_valid(t) && is_valid(b)) {
        return INVALID;
    }
    let jump = params.max_depth_jump_m;
    if (l[2] - c[2]).abs() > jump
        || (r[2] - c[2]).abs() > jump
        || (t[2] - c[2]).abs() > jump
        || (b[2] - c[2]).abs() > jump
    {
        return INVALID;
    }
    let n = (xyz(r) - xyz(l)).cross(xyz(b) - xyz(t));
    let len = super::arith::length(n);
    if len <= 1e-12 {
        return INVALID;
    }
    let mut nn = super::arith::div3(n, len);
    if nn.dot(xyz(c)) > 0.0 {
        nn = -nn;
    }
    let point = point_map[v as usize * w + u as usize];
    if !is_valid(point) {
        return INVALID;
    }
    [nn.x, nn.y, nn.z, point[2]]
}

twin! {
    /// A level's normals, with the depth of its points in w (`normal_depth`): the
    /// parameters are the shader's bindings in `@binding` order, named as there (see the
    /// declarations in `shaders/vertex_to_normal.wgsl` for shapes, units and frames).
    pub fn vertex_to_normal(
        params: &NormalParams,
        vertex_map: &[[f32; 4]],
        normal_depth: &mut [[f32; 4]],
        point_map: &[[f32; 4]],
    ) {
        let (w, h) = (params.width as usize, params.height as usize);
        assert_eq!(vertex_map.len(), w * h, "vertex_map has the wrong size");
        assert_eq!(normal_depth.len(), w * h, "normal_depth has the wrong size");
        assert_eq!(point_map.len(), w * h, "point_map has the wrong size");
        let normal_depth = Storage::new(normal_depth);
        // The shader's entry, pixel_grid.wgsl: every pixel once.
        pixel_grid(params.width, params.height, |[u, v]| {
            normal_depth.store(
                v as usize * w + u as usize,
                normal_at(params, vertex_map, point_map, u, v),
            );
        });
    }
}
