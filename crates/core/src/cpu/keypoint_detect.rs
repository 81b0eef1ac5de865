//! CPU twin of `shaders/keypoint_detect.wgsl`: Harris corners of the level-0 colour, for
//! feature-based relocalisation (`slam::features`).
//!
//! A corner is a pixel with valid depth (its 3-D point is what relocalisation matches)
//! whose Harris response (Harris and Stephens 1988: `det(M) - k trace(M)^2` of the
//! structure tensor `M` summed over a 3x3 window of central differences) is above
//! `threshold` and above its 8 neighbours' (non-maximum suppression; a tie goes to the
//! neighbour earlier in raster order). Grey is `r + g + b` (0..765), a sum so that it is
//! exact; the response is f32 arithmetic in the same order as the shader, which lavapipe
//! may contract into fused multiply-adds, so a corner whose response ties a neighbour's
//! within an ULP may be found by one side only (the parity test allows a small fraction).
//!
//! The shader appends corners through an atomic counter in no particular order; the twin
//! appends them in raster order. The host sorts them (`slam::features`), so the order
//! does not reach the result.

use super::binding::twin;
use crate::layout::{Keypoint, KeypointParams};

/// Pixels this close to the border are skipped (the neighbours' windows need 3 more).
pub const BORDER: u32 = 3;
/// Harris's k.
pub const HARRIS_K: f32 = 0.04;

/// Grey level of texel `(u, v)`: `r + g + b`. Mirrors `grey` in keypoint_detect.wgsl.
pub fn grey(color_map: &[[f32; 4]], width: u32, u: u32, v: u32) -> f32 {
    let c = color_map[(v * width + u) as usize];
    c[0] + c[1] + c[2]
}

/// Harris response at `(u, v)`. Mirrors `harris` in keypoint_detect.wgsl.
pub fn harris(color_map: &[[f32; 4]], width: u32, u: u32, v: u32) -> f32 {
    let g = |x: u32, y: u32| grey(color_map, width, x, y);
    let (mut sxx, mut syy, mut sxy) = (0.0f32, 0.0f32, 0.0f32);
    for y in v - 1..=v + 1 {
        for x in u - 1..=u + 1 {
            let ix = g(x + 1, y) - g(x - 1, y);
            let iy = g(x, y + 1) - g(x, y - 1);
            sxx += ix * ix;
            syy += iy * iy;
            sxy += ix * iy;
        }
    }
    let trace = sxx + syy;
    sxx * syy - sxy * sxy - HARRIS_K * trace * trace
}

/// The response at `(u, v)` when it is a corner, else -1. Mirrors `corner_at`.
pub fn corner_at(
    p: &KeypointParams,
    color_map: &[[f32; 4]],
    normal_depth: &[[f32; 4]],
    u: u32,
    v: u32,
) -> f32 {
    if normal_depth[(v * p.width + u) as usize][3] <= 0.0 {
        return -1.0;
    }
    let r = harris(color_map, p.width, u, v);
    if r <= p.threshold {
        return -1.0;
    }
    for y in v - 1..=v + 1 {
        for x in u - 1..=u + 1 {
            if x == u && y == v {
                continue;
            }
            let n = harris(color_map, p.width, x, y);
            let earlier = y < v || (y == v && x < u);
            if n > r || (n == r && earlier) {
                return -1.0;
            }
        }
    }
    r
}

twin! {
    /// The colour map's corners with a valid depth, appended through `counter`: the
    /// parameters are the shader's bindings in `@binding` order, named as there (see the
    /// declarations in `shaders/keypoint_detect.wgsl`). `counter[0]` must be zero on entry.
    pub fn keypoint_detect(
        params: &KeypointParams,
        color_map: &[[f32; 4]],
        normal_depth: &[[f32; 4]],
        keypoints: &mut [Keypoint],
        counter: &mut [u32],
    ) {
        let p = *params;
        assert_eq!(color_map.len(), (p.width * p.height) as usize);
        assert_eq!(normal_depth.len(), color_map.len());
        assert!(keypoints.len() >= p.capacity as usize);
        // The shader's grid-stride loop as one thread with stride 1: raster order.
        let mut v = BORDER;
        while v + BORDER < p.height {
            let mut u = BORDER;
            while u + BORDER < p.width {
                let r = corner_at(&p, color_map, normal_depth, u, v);
                if r >= 0.0 {
                    let slot = counter[0];
                    counter[0] += 1;
                    if slot < p.capacity {
                        keypoints[slot as usize] = Keypoint {
                            u,
                            v,
                            score: r,
                            _pad: 0,
                        };
                    }
                }
                u += 1;
            }
            v += 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cpu::binding::Binding;
    use bytemuck::Zeroable;

    /// A bright square on a dark field with valid depth: its four corners are found, the
    /// flat inside and edges are not, and a corner without depth is skipped.
    #[test]
    fn finds_the_corners_of_a_square() {
        let (w, h) = (24u32, 24u32);
        let mut color_map = vec![[0.0f32, 0.0, 0.0, 255.0]; (w * h) as usize];
        for v in 8..16 {
            for u in 8..16 {
                color_map[(v * w + u) as usize] = [200.0, 200.0, 200.0, 255.0];
            }
        }
        let mut nd = vec![[0.0, 0.0, 1.0, 2.0f32]; (w * h) as usize];
        let p = KeypointParams {
            width: w,
            height: h,
            threshold: 1e9,
            capacity: 16,
            ..Zeroable::zeroed()
        };
        let run = |nd: &[[f32; 4]]| {
            let mut kps = vec![Keypoint::zeroed(); 16];
            let mut counter = [0u32];
            keypoint_detect(&mut [
                Binding::of(&p),
                Binding::read(&color_map),
                Binding::read(nd),
                Binding::write(&mut kps),
                Binding::write(&mut counter),
            ]);
            kps.truncate(counter[0] as usize);
            kps.iter().map(|k| (k.u, k.v)).collect::<Vec<_>>()
        };
        let found = run(&nd);
        assert_eq!(found.len(), 4, "{found:?}");
        for (u, v) in &found {
            assert!(
                [7, 8, 15, 16].contains(u) && [7, 8, 15, 16].contains(v),
                "{found:?}"
            );
        }
        let (u0, v0) = found[0];
        nd[(v0 * w + u0) as usize][3] = 0.0;
        assert!(!run(&nd).contains(&(u0, v0)));
    }
}
