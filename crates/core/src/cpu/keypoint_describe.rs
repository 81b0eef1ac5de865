//! CPU twin of `shaders/keypoint_describe.wgsl`: a binary descriptor and the camera-frame
//! point of each keypoint, for feature-based relocalisation (`slam::features`).
//!
//! The descriptor is BRIEF's (Calonder et al. 2010): 256 intensity comparisons between
//! pairs of offsets around the keypoint, drawn once from a fixed seed
//! (`slam::features::pattern`). BRIEF smooths the image first; here each sample is the sum
//! of a 3x3 box of grey levels (`r + g + b`), which smooths as well and, being a sum of whole
//! numbers, is exact on both sides, so the bits match the shader's exactly. Samples past
//! the border are clamped to it.

use super::binding::twin;
use crate::layout::{Keypoint, KeypointParams, DESCRIPTOR_WORDS};

/// Sum of `r + g + b` over the 3x3 box around `(u, v) + d`, clamped to the image. Mirrors
/// `box_grey` in keypoint_describe.wgsl.
pub fn box_grey(p: &KeypointParams, color_map: &[[f32; 4]], u: u32, v: u32, d: [i32; 2]) -> f32 {
    let last = [p.width as i32 - 1, p.height as i32 - 1];
    let c = [u as i32 + d[0], v as i32 + d[1]];
    let mut sum = 0.0f32;
    for dy in -1..=1 {
        for dx in -1..=1 {
            let x = (c[0] + dx).clamp(0, last[0]);
            let y = (c[1] + dy).clamp(0, last[1]);
            let rgb = color_map[(y * p.width as i32 + x) as usize];
            sum += rgb[0] + rgb[1] + rgb[2];
        }
    }
    sum
}

twin! {
    /// The descriptor and the camera-frame point of each of the first `params.count`
    /// keypoints: the parameters are the shader's bindings in `@binding` order, named as there
    /// (see the declarations in `shaders/keypoint_describe.wgsl` for shapes, units and frames).
    pub fn keypoint_describe(
        params: &KeypointParams,
        color_map: &[[f32; 4]],
        vertex_map: &[[f32; 4]],
        keypoints: &[Keypoint],
        pattern: &[[i32; 4]],
        descriptors: &mut [u32],
        points: &mut [[f32; 4]],
    ) {
        let p = *params;
        let n = p.count as usize;
        assert!(keypoints.len() >= n && pattern.len() >= p.tests as usize);
        assert!(descriptors.len() >= n * DESCRIPTOR_WORDS && points.len() >= n);
        assert_eq!(vertex_map.len(), color_map.len());
        // The shader's grid-stride loop as one thread with stride 1.
        for k in 0..n {
            let kp = keypoints[k];
            for w in 0..DESCRIPTOR_WORDS as u32 {
                let mut bits = 0u32;
                for b in 0..32u32 {
                    let t = w * 32 + b;
                    if t < p.tests {
                        let o = pattern[t as usize];
                        let a = box_grey(&p, color_map, kp.u, kp.v, [o[0], o[1]]);
                        let c = box_grey(&p, color_map, kp.u, kp.v, [o[2], o[3]]);
                        if a < c {
                            bits |= 1 << b;
                        }
                    }
                }
                descriptors[k * DESCRIPTOR_WORDS + w as usize] = bits;
            }
            points[k] = vertex_map[(kp.v * p.width + kp.u) as usize];
        }
    }
}
