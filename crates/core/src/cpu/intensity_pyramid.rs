//! CPU twin of `shaders/intensity_pyramid.wgsl`: one level of the frame's intensity
//! pyramid for the photometric term (`photo_reduce`), made once per frame of RGB-D
//! tracking, and not at all with geometric tracking.
//!
//! Each pixel `(u, v)` of a level holds its intensity patch: the intensities (0..1, the
//! unit of `intensity_of`) of the four texels `(u, v)`, `(u + 1, v)`, `(u, v + 1)`,
//! `(u + 1, v + 1)` (coordinates clamped to the level, so the last row and column repeat
//! themselves). `photo_reduce` reads the one patch at the texel left of and above a
//! sub-pixel position and evaluates the bilinear interpolant and its exact gradient from
//! it: one texel read per pixel and iteration instead of four colour reads and four luma
//! conversions, with the same values.
//!
//! Level 0's intensity is the luma of the frame's colour map (`intensity_of`). A coarser
//! level's pixel `(u, v)` is the `[1 2 1] x [1 2 1] / 16` binomial mean of the finer
//! level's intensities around finer pixel `(2u, 2v)` (clamped at the border): centred on
//! the pixel it samples, as the depth pyramid's `pyramid_depth` (so the halved intrinsics
//! hold for it too), and smoothed so that the coarse image does not alias.

use super::binding::twin;
use super::invocations::Storage;
use super::{intensity_of, pixel_grid};
use crate::layout::IntensityParams;

/// The binomial weights of the `[1 2 1] x [1 2 1] / 16` mean, offset -1, 0, 1.
const BINOMIAL: [f32; 3] = [0.25, 0.5, 0.25];

/// The intensity of the map read at texel `(x, y)`, clamped to it: the luma of the colour
/// map at level 0, else the finer level's patch intensity. Mirrors `fine_intensity` in
/// intensity_pyramid.wgsl.
#[inline]
fn fine_intensity(params: &IntensityParams, fine: &[[f32; 4]], x: i32, y: i32) -> f32 {
    let xc = x.clamp(0, params.fine_width as i32 - 1) as usize;
    let yc = y.clamp(0, params.fine_height as i32 - 1) as usize;
    let t = fine[yc * params.fine_width as usize + xc];
    match params.level {
        0 => intensity_of(t),
        _ => t[0],
    }
}

/// This level's intensity at pixel `(u, v)`, clamped to the level (the rules of the module
/// header). Mirrors `level_intensity` in intensity_pyramid.wgsl.
#[inline]
pub fn level_intensity(params: &IntensityParams, fine: &[[f32; 4]], u: i32, v: i32) -> f32 {
    let uc = u.clamp(0, params.width as i32 - 1);
    let vc = v.clamp(0, params.height as i32 - 1);
    if params.level == 0 {
        return fine_intensity(params, fine, uc, vc);
    }
    let mut sum = 0.0f32;
    for (j, wy) in BINOMIAL.iter().enumerate() {
        for (i, wx) in BINOMIAL.iter().enumerate() {
            let x = 2 * uc + i as i32 - 1;
            let y = 2 * vc + j as i32 - 1;
            sum += wx * wy * fine_intensity(params, fine, x, y);
        }
    }
    sum
}

