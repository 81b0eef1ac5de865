//! CPU twin of `shaders/bilateral_filter.wgsl`: KinectFusion's edge-preserving bilateral
//! filter on the depth of the camera-frame vertex map (Newcombe et al. 2011, section 3.2:
//! noise is smoothed for the normals and ICP while depth discontinuities stay sharp).
//!
//! For each valid pixel `(u, v)` with depth `z`, the filtered depth is the weighted mean of
//! the valid depths `z_n` in the `(2 radius_px + 1)²` window around it (clipped at the image
//! border), with weight
//! `exp(-d_px² / (2 sigma_space_px²)) * exp(-(z_n - z)² / (2 sigma_depth_m²))`, evaluated as
//! one `exp` of the summed exponents (`d_px` is the pixel distance of the neighbour). The
//! pixel itself has weight 1, so the sum of weights is at least 1 and the mean stays inside
//! the window's depth range. The output is the vertex re-built from the filtered depth with
//! [`super::back_project`] (the function `depth_to_vertex` made the input with); invalid
//! pixels (w = 0) stay invalid and never contribute.
//!
//! What it is not: it does not fill holes, and it does not replace the raw depth: the
//! caller keeps `depth_to_vertex`'s unfiltered map, and by default (the robust profile's
//! `bilateral.filter_points` off) level 0's points, which ICP and fusion rebuild from
//! `normal_depth`, keep the raw depth while the normals and the coarser pyramid levels
//! come from this filter's output (see `cpu::vertex_to_normal` for why and the
//! measurements). The table below was measured with the filtered points (before
//! 2026-11-26, when fusion and ICP took the filtered depth).
//!
//! The range sigma grows with depth, `sigma_depth_m + sigma_depth_per_m2 * z²` at the
//! pixel's own depth `z`, because a structured-light sensor's depth noise does (disparity
//! noise: `sigma_z ~ z²`; on the noisy ICL-NUIM set the disparity step is `z² / 351 m`, 11 mm
//! at 2 m and 46 mm at 4 m). Measured on `icl_living_room_kt2_noisy` frames 1..200 at
//! 320x240, CPU backend, ATE after alignment (off: 204 mm; the clean set: 0.326 mm off):
//!
//! | window | range sigma | noisy ATE | clean ATE |
//! |---|---|---|---|
//! | 7x7, sigma 2.25 px (KinectFusion at 320x240) | 30 mm | 184 mm | 1.71 mm |
//! | 7x7, sigma 2.25 px | 50 mm | 132 mm | |
//! | 7x7, sigma 2.25 px | 10 mm | | 0.372 mm |
//! | 7x7, sigma 2.25 px | 0.005 z² | 38.7 mm | |
//! | 7x7, sigma 2.25 px | 0.01 z² | 14.2 mm | 1.95 mm |
//! | 7x7, sigma 2.25 px | 0.015 z², 0.02 z² | 14.1 mm, 14.1 mm | |
//! | 5x5, sigma 1.5 px | 0.01 z² | | 0.969 mm |
//! | 5x5, sigma 1 px | 0.01 z² | 53.1 mm | 0.543 mm |
//! | 3x3, sigma 1 px | 30 mm | 178 mm | 0.261 mm |
//! | 3x3, sigma 1 px (the default) | 0.01 z² | 75.5 mm | 0.279 mm |
//! | 3x3, sigma 1 px | 0.02 z² | 70.8 mm | |
//!
//! A depth-proportional-to-z² sigma beats every constant one on the noisy set at any window
//! (a constant sigma small enough to keep near edges sharp cannot average across the far
//! disparity steps), and 0.01/m is where the gain levels off. The window is a compromise:
//! larger windows track the noisy set better but bias the clean one (windows clipped at the
//! image border and at depth edges are one-sided, so slanted and curved surfaces move with
//! the view), and the clean set must stay within 0.5 mm; 3x3 is the largest that does. The
//! defaults (in `slam::params::BilateralSettings`) are therefore 3x3, sigma 1 px,
//! `sigma_depth = 0.01 z²`. The filter alone does not make noisy tracking good (fusion keeps
//! the noise in the map).

use super::{back_project, is_valid, pixel_grid, valid_entry, INVALID};
use crate::layout::BilateralParams;

