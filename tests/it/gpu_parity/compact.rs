//! The map's compaction (unstable-surfel removal): compact_flags, the scan
//! (prefix_sum_reduce, prefix_sum_blocks, prefix_sum) and compact_scatter against their
//! twins, at many sizes, in small map chunks and across
//! map growth.

use super::RUN_SURFEL_FRACTION_TOL;
use super::{check_count, cpu_map_from_gt, root, slam, small_chunk_backend};
use crate::common::frames::{gt_at, load_frame, load_gt};
use crate::common::harness::{gpu, gpu_backend_test, Test};
use wgslam::cpu;
use wgslam::cpu::binding::Binding;
use wgslam::gpu::{GpuBackend, GpuContext};
use wgslam::layout::map::SurfelMap;
use wgslam::layout::{CompactParams, MapChunk};
use wgslam::slam::backend::{Backend, Inspect};
use wgslam::slam::cpu_backend::CpuBackend;
use wgslam::slam::params::{PoseSource, Profile, SlamParams, UnstableRemoval};

/// Runs the `compact` step on both backends from the same `map` with `params`; checks
/// each kernel's output against its twin exactly (integer flags, offsets and count; the
/// scatter is a copy, so the compacted maps are bit-identical: same surfels, same order).
/// Returns the surfels kept.
fn check_compaction(gpu: &mut GpuBackend, map: &SurfelMap, params: &CompactParams) -> usize {
    let n = map.len();
    let params = CompactParams {
        surfel_count: n as u32,
        ..*params
    };
    // The twins, kernel by kernel.
    let mut flags = vec![0u32; n];
    cpu::compact_flags::compact_flags(&mut [
        Binding::of(&params),
        Binding::of(&MapChunk::whole(n)),
        Binding::read(&map.position_weight),
        Binding::read(&map.normal_frame),
        Binding::write(&mut flags),
    ]);
    let mut offsets = vec![0u32; n];
    let mut kept = 0u32;
    cpu::prefix_sum::scan(&params, &flags, &mut offsets, &mut kept);
    // The plain running sum, so a bug shared by the twin and the shader shows too.
    let mut running = 0u32;
    for i in 0..n {
        assert_eq!(offsets[i], running, "twin prefix_sum at surfel {i}");
        running += flags[i];
    }
    assert_eq!(kept, running, "twin prefix_sum total");
    // The step on both backends.
    let mut c = CpuBackend::with_map(map.clone());
    let n_cpu = c.compact(&params).unwrap();
    gpu.upload_map(map).unwrap();
    let n_gpu = gpu.compact(&params).unwrap();
    let (g_flags, g_offsets) = gpu.download_compaction(n).unwrap();
    let first_diff = |a: &[u32], b: &[u32]| (0..n).find(|&i| a[i] != b[i]);
    if let Some(i) = first_diff(&flags, &g_flags) {
        panic!(
            "compact_flags: surfel {i} cpu {} gpu {}",
            flags[i], g_flags[i]
        );
    }
    if let Some(i) = first_diff(&offsets, &g_offsets) {
        panic!(
            "prefix_sum: surfel {i} cpu {} gpu {}",
            offsets[i], g_offsets[i]
        );
    }
    assert_eq!(
        (n_cpu, n_gpu),
        (kept as usize, kept as usize),
        "surfels kept (cpu step, gpu step) vs twin"
    );
    let (cm, gm) = (c.download_map().unwrap(), gpu.download_map().unwrap());
    assert_eq!(cm.len(), n_cpu);
    for i in 0..n_cpu {
        let same = cm.position_weight[i].map(f32::to_bits)
            == gm.position_weight[i].map(f32::to_bits)
            && cm.normal_frame[i] == gm.normal_frame[i]
            && cm.color[i].map(f32::to_bits) == gm.color[i].map(f32::to_bits);
        assert!(
            same,
            "compact_scatter: slot {i} cpu {:?} {:?} {:?} gpu {:?} {:?} {:?}",
            cm.position_weight[i],
            cm.normal_frame[i],
            cm.color[i],
            gm.position_weight[i],
            gm.normal_frame[i],
            gm.color[i]
        );
    }
    // The survivors are the flagged surfels in their order.
    let expected: Vec<usize> = (0..n).filter(|&i| flags[i] != 0).collect();
    for (slot, &i) in expected.iter().enumerate() {
        assert_eq!(
            cm.normal_frame[slot], map.normal_frame[i],
            "slot {slot} is surfel {i}"
        );
    }
    n_cpu
}