twin! {
    /// A level's intensity patches from its finer level's (`fine_map`): the parameters are
    /// the shader's bindings in `@binding` order, named as there (see the declarations in
    /// `shaders/intensity_pyramid.wgsl` for shapes and units).
    pub fn intensity_pyramid(
        params: &IntensityParams,
        fine_map: &[[f32; 4]],
        intensity_patch: &mut [[f32; 4]],
    ) {
        let w = params.width as usize;
        let sizes = [
            (params.fine_width, params.fine_height),
            (params.width, params.height),
        ];
        for ((sw, sh), (name, len)) in sizes.into_iter().zip([
            ("fine_map", fine_map.len()),
            ("intensity_patch", intensity_patch.len()),
        ]) {
            assert_eq!(len, (sw * sh) as usize, "{name} is not {sw}x{sh}");
        }
        // The shader's entry, pixel_grid.wgsl: every pixel once, in parallel.
        let intensity_patch = Storage::new(intensity_patch);
        pixel_grid(params.width, params.height, |[u, v]| {
            let (u, v) = (u as i32, v as i32);
            let at = |du, dv| level_intensity(params, fine_map, u + du, v + dv);
            intensity_patch.store(
                v as usize * w + u as usize,
                [at(0, 0), at(1, 0), at(0, 1), at(1, 1)],
            );
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cpu::binding::Binding;

    /// Level 0: each patch holds the luma of its four texels, the last column and row
    /// repeating themselves; level 1 of a linear ramp is the ramp sampled at the even
    /// pixels (the binomial mean is exact on a linear image, away from the clamped border).
    #[test]
    fn patches_of_a_ramp() {
        let (w, h) = (8u32, 6u32);
        let ramp = |u: u32, v: u32| 0.2 + 0.05 * u as f32 + 0.02 * v as f32;
        let color: Vec<[f32; 4]> = (0..w * h)
            .map(|i| {
                let g = 255.0 * ramp(i % w, i / w);
                [g, g, g, 255.0]
            })
            .collect();
        let p = IntensityParams::levels(w, h, &[[4, 3]]);
        let mut l0 = vec![[0.0f32; 4]; (w * h) as usize];
        intensity_pyramid(&mut [
            Binding::of(&p[0]),
            Binding::read(&color),
            Binding::write(&mut l0),
        ]);
        let close = |a: f32, b: f32| (a - b).abs() < 1e-6;
        for v in 0..h {
            for u in 0..w {
                let got = l0[(v * w + u) as usize];
                let (u1, v1) = ((u + 1).min(w - 1), (v + 1).min(h - 1));
                let want = [ramp(u, v), ramp(u1, v), ramp(u, v1), ramp(u1, v1)];
                for k in 0..4 {
                    assert!(close(got[k], want[k]), "({u}, {v}) {got:?} vs {want:?}");
                }
            }
        }
        let mut l1 = vec![[0.0f32; 4]; 12];
        intensity_pyramid(&mut [
            Binding::of(&p[1]),
            Binding::read(&l0),
            Binding::write(&mut l1),
        ]);
        // Coarse (1, 1) and (2, 1) sample finer (2, 2) and (4, 2), inside the border.
        for u in 1..3u32 {
            let got = l1[(4 + u) as usize];
            let want = [
                ramp(2 * u, 2),
                ramp(2 * u + 2, 2),
                ramp(2 * u, 4),
                ramp(2 * u + 2, 4),
            ];
            for k in 0..4 {
                assert!(close(got[k], want[k]), "({u}, 1) {got:?} vs {want:?}");
            }
        }
    }

    /// A coarse pixel is the binomial mean around the finer pixel it samples: a single
    /// bright finer texel at (2, 2) puts 1/4 of itself in coarse (1, 1), whose window it
    /// centres, and nothing in the other coarse pixels (their windows miss it).
    #[test]
    fn an_impulse_spreads_binomially() {
        let mut fine = vec![[0.0f32; 4]; 36];
        fine[2 * 6 + 2] = [1.0, 0.0, 0.0, 0.0];
        let p = IntensityParams::levels(6, 6, &[[3, 3]])[1];
        let mut out = vec![[0.0f32; 4]; 9];
        intensity_pyramid(&mut [
            Binding::of(&p),
            Binding::read(&fine),
            Binding::write(&mut out),
        ]);
        assert_eq!(out[4][0], 0.25);
        assert_eq!(out[0][0], 0.0);
        // Coarse (1, 1)'s patch: itself, then (2, 1), (1, 2), (2, 2), which sample finer
        // (4, 2), (2, 4), (4, 4): two pixels from the impulse, outside the 3x3 window.
        assert_eq!(out[4], [0.25, 0.0, 0.0, 0.0]);
        // Coarse (0, 0)'s patch: (1, 1) at its last corner.
        assert_eq!(out[0], [0.0, 0.0, 0.0, 0.25]);
    }
}