/// The filtered vertex of pixel `(u, v)`, or [`INVALID`] where its vertex is invalid (the
/// rules of the module header). Mirrors `filtered_at` in bilateral_filter.wgsl.
pub fn filtered_at(params: &BilateralParams, vertex_map: &[[f32; 4]], u: u32, v: u32) -> [f32; 4] {
    let w = params.camera.width as usize;
    let load = |u: u32, v: u32| vertex_map[v as usize * w + u as usize];
    let c = load(u, v);
    if !is_valid(c) {
        return INVALID;
    }
    let r = params.radius_px;
    // The shader's `select(u - r, 0u, u < r)`.
    let u_lo = u.saturating_sub(r);
    let v_lo = v.saturating_sub(r);
    let u_hi = (u + r).min(params.camera.width - 1);
    let v_hi = (v + r).min(params.camera.height - 1);
    let k_space = 1.0 / (2.0 * params.sigma_space_px * params.sigma_space_px);
    let sigma_depth = params.sigma_depth_m + params.sigma_depth_per_m2 * c[2] * c[2];
    let k_depth = 1.0 / (2.0 * sigma_depth * sigma_depth);
    let mut sum_w = 0.0f32;
    let mut sum_wz = 0.0f32;
    for nv in v_lo..=v_hi {
        for nu in u_lo..=u_hi {
            let n = load(nu, nv);
            if is_valid(n) {
                let du = nu as f32 - u as f32;
                let dv = nv as f32 - v as f32;
                let dz = n[2] - c[2];
                let w = (-((du * du + dv * dv) * k_space) - dz * dz * k_depth).exp();
                sum_w += w;
                sum_wz += w * n[2];
            }
        }
    }
    let cam = [
        params.camera.fx,
        params.camera.fy,
        params.camera.cx,
        params.camera.cy,
    ];
    valid_entry(back_project(cam, [u, v], sum_wz / sum_w))
}

