//! The map's prediction at a pose: project_model and predict_model against their twins
//! (also in small map chunks) and pyramid_model's coarser levels.

use super::{check_index_maps, check_vec4_map, cpu_map_from_gt, robust_pyramids_on_both};
use super::{root, small_chunk_backend, MASK_MISMATCH_FRACTION};
use crate::common::frames::{gt_at, load_frame};
use crate::common::harness::{gpu, gpu_backend_test, Test};
use crate::common::unfiltered_level_0;
use wgslam::cpu;
use wgslam::cpu::binding::Binding;
use wgslam::geometry::se3;
use wgslam::gpu::GpuBackend;
use wgslam::layout::MapChunk;
use wgslam::slam::backend::{Backend, Inspect};
use wgslam::slam::params::{Profile, SlamParams};

/// project_model and predict_model against their twins on a real fused map, viewed from a
/// later frame's ground-truth pose.
fn predict_matches_twins(mut gpu: GpuBackend) {
    let params = SlamParams::profile(Profile::Assignment);
    let (mut s, gt) = cpu_map_from_gt(3, &params);
    let map = s.backend.download_map().unwrap();
    gpu.upload_map(&map).unwrap();
    let frame = load_frame(&root(), 6);
    let steps = unfiltered_level_0(&s);
    gpu.preprocess(&steps, &frame.depth, &frame.rgba).unwrap();
    let t_world_to_cam = se3::inverse_rigid(gt_at(&gt, 6).unwrap());
    let mut proj = s.project_params(&t_world_to_cam);
    // A backend fills the count in; the twins below are called directly.
    assert_eq!(proj.surfel_count, 0);
    proj.surfel_count = map.len() as u32;

    let n = (proj.camera.width * proj.camera.height) as usize;
    let mut index_cpu = vec![0u64; n];
    let whole = MapChunk::whole(map.len());
    crate::common::project_map(&proj, &map, None, Binding::write(&mut index_cpu));
    let (mut pv_cpu, mut pn_cpu) = (vec![[0.0; 4]; n], vec![[0.0; 4]; n]);
    let mut pi_cpu = vec![0.0; n];
    cpu::predict_model::predict_model(&mut [
        Binding::of(&proj),
        Binding::read(&index_cpu),
        Binding::of(&whole),
        Binding::read(&map.position_weight),
        Binding::read(&map.normal_frame),
        Binding::read(&map.color),
        Binding::write(&mut pv_cpu),
        Binding::write(&mut pn_cpu),
        Binding::write(&mut pi_cpu),
    ]);
    gpu.predict(&proj, &[]).unwrap();
    let index_gpu = gpu.download_index_map().unwrap();
    let (pv_gpu, pn_gpu) = gpu.download_prediction(0).unwrap();
    check_index_maps("index map", &index_cpu, &index_gpu);
    // The same surfel gives bit-identical copies of its position and normal.
    check_vec4_map("predicted vertex", &pv_cpu, &pv_gpu, 0.0);
    check_vec4_map("predicted normal", &pn_cpu, &pn_gpu, 0.0);
    // The predicted intensity of each pixel both predicted from the same surfel (the same
    // vertex bits) is the same luma; pixels without one are INTENSITY_NONE on both.
    let pi_gpu = gpu.download_pred_intensity().unwrap();
    let same: Vec<usize> = (0..n).filter(|&i| pv_cpu[i] == pv_gpu[i]).collect();
    assert!(same.len() as f64 >= (1.0 - MASK_MISMATCH_FRACTION) * n as f64);
    let mut surfels = 0;
    for i in same {
        let (c, g) = (pi_cpu[i], pi_gpu[i]);
        surfels += usize::from(c >= 0.0);
        assert!(
            (c - g).abs() <= INTENSITY_TOL && (c >= 0.0) == (pv_cpu[i][3] > 0.0),
            "pixel {i}: predicted intensity cpu {c} gpu {g}"
        );
    }
    assert!(
        surfels > n / 2,
        "a real prediction: {surfels} of {n} pixels"
    );
}

/// The predicted intensity is the luma of a surfel colour (0..255 per channel) over 255:
/// three products and two sums near 1, where the GPU may fuse or reorder them (a few ulps
/// of 6e-8 each); 1e-6 is ample and far below one grey level (4e-3).
const INTENSITY_TOL: f32 = 1e-6;

/// pyramid_model against its twin, through `predict` with the robust profile's three
/// levels: each coarser level copies the finer level's pixel (2u, 2v), bit for bit, on
/// both backends.
fn pyramid_model_matches_twin(mut gpu: GpuBackend) {
    let (mut s, _) = robust_pyramids_on_both(&mut gpu, 6, 6);
    for level in 0..3 {
        let k = s.level_intrinsics(level);
        let (cv, cn) = s.backend.download_prediction(level).unwrap();
        let (gv, gn) = gpu.download_prediction(level).unwrap();
        assert_eq!(
            (cv.len(), gv.len()),
            (k.pixels(), k.pixels()),
            "level {level}"
        );
        check_vec4_map(&format!("level {level} predicted vertex"), &cv, &gv, 0.0);
        check_vec4_map(&format!("level {level} predicted normal"), &cn, &gn, 0.0);
        if level > 0 {
            // The twin's rule on its own finer level.
            let (fv, _) = s.backend.download_prediction(level - 1).unwrap();
            let fine_w = s.level_intrinsics(level - 1).width as usize;
            let (u, v) = (k.width as usize / 2, k.height as usize / 2);
            assert_eq!(cv[v * k.width as usize + u], fv[2 * v * fine_w + 2 * u]);
        }
    }
    assert!(gpu.download_prediction(3).unwrap().0.is_empty());
}

pub(super) fn tests() -> Vec<Test> {
    vec![
        gpu_backend_test("predict_matches_twins", predict_matches_twins),
        gpu("predict_matches_twins_in_small_chunks", |ctx| {
            predict_matches_twins(small_chunk_backend(ctx))
        }),
        gpu_backend_test("pyramid_model_matches_twin", pyramid_model_matches_twin),
    ]
}
