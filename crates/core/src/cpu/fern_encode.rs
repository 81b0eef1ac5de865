//! CPU twin of `shaders/fern_encode.wgsl`: the frame's randomised-fern code, one 4-bit
//! code per fern, that the relocalisation keyframe database (`slam::keyframes`) stores and
//! looks up.
//!
//! A fern (ElasticFusion's `Ferns`, after Glocker et al., "Real-time RGB-D camera
//! relocalization via randomized ferns for keyframe encoding", 2015) is a cell of a coarse
//! grid over the image and four thresholds. ElasticFusion reads one pixel of an image
//! resized to 80 x 60; here each fern averages its cell of the [`FERN_GRID`] over the
//! level-0 maps directly (the same small image, without a resize pass), over the pixels with
//! valid depth only, so holes do not darken the colour. A cell without valid depth gets
//! [`FERN_NO_DEPTH`], which never matches. The means are compared as sums
//! (`sum > threshold * count`): colour sums of whole numbers are exact and the depth sum
//! adds in the same order on both sides, so the codes match the shader's bit for bit.
//!
//! [`FERN_GRID`]: crate::layout::FERN_GRID
//! [`FERN_NO_DEPTH`]: crate::layout::FERN_NO_DEPTH

use super::binding::twin;
use super::invocations::{par_for_each_group, Storage};
use crate::layout::{Fern, FernParams, FERN_NO_DEPTH};

/// The code of `fern`. Mirrors `fern_code` in fern_encode.wgsl.
pub fn fern_code(
    p: &FernParams,
    fern: &Fern,
    normal_depth: &[[f32; 4]],
    color_map: &[[f32; 4]],
) -> u32 {
    let u0 = fern.cell_u * p.cell_width;
    let v0 = fern.cell_v * p.cell_height;
    let mut rgb = [0.0f32; 3];
    let mut depth = 0.0f32;
    let mut count = 0u32;
    for v in v0..(v0 + p.cell_height).min(p.height) {
        for u in u0..(u0 + p.cell_width).min(p.width) {
            let texel = (v * p.width + u) as usize;
            let nd = normal_depth[texel];
            if nd[3] <= 0.0 {
                continue;
            }
            let c = color_map[texel];
            rgb[0] += c[0];
            rgb[1] += c[1];
            rgb[2] += c[2];
            depth += nd[3];
            count += 1;
        }
    }
    if count == 0 {
        return FERN_NO_DEPTH;
    }
    let n = count as f32;
    let t = fern.threshold;
    (if rgb[0] > t[0] * n { 8 } else { 0 })
        | (if rgb[1] > t[1] * n { 4 } else { 0 })
        | (if rgb[2] > t[2] * n { 2 } else { 0 })
        | (if depth > t[3] * n { 1 } else { 0 })
}

twin! {
    /// The code of each of the first `params.fern_count` ferns into `codes`: the
    /// parameters are the shader's bindings in `@binding` order, named as there (see the
    /// declarations in `shaders/fern_encode.wgsl` for shapes, units and frames).
    pub fn fern_encode(
        params: &FernParams,
        ferns: &[Fern],
        normal_depth: &[[f32; 4]],
        color_map: &[[f32; 4]],
        codes: &mut [u32],
    ) {
        let pixels = (params.width * params.height) as usize;
        assert!(normal_depth.len() == pixels && color_map.len() == pixels);
        let n = params.fern_count as usize;
        assert!(ferns.len() >= n && codes.len() >= n);
        // The shader's grid-stride loop over the ferns, on every thread, each fern writing
        // its own code, weighed by the pixels of its cell (500 cells of 1600 pixels at
        // 640x480 took 0.6 ms a frame on one thread).
        let codes = Storage::new(&mut codes[..n]);
        let cell = (params.cell_width * params.cell_height) as usize;
        par_for_each_group(n, cell, |i| {
            codes.store(i, fern_code(params, &ferns[i], normal_depth, color_map));
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cpu::binding::Binding;
    use bytemuck::Zeroable;

    /// A 4 x 2 image, cells of 2 x 2: the left cell's valid pixels decide its code, the
    /// invalid one is left out of the means; a cell without depth is FERN_NO_DEPTH.
    #[test]
    fn codes_compare_means_of_valid_pixels() {
        let p = FernParams {
            width: 4,
            height: 2,
            cell_width: 2,
            cell_height: 2,
            fern_count: 2,
            ..Zeroable::zeroed()
        };
        let nd = |z: f32| [0.0, 0.0, 1.0, z];
        let normal_depth = [
            nd(1.0),
            nd(3.0),
            nd(0.0),
            nd(0.0),
            nd(2.0),
            nd(0.0),
            nd(0.0),
            nd(0.0),
        ];
        let c = |r: f32| [r, 100.0, 0.0, 255.0];
        // Mean red of the valid pixels 20, of all four 35 (the invalid one is 100).
        let color_map = [
            c(10.0),
            c(20.0),
            c(0.0),
            c(0.0),
            c(30.0),
            c(100.0),
            c(0.0),
            c(0.0),
        ];
        let fern = |cell_u, t: [f32; 4]| Fern {
            cell_u,
            threshold: t,
            ..Zeroable::zeroed()
        };
        let ferns = [fern(0, [25.0, 50.0, 0.0, 1.9]), fern(1, [0.0; 4])];
        let mut codes = [0; 2];
        fern_encode(&mut [
            Binding::of(&p),
            Binding::read(&ferns),
            Binding::read(&normal_depth),
            Binding::read(&color_map),
            Binding::write(&mut codes),
        ]);
        // red 20 < 25, green 100 > 50, blue 0 = 0 (not above), depth 2 > 1.9.
        assert_eq!(codes, [0b0101, FERN_NO_DEPTH]);
    }
}