/// Arguments: the shader's bindings in `@binding` order, named as there; see the
/// declarations in `shaders/bilateral_filter.wgsl` for shapes, units and frames.
pub fn bilateral_filter(
    params: &BilateralParams,
    vertex_map: &[[f32; 4]],
    filtered_vertex: &mut [[f32; 4]],
) {
    let (w, h) = (params.camera.width as usize, params.camera.height as usize);
    assert_eq!(vertex_map.len(), w * h, "vertex_map has the wrong size");
    assert_eq!(
        filtered_vertex.len(),
        w * h,
        "filtered_vertex has the wrong size"
    );
    // The shader's entry, pixel_grid.wgsl: every pixel once, row by row.
    pixel_grid(params.camera.width, params.camera.height, |[u, v]| {
        filtered_vertex[v as usize * w + u as usize] = filtered_at(params, vertex_map, u, v);
    });
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cpu::back_project;
    use crate::geometry::camera::Intrinsics;
    use crate::layout::Camera;
    use crate::slam::params::BilateralSettings;
    use bytemuck::Zeroable;

    const W: u32 = 64;
    const H: u32 = 48;
    /// Noise of the synthetic depth, metres (a Kinect at ~2 m).
    const NOISE_M: f32 = 0.01;

    /// The filters under test: the defaults, and KinectFusion's 7x7 window with a constant
    /// 30 mm range sigma.
    fn settings() -> [BilateralSettings; 2] {
        [
            BilateralSettings::default(),
            BilateralSettings {
                radius_px: 3,
                sigma_space_px: 2.25,
                sigma_depth_m: 0.03,
                sigma_depth_per_m2: 0.0,
                filter_points: false,
            },
        ]
    }

    fn params(s: &BilateralSettings) -> BilateralParams {
        BilateralParams {
            camera: Camera::new(&Intrinsics {
                width: W,
                height: H,
                fx: 60.0,
                fy: -60.0,
                cx: 31.5,
                cy: 23.5,
            }),
            radius_px: s.radius_px,
            sigma_space_px: s.sigma_space_px,
            sigma_depth_m: s.sigma_depth_m,
            sigma_depth_per_m2: s.sigma_depth_per_m2,
            filter_points: s.filter_points as u32,
            ..Zeroable::zeroed()
        }
    }

    /// Standard normal samples from a fixed-seed splitmix64 (Box-Muller).
    struct Normal(u64);
    impl Normal {
        fn uniform(&mut self) -> f32 {
            self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
            let mut z = self.0;
            z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
            ((z ^ (z >> 31)) >> 40) as f32 / (1u64 << 24) as f32
        }
        fn sample(&mut self) -> f32 {
            let u1 = self.uniform().max(1e-7);
            let u2 = self.uniform();
            (-2.0 * u1.ln()).sqrt() * (std::f32::consts::TAU * u2).cos()
        }
    }

    /// A vertex map of the true depth `depth(u, v)` plus noise, and the true depths.
    fn noisy_map(depth: impl Fn(u32, u32) -> f32) -> (Vec<[f32; 4]>, Vec<f32>) {
        let p = params(&BilateralSettings::default());
        let cam = [p.camera.fx, p.camera.fy, p.camera.cx, p.camera.cy];
        let mut rng = Normal(42);
        let mut map = Vec::new();
        let mut truth = Vec::new();
        for v in 0..H {
            for u in 0..W {
                let z = depth(u, v);
                truth.push(z);
                map.push(valid_entry(back_project(
                    cam,
                    [u, v],
                    z + NOISE_M * rng.sample(),
                )));
            }
        }
        (map, truth)
    }

    fn rms_error(map: &[[f32; 4]], truth: &[f32], pixels: &[usize]) -> f32 {
        let sum: f32 = pixels.iter().map(|&i| (map[i][2] - truth[i]).powi(2)).sum();
        (sum / pixels.len() as f32).sqrt()
    }

    /// On a slanted plane, the filter cuts the depth noise by more than half (ideally to
    /// 0.35 for the default 3x3 window with sigma 1 px, to a fifth for the 7x7 one), keeps
    /// every vertex on its pixel's ray, and leaves invalid pixels invalid.
    #[test]
    fn smooths_a_noisy_plane() {
        let (mut map, truth) = noisy_map(|u, v| 2.0 + 0.004 * u as f32 + 0.002 * v as f32);
        for i in [100, 777, 2000] {
            map[i] = INVALID;
        }
        for s in settings() {
            smooths_a_noisy_plane_with(&params(&s), &map, &truth);
        }
    }

    fn smooths_a_noisy_plane_with(p: &BilateralParams, map: &[[f32; 4]], truth: &[f32]) {
        let mut out = vec![[9.0; 4]; map.len()];
        bilateral_filter(p, map, &mut out);
        let interior: Vec<usize> = (0..map.len())
            .filter(|&i| {
                let (u, v) = (i as u32 % W, i as u32 / W);
                (3..W - 3).contains(&u) && (3..H - 3).contains(&v) && is_valid(map[i])
            })
            .collect();
        let (before, after) = (
            rms_error(map, truth, &interior),
            rms_error(&out, truth, &interior),
        );
        assert!(
            after < 0.5 * before,
            "{p:?}: noise {:.2} mm -> {:.2} mm",
            before * 1e3,
            after * 1e3
        );
        for i in 0..map.len() {
            assert_eq!(is_valid(out[i]), is_valid(map[i]), "pixel {i} validity");
            if is_valid(out[i]) {
                let (u, v) = (i as u32 % W, i as u32 / W);
                let expected = back_project(
                    [p.camera.fx, p.camera.fy, p.camera.cx, p.camera.cy],
                    [u, v],
                    out[i][2],
                );
                assert_eq!(out[i], valid_entry(expected), "pixel {i} is off its ray");
            } else {
                assert_eq!(out[i], INVALID, "pixel {i}");
            }
        }
    }

    /// A 0.3 m depth step (an occlusion edge) stays sharp: the columns on both sides of it
    /// keep their own depth within the noise, where a plain Gaussian blur of the same window
    /// would pull them 0.07 m (3x3) to 0.1 m (7x7) towards each other; the noise beside the
    /// edge still shrinks.
    #[test]
    fn keeps_a_depth_step_sharp() {
        let step = |u: u32, _v: u32| if u < W / 2 { 2.0 } else { 2.3 };
        let (map, truth) = noisy_map(step);
        for s in settings() {
            let p = params(&s);
            let mut out = vec![[0.0; 4]; map.len()];
            bilateral_filter(&p, &map, &mut out);
            keeps_the_step_columns(&p, &map, &truth, &out);
        }
    }

    fn keeps_the_step_columns(
        p: &BilateralParams,
        map: &[[f32; 4]],
        truth: &[f32],
        out: &[[f32; 4]],
    ) {
        for u in [W / 2 - 1, W / 2] {
            let column: Vec<usize> = (3..H - 3).map(|v| (v * W + u) as usize).collect();
            let mean_error: f32 =
                column.iter().map(|&i| out[i][2] - truth[i]).sum::<f32>() / column.len() as f32;
            let worst = column
                .iter()
                .map(|&i| (out[i][2] - truth[i]).abs())
                .fold(0.0, f32::max);
            let (before, after) = (
                rms_error(map, truth, &column),
                rms_error(out, truth, &column),
            );
            assert!(
                mean_error.abs() < 0.2 * NOISE_M,
                "{p:?} column {u}: mean shift {:.2} mm across the step",
                mean_error * 1e3
            );
            assert!(
                worst < 4.0 * NOISE_M,
                "{p:?} column {u}: a pixel moved {:.2} mm",
                worst * 1e3
            );
            assert!(
                after < 0.7 * before,
                "{p:?} column {u}: noise {:.2} mm -> {:.2} mm",
                before * 1e3,
                after * 1e3
            );
        }
    }
}
