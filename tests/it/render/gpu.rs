//! The GPU renderer: its parameter struct against both kernels, and GPU-vs-CPU parity.

use crate::common;

use common::harness::{gpu, plain, skipped, Test};
use common::wgsl::{self, rust_layout};
use libtest_mimic::Completion;
use wgslam::geometry::camera::Intrinsics;
use wgslam::gpu::GpuContext;
use wgslam::render::{self, MapCloud, RenderCamera, RenderSettings, View};

use super::{bundled_map, gt_poses};

/// `RenderParams` is declared in both render kernels (not in common.wgsl): both match Rust.
fn render_params_layout_matches_both_shaders() {
    use wgslam::gpu::shaders;
    use wgslam::layout::render::RenderParams;
    use wgslam::layout::Camera;
    let rust = rust_layout!(RenderParams {
        t_world_to_cam,
        camera: Camera,
        surfel_count,
        view,
        splat_radius_m,
        min_radius_px,
        max_radius_px,
        cull_backfaces,
        near_m,
        far_m,
        weight_max,
        background,
        fill_gap_px,
        _pad0,
    });
    let mut failures = Vec::new();
    for kernel in ["render_splat", "render_splat_portable", "render_resolve"] {
        let module = wgsl::parse(kernel, &shaders::source(kernel));
        failures.extend(wgsl::layout_mismatches(kernel, &module, &rust));
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// Pixels whose winning surfel may differ between GPU and CPU: a pixel centre exactly on a
/// splat's rim can fall in or out depending on fused multiply-add in `du*du + dv*dv` and in
/// the projection (lavapipe fuses, Rust does not). Measured on lavapipe: 0 of 76,800
/// pixels in each of the 8 renders below.
const MAX_INDEX_MISMATCH_FRACTION: f64 = 0.002;

/// Depth in the keys: the transform's multiply-adds may be fused on the GPU.
const MAX_DEPTH_ULPS: i64 = 4;

/// Colour channels may differ by one level where `(n + 1) * 127.5 + 0.5` or a ramp lands
/// within an ulp of a rounding boundary and the GPU fuses the multiply-add.
const MAX_CHANNEL_DIFF: i32 = 1;

/// ... and only on a tiny fraction of the pixels (measured on lavapipe: at most 1 pixel
/// of 76,800 per render, in the depth view).
const MAX_COLOUR_DIFF_FRACTION: f64 = 0.001;

/// Empty pixels (no splat on either side) whose gap filling differs: each pixel whose
/// winning surfel differs can change the fill of the empty pixels that see it, at most
/// `2 * DEFAULT_FILL_GAP_PX` in its column and as many in its row. Measured on lavapipe: 0.
const MAX_FILLED_DIFF_FRACTION: f64 =
    MAX_INDEX_MISMATCH_FRACTION * 4.0 * wgslam::render::DEFAULT_FILL_GAP_PX as f64;

fn gpu_matches_cpu_on_a_small_map(ctx: GpuContext) -> Completion {
    use wgslam::render::gpu::GpuRenderer;
    let renderer = match GpuRenderer::new(&ctx) {
        Ok(r) => r,
        Err(e) if !wgslam::gpu::test_support::gpu_required() => {
            return skipped(format!("the adapter cannot run the renderer: {e}"));
        }
        Err(e) => panic!("{e}"),
    };
    let root = common::bundled_icl();
    let map = bundled_map(&[1, 10, 20], 2);
    let map_cloud = MapCloud::new(&map);
    let cloud = map_cloud.cloud();
    let (up, heading) = render::trajectory_view_hint(&[gt_poses(&root)[0].1], -480.0).unwrap();
    let cameras = [
        (
            "default",
            render::default_camera(&map.position_weight, 320, 240, up, heading, true).unwrap(),
        ),
        (
            "own pose",
            RenderCamera {
                t_cam_to_world: gt_poses(&root)[0].1,
                intrinsics: Intrinsics::ICL_NUIM.downsampled(2),
            },
        ),
    ];
    for (name, camera) in &cameras {
        for view in [View::Color, View::Normals, View::Weight, View::Depth] {
            let params =
                render::render_params(&cloud, camera, view, &RenderSettings::default()).unwrap();
            let (cpu_idx, cpu_rgba) = render::render_cpu_raw(&params, &cloud);
            let (gpu_idx, gpu_rgba) = renderer.render_raw(&ctx, &params, &cloud).unwrap();
            let mut index_mismatch = 0usize;
            let mut colour_diff = 0usize;
            let mut filled_diff = 0usize;
            let mut first = None;
            for pix in 0..cpu_idx.len() {
                // The winning surfel (or emptiness) must match; its depth (high word) may
                // differ by a few ulps (the GPU fuses the transform's multiply-adds).
                let (kc, kg) = (cpu_idx[pix], gpu_idx[pix]);
                let same_surfel = (kc == 0 && kg == 0)
                    || (kc != 0 && kg != 0 && kc & 0xffff_ffff == kg & 0xffff_ffff);
                if !same_surfel {
                    index_mismatch += 1;
                    first.get_or_insert((pix, kc, kg));
                    continue;
                }
                // Both empty: the pixel shows the background or a filled gap, which reads its
                // neighbours' keys (and so follows their mismatches).
                if kc == 0 && cpu_rgba[pix] != gpu_rgba[pix] {
                    filled_diff += 1;
                    continue;
                }
                let depth_bits = |k: u64| !((k >> 32) as u32) as i64;
                assert!(
                    kc == 0 || (depth_bits(kc) - depth_bits(kg)).abs() <= MAX_DEPTH_ULPS,
                    "{name}/{}: pixel {pix} depth CPU {kc:x} GPU {kg:x}",
                    view.name()
                );
                let (a, b) = (cpu_rgba[pix], gpu_rgba[pix]);
                colour_diff += (a != b) as usize;
                for c in 0..4 {
                    let d = ((a >> (8 * c)) & 255) as i32 - ((b >> (8 * c)) & 255) as i32;
                    assert!(
                        d.abs() <= MAX_CHANNEL_DIFF,
                        "{name}/{}: pixel {pix} CPU {a:08x} GPU {b:08x}",
                        view.name()
                    );
                }
            }
            let filled_frac = filled_diff as f64 / cpu_idx.len() as f64;
            eprintln!("{name}/{}: {filled_diff} filled pixels differ", view.name());
            assert!(
                filled_frac <= MAX_FILLED_DIFF_FRACTION,
                "{name}/{}: {filled_diff} filled pixels differ",
                view.name()
            );
            let frac = index_mismatch as f64 / cpu_idx.len() as f64;
            let colour_frac = colour_diff as f64 / cpu_idx.len() as f64;
            eprintln!(
                "{name}/{}: {colour_diff} pixels off by one level",
                view.name()
            );
            assert!(
                colour_frac <= MAX_COLOUR_DIFF_FRACTION,
                "{name}/{}: {colour_diff} pixels differ in colour",
                view.name()
            );
            eprintln!(
                "{name}/{}: {index_mismatch} index mismatches ({frac:.5})",
                view.name()
            );
            assert!(
                frac <= MAX_INDEX_MISMATCH_FRACTION,
                "{name}/{}: {index_mismatch} pixels differ, first {first:?} (pixel, CPU key, GPU key)",
                view.name()
            );
            // Determinism on the GPU as well: the atomics make the winner order-independent.
            let (gpu_idx2, gpu_rgba2) = renderer.render_raw(&ctx, &params, &cloud).unwrap();
            assert!(
                gpu_idx2 == gpu_idx && gpu_rgba2 == gpu_rgba,
                "GPU render not repeatable"
            );
        }
    }
    Completion::Completed
}

pub(super) fn tests() -> Vec<Test> {
    vec![
        plain(
            "render_params_layout_matches_both_shaders",
            render_params_layout_matches_both_shaders,
        ),
        gpu(
            "gpu_matches_cpu_on_a_small_map",
            gpu_matches_cpu_on_a_small_map,
        ),
    ]
}
