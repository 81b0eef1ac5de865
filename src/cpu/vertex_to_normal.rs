//! CPU twin of `shaders/vertex_to_normal.wgsl`: normal map from the vertex map by central
//! differences, oriented towards the camera.
//!
//! `n = normalize((V(u+1,v) - V(u-1,v)) x (V(u,v+1) - V(u,v-1)))`, flipped so that
//! `n . V(u,v) < 0` (it faces the camera, whatever the sign of fy). Invalid on the image
//! border, where any of the five vertices is invalid, where a neighbour's depth differs by
//! more than `max_depth_jump_m` (an occlusion edge), or where the cross product vanishes.

use super::{is_valid, valid_entry, xyz, INVALID};
use crate::layout::NormalParams;

/// Bindings: 0 `params`, 1 `vertex_map` (camera frame), 2 `normal_map` (out, camera frame).
pub fn vertex_to_normal(
    params: &NormalParams,
    vertex_map: &[[f32; 4]],
    normal_map: &mut [[f32; 4]],
) {
    let (w, h) = (params.width as usize, params.height as usize);
    assert_eq!(vertex_map.len(), w * h, "vertex_map has the wrong size");
    assert_eq!(normal_map.len(), w * h, "normal_map has the wrong size");
    for pix in 0..w * h {
        let (u, v) = (pix % w, pix / w);
        normal_map[pix] = INVALID;
        if u == 0 || v == 0 || u + 1 >= w || v + 1 >= h {
            continue;
        }
        let c = vertex_map[pix];
        let (l, r) = (vertex_map[pix - 1], vertex_map[pix + 1]);
        let (t, b) = (vertex_map[pix - w], vertex_map[pix + w]);
        if !(is_valid(c) && is_valid(l) && is_valid(r) && is_valid(t) && is_valid(b)) {
            continue;
        }
        let jump = params.max_depth_jump_m;
        if (l[2] - c[2]).abs() > jump
            || (r[2] - c[2]).abs() > jump
            || (t[2] - c[2]).abs() > jump
            || (b[2] - c[2]).abs() > jump
        {
            continue;
        }
        let n = (xyz(r) - xyz(l)).cross(xyz(b) - xyz(t));
        let len = n.length();
        if len <= 1e-12 {
            continue;
        }
        let mut n = n / len;
        if n.dot(xyz(c)) > 0.0 {
            n = -n;
        }
        normal_map[pix] = valid_entry(n);
    }
}
