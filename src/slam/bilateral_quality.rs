//! The bilateral filter's twin (`cpu::bilateral_filter`) with the pipeline's filter
//! settings (the profiles' defaults, and KinectFusion's 7x7 window): it smooths a noisy
//! plane and keeps a depth step sharp. Here rather than beside the twin because the
//! settings are the pipeline's (`slam::params`), a floor above the twins' crate.

use crate::cpu::bilateral_filter::bilateral_filter;
use crate::cpu::binding::Binding;
use crate::cpu::{back_project, is_valid, valid_entry, INVALID};
use crate::geometry::camera::Intrinsics;
use crate::layout::BilateralParams;
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
    let cam = crate::cpu::camera_intrinsics(&p.camera);
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
    let mut out = vec![[9.0f32; 4]; map.len()];
    bilateral_filter(&mut [Binding::of(p), Binding::read(map), Binding::write(&mut out)]);
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
            let expected =
                back_project(crate::cpu::camera_intrinsics(&p.camera), [u, v], out[i][2]);
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
        let mut out = vec![[0.0f32; 4]; map.len()];
        bilateral_filter(&mut [
            Binding::of(&p),
            Binding::read(&map),
            Binding::write(&mut out),
        ]);
        keeps_the_step_columns(&p, &map, &truth, &out);
    }
}

fn keeps_the_step_columns(p: &BilateralParams, map: &[[f32; 4]], truth: &[f32], out: &[[f32; 4]]) {
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