/// compact_flags, prefix_sum and compact_scatter against their twins on a real map: the
/// robust profile's fusion of bundled frames 1..=8 at ground truth without removal, then
/// removal after frame 8 with a short age limit (so part of the map goes), and with rules
/// that keep everything and remove every unstable surfel.
fn compaction_matches_twins(mut gpu: GpuBackend) {
    let mut params = SlamParams::profile(Profile::Robust);
    params.fusion.unstable_removal = None;
    let (mut s, _) = cpu_map_from_gt(8, &params);
    let map = s.backend.download_map().unwrap();
    let n = map.len();
    assert!(n > 2 * 4096, "a map over several texture rows ({n})");
    let rule = |stable_weight, max_age_frames| CompactParams {
        surfel_count: 0,
        frame_id: 8,
        stable_weight,
        max_age_frames,
    };
    let kept = check_compaction(&mut gpu, &map, &rule(3.0, 2));
    eprintln!("compaction: {n} surfels, {kept} kept (weight >= 3 or seen in frames 6..8)");
    assert!(
        kept < n && kept > n / 10,
        "a real test removes some: {kept} of {n}"
    );
    assert_eq!(check_compaction(&mut gpu, &map, &rule(0.0, 0)), n);
    let stable = (0..n)
        .filter(|&i| map.weight(i) >= 2.0 || map.last_frame(i) == 8)
        .count();
    assert_eq!(check_compaction(&mut gpu, &map, &rule(2.0, 0)), stable);
}

/// The scan's blocking at sizes around a thread's 32 flags and a block's 2048 (fewer
/// surfels than one thread's, not a multiple, one block, one more, many blocks: more than
/// prefix_sum_blocks' 256 threads have chunks of several) on hand-made maps with a fixed
/// pattern of stable surfels.
fn compaction_sizes_match_twins(mut gpu: GpuBackend) {
    let block = cpu::prefix_sum::SCAN_BLOCK as usize;
    for n in [
        1usize,
        7,
        33,
        255,
        block - 1,
        block,
        block + 1,
        4097,
        70_001,
        300 * block + 3,
    ] {
        let mut map = SurfelMap::default();
        for i in 0..n {
            // Every third surfel stable, every fifth recent: a pattern that is not periodic
            // in the chunk size.
            let weight = if i % 3 == 0 { 5.0 } else { 1.0 };
            let frame = if i % 5 == 0 { 100 } else { 1 };
            let x = i as f32 * 1e-3;
            map.push(
                [x, 0.5, 2.0],
                [0.0, 0.0, -1.0],
                [i as f32 % 255.0, 1.0, 2.0],
                weight,
                frame,
            );
        }
        let params = CompactParams {
            surfel_count: 0,
            frame_id: 100,
            stable_weight: 3.0,
            max_age_frames: 10,
        };
        let kept = check_compaction(&mut gpu, &map, &params);
        let expected = (0..n).filter(|i| i % 3 == 0 || i % 5 == 0).count();
        assert_eq!(kept, expected, "n = {n}");
    }
}

/// The compact step across map growth: from a tiny capacity, the robust profile with an
/// aggressive removal rule over bundled frames 1..=8 at ground truth (the map grows, the
/// compaction buffers follow, the two map sets swap every frame); the GPU's surfel counts
/// stay within the run tolerance of the CPU's and its map downloads at its count.
fn compaction_follows_map_growth(ctx: GpuContext) {
    let gpu = GpuBackend::with_initial_capacity(ctx, 1000).unwrap();
    let gt = load_gt(&root());
    let mut params = SlamParams {
        poses: PoseSource::GroundTruth,
        ..SlamParams::profile(Profile::Robust)
    };
    params.fusion.unstable_removal = Some(UnstableRemoval {
        stable_weight: 3.0,
        max_age_frames: 1,
        every_frames: 1,
    });
    let mut c = slam(CpuBackend::new(), params.clone());
    let mut g = slam(gpu, params);
    let mut obeyed = 0;
    for i in 1..=8 {
        let f = load_frame(&root(), i);
        let rc = c
            .process(i as u32, &f.depth, &f.rgba, gt_at(&gt, i))
            .unwrap();
        let rg = g
            .process(i as u32, &f.depth, &f.rgba, gt_at(&gt, i))
            .unwrap();
        let what = format!("frame {i}: surfels");
        let (sc, sg) = (rc.surfels_before, rg.surfels_before);
        check_count(&format!("{what} before"), sc, sg, RUN_SURFEL_FRACTION_TOL);
        let (sc, sg) = (
            c.backend.surfel_count().unwrap(),
            g.backend.surfel_count().unwrap(),
        );
        check_count(&what, sc, sg, RUN_SURFEL_FRACTION_TOL);
        let map = c.backend.map();
        obeyed += (0..map.len()).all(|k| map.last_frame(k) + 1 >= i as u32 || map.weight(k) >= 3.0)
            as usize;
    }
    assert_eq!(obeyed, 8, "every CPU map obeys the rule after each frame");
    assert!(g.backend.capacity() > 1000, "the map grew");
    assert_eq!(
        g.backend.download_map().unwrap().len(),
        g.backend.surfel_count().unwrap()
    );
}

pub(super) fn tests() -> Vec<Test> {
    vec![
        gpu_backend_test("compaction_matches_twins", compaction_matches_twins),
        gpu_backend_test("compaction_sizes_match_twins", compaction_sizes_match_twins),
        gpu("compaction_matches_twins_in_small_chunks", |ctx| {
            compaction_matches_twins(small_chunk_backend(ctx))
        }),
        gpu(
            "compaction_follows_map_growth",
            compaction_follows_map_growth,
        ),
    ]
}
