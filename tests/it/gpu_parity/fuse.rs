//! Fusion of a frame into the map: fuse_select, fuse_merge, fuse_flags, prefix_sum,
//! fuse_add and fuse_prune against their twins, for each profile and in small map chunks.

use super::{check_index_maps, check_surfel, cpu_map_from_gt, gpu_backend, preprocess_both, root};
use super::{small_chunk_backend, SMALL_CHUNK_SURFELS};
use super::{FUSED_INDEX_MAP_MISMATCH_FRACTION, MASK_MISMATCH_FRACTION, OFF_RAY_TOL_M};
use crate::common::frames::{gt_at, load_frame};
use crate::common::harness::{gpu, Test};
use crate::common::level_0;
use wgslam::cpu;
use wgslam::cpu::binding::Binding;
use wgslam::geometry::se3;
use wgslam::gpu::GpuBackend;
use wgslam::layout::map::SurfelMap;
use wgslam::layout::{FuseParams, MapChunk, ProjectParams, ASSOCIATION_BEST_CANDIDATE};
use wgslam::slam::backend::{Backend, FrameMaps, Inspect};
use wgslam::slam::params::{Profile, SlamParams};

/// Stride of [`interleaved`]: 64 surfels apart in the original order are neighbours in the
/// new one, so a map of 73,000 surfels puts each original 1024-surfel block across all
/// of them.
const INTERLEAVE_STRIDE: usize = 64;

/// A confident surfel's depth gate for the best-candidate checks, metres: below the robust
/// profile's 0.05, as `docs/robust-profile.md` measures it.
const NARROWING_GATE_M: f32 = 0.04;

/// `m` reordered: every `stride`-th surfel from 0, then every `stride`-th from 1, and so
/// on, so surfels made from neighbouring pixels (neighbours in append order) end up far
/// apart in the map.
fn interleaved(m: &SurfelMap, stride: usize) -> SurfelMap {
    let order: Vec<usize> = (0..stride)
        .flat_map(|r| (r..m.len()).step_by(stride))
        .collect();
    SurfelMap {
        position_weight: order.iter().map(|&i| m.position_weight[i]).collect(),
        normal_frame: order.iter().map(|&i| m.normal_frame[i]).collect(),
        color: order.iter().map(|&i| m.color[i]).collect(),
    }
}

/// fuse_select (robust profile), fuse_merge, fuse_flags, prefix_sum and fuse_add against
/// their twins, for each profile: the association keys pixel by pixel; merged surfels
/// keep their index and appended ones are in append order, so the maps are compared slot
/// by slot.
/// With `chunk_surfels` (the GPU map's chunk size), both backends start from the map in
/// [`interleaved`] order, so neighbouring surfels lie in different chunks, and the test
/// checks that surfels are retired across chunks.
fn fuse_matches_twins(mut gpu: GpuBackend, profile: Profile, chunk_surfels: Option<usize>) {
    let params = SlamParams::profile(profile);
    let (mut s, gt) = cpu_map_from_gt(2, &params);
    let mut before = s.backend.download_map().unwrap();
    if chunk_surfels.is_some() {
        before = interleaved(&before, INTERLEAVE_STRIDE);
        s.backend.upload_map(&before).unwrap();
    }
    gpu.upload_map(&before).unwrap();
    let frame = load_frame(&root(), 3);
    let steps = level_0(&s);
    preprocess_both(&mut s.backend, &mut gpu, &steps, &frame);
    let t_world_to_cam = se3::inverse_rigid(gt_at(&gt, 3).unwrap());
    let mut fp = s.fuse_params(&t_world_to_cam, 3);
    // The pipeline prunes only on the frames the unstable-surfel removal runs after; the
    // kernels are checked with the profile's scale whatever the frame.
    let removal_frame = params.fusion.unstable_removal.map_or(1, |r| r.every_frames);
    assert_eq!(
        s.fuse_params(&t_world_to_cam, removal_frame).prune_scale,
        params.fusion.prune_scale
    );
    if params.fusion.unstable_removal.is_some() {
        assert_eq!(fp.prune_scale, 0.0, "frame 3 is not a removal frame");
    }
    fp.prune_scale = params.fusion.prune_scale;
    if fp.association == ASSOCIATION_BEST_CANDIDATE {
        // Both profiles keep one depth gate; the kernels are checked with a gate that
        // narrows with weight (`--fuse-dist-confident`), so that path is the twin's too.
        assert_eq!(fp.dist_confident_m, fp.dist_m);
        fp.dist_confident_m = NARROWING_GATE_M;
        check_fuse_select(&mut gpu, &before, &s.backend.download_frame().unwrap(), &fp);
    }
    s.backend.fuse(&fp, None).unwrap();
    gpu.fuse(&fp, None).unwrap();
    let n_cpu = s.backend.surfel_count().unwrap();
    let n_gpu = gpu.surfel_count().unwrap();
    let c = s.backend.download_map().unwrap();
    let g = gpu.download_map().unwrap();
    assert_eq!((c.len(), g.len()), (n_cpu, n_gpu));
    let merged = (0..before.len()).filter(|&i| c.last_frame(i) == 3).count();
    eprintln!(
        "fuse: {} surfels before, {merged} merged; after cpu {n_cpu}, gpu {n_gpu}",
        before.len()
    );
    assert!(merged > 1000, "too few merges for a real test");
    // The GPU's association keys of this fuse step (fuse_select's choices).
    let keys = gpu.download_assoc().unwrap();
    if fp.association == ASSOCIATION_BEST_CANDIDATE {
        // fuse_flags: a valid pixel that chose nothing is added unless a neighbour's merged
        // surfel covers it; the test must see such pixels.
        let nd = s.backend.download_frame().unwrap().normal_depth;
        let unchosen = (0..keys.len())
            .filter(|&p| keys[p] == 0 && nd[p][3] > 0.0)
            .count();
        let covered = unchosen - (n_gpu - before.len());
        eprintln!("fuse_flags: {unchosen} valid pixels chose nothing, {covered} covered");
        assert!(
            covered > 100,
            "too few neighbour-covered pixels for a real test"
        );
        // The index map fuse_select and fuse_add built for the next prediction, on each
        // backend against a fresh projection of its own map, then against each other.
        let fused_cpu = s.backend.index_map().to_vec();
        let fused_gpu = gpu.download_index_map().unwrap();
        let proj = s.project_params(&t_world_to_cam);
        check_fused_index_map(&c, before.len(), &fused_cpu, &proj);
        check_fused_index_map(&g, before.len(), &fused_gpu, &proj);
        check_index_maps("fused index map", &fused_cpu, &fused_gpu);
    }
    // fuse_prune (robust profile) retires duplicates: weight 0 and last frame 0.
    let retired = |m: &SurfelMap| {
        (0..before.len())
            .filter(|&i| m.weight(i) == 0.0 && m.last_frame(i) == 0 && before.weight(i) > 0.0)
            .count()
    };
    let (retired_cpu, retired_gpu) = (retired(&c), retired(&g));
    eprintln!("fuse_prune: retired cpu {retired_cpu}, gpu {retired_gpu}");
    if fp.prune_scale > 0.0 {
        assert!(retired_cpu > 100, "too few retired surfels for a real test");
        // The merged surfel a duplicate is compared with may be in another GPU chunk.
        let allowed = (retired_cpu as f64 * MASK_MISMATCH_FRACTION).ceil() as usize;
        assert!(
            retired_cpu.abs_diff(retired_gpu) <= allowed,
            "retired cpu {retired_cpu} vs gpu {retired_gpu}"
        );
        if let Some(chunk) = chunk_surfels {
            // Retired surfels whose pixel chose a surfel in another GPU chunk: the merged
            // surfel they were compared with came from that chunk, via `merged`.
            let cam = wgslam::cpu::camera_intrinsics(&fp.camera);
            let across = (0..before.len())
                .filter(|&i| g.weight(i) == 0.0 && g.last_frame(i) == 0 && before.weight(i) > 0.0)
                .filter(|&i| {
                    let p = cpu::transform_point(&fp.t_world_to_cam, g.position(i).into());
                    cpu::project_to_pixel(cam, fp.camera.width, fp.camera.height, p)
                        .is_some_and(|pix| (keys[pix] as u32) as usize / chunk != i / chunk)
                })
                .count();
            eprintln!("fuse_prune: {across} of {retired_gpu} retired across GPU chunks");
            assert!(
                across > 10,
                "too few retirements across chunks for a real test"
            );
        }
    } else {
        assert_eq!((retired_cpu, retired_gpu), (0, 0), "pruning is off");
    }
    // Merge decisions on a threshold can flip for a few surfels (FMA); then the appended
    // sets differ by the same few pixels.
    let allowed = (before.len() as f64 * MASK_MISMATCH_FRACTION).ceil() as usize;
    let flips: Vec<usize> = (0..before.len())
        .filter(|&i| (c.last_frame(i) == 3) != (g.last_frame(i) == 3))
        .collect();
    assert!(
        flips.len() <= allowed,
        "{} merge decisions differ; first surfel {:?}",
        flips.len(),
        flips.first()
    );
    for i in (0..before.len()).filter(|i| !flips.contains(i)) {
        check_surfel("merged/kept surfel", &c, i, &g, i);
    }
    assert!(
        n_cpu.abs_diff(n_gpu) <= allowed,
        "surfel counts cpu {n_cpu} gpu {n_gpu}"
    );
    // New surfels lie in append order on both backends (fuse_flags + prefix_sum), so the
    // maps match slot by slot: the GPU map's bytes do not depend on thread order.
    if flips.is_empty() && n_cpu == n_gpu {
        for i in before.len()..n_cpu {
            check_surfel("appended surfel", &c, i, &g, i);
        }
    }
}

/// The index map a best-candidate fusion built (`fused`, on the CPU) against
/// project_model's of the fused `map` at the same view (`proj`): a surfel merged this frame
/// keys the pixel its centre projected to before the merge moved it, so a few pixels pick
/// another surfel, and none may pick a surfel past the map's end. The surfels fuse_add
/// appended (from `first_new` on) lie on their pixels' rays, so both maps agree where one
/// of them is nearest.
fn check_fused_index_map(map: &SurfelMap, first_new: usize, fused: &[u64], proj: &ProjectParams) {
    let n = fused.len();
    let mut fresh = vec![0u64; n];
    let proj = ProjectParams {
        surfel_count: map.len() as u32,
        ..*proj
    };
    crate::common::project_map(&proj, map, None, Binding::write(&mut fresh));
    let surfel = |k: u64| (k != 0).then_some(k & 0xffff_ffff);
    assert!(
        fused
            .iter()
            .all(|&k| surfel(k).is_none_or(|i| (i as usize) < map.len())),
        "the fused index map names a surfel past the map's end"
    );
    let covered = fresh.iter().filter(|&&k| k != 0).count();
    let differ = (0..n)
        .filter(|&p| surfel(fused[p]) != surfel(fresh[p]))
        .count();
    let is_new = |k: u64| surfel(k).is_some_and(|i| i as usize >= first_new);
    let new_keys = (0..n).filter(|&p| is_new(fresh[p])).count();
    let new_differ = (0..n)
        .filter(|&p| is_new(fresh[p]) && surfel(fused[p]) != surfel(fresh[p]))
        .count();
    eprintln!(
        "fused index map: {differ} of {covered} covered pixels pick another surfel than a \
         fresh projection; {new_differ} of the {new_keys} that pick a new surfel differ"
    );
    assert!(covered > 1000, "too few keys for a real test");
    assert!(new_keys > 10, "too few new surfels for a real test");
    // The new surfel's depth is its pixel's measurement both ways, give or take the few
    // ULP of the trip through the pose and back, which can flip a near tie: the mask
    // allowance.
    assert!(
        new_differ as f64 <= (MASK_MISMATCH_FRACTION * new_keys as f64).ceil(),
        "fused index map: {new_differ} of {new_keys} new surfels' pixels differ"
    );
    assert!(
        differ as f64 <= FUSED_INDEX_MAP_MISMATCH_FRACTION * covered as f64,
        "fused index map: {differ} of {covered} pixels differ from a fresh projection"
    );
}

/// fuse_select's twin on `map` against the GPU's keys of its whole fuse step from the
/// same map and frame (`params`: the fuse step's, with `surfel_count` filled in here).
fn check_fuse_select(
    gpu: &mut GpuBackend,
    map: &SurfelMap,
    frame: &FrameMaps,
    params: &FuseParams,
) {
    let params = FuseParams {
        surfel_count: map.len() as u32,
        ..*params
    };
    let n = frame.normal_depth.len();
    let mut keys = vec![0u64; n];
    let mut index_map = vec![0u64; n];
    let whole = MapChunk::whole(map.len());
    let bounds = cpu::block_bounds::whole_map_bounds(&map.position_weight);
    cpu::fuse_select::fuse_select(&mut [
        Binding::of(&params),
        Binding::read(&frame.normal_depth),
        Binding::of(&whole),
        Binding::read(&bounds),
        Binding::read(&map.position_weight),
        Binding::read(&map.normal_frame),
        Binding::read(&map.color),
        Binding::write(&mut keys),
        Binding::write(&mut index_map),
    ]);
    // The index map it builds on the way is project_model's at the same view, key for key
    // (the same transform and projection functions).
    let proj = ProjectParams {
        t_world_to_cam: params.t_world_to_cam,
        camera: params.camera,
        surfel_count: params.surfel_count,
        _pad0: 0,
        _pad1: 0,
        _pad2: 0,
    };
    let mut projected = vec![0u64; n];
    crate::common::project_map(&proj, map, None, Binding::write(&mut projected));
    assert!(
        projected.iter().filter(|&&k| k != 0).count() > 1000,
        "too few keys"
    );
    if let Some(p) = (0..n).find(|&p| index_map[p] != projected[p]) {
        panic!(
            "fuse_select's index map differs from project_model's at pixel {p}: {:#x} vs {:#x}",
            index_map[p], projected[p]
        );
    }
    gpu.upload_map(map).unwrap();
    gpu.fuse(&params, None).unwrap();
    let g = gpu.download_assoc().unwrap();
    assert_eq!(g.len(), keys.len(), "assoc sizes");
    // A pixel's choice: the surfel (low word) must match; the off-ray distance (high word,
    // inverted bits) within OFF_RAY_TOL_M. A choice may flip where a gate or two distances
    // tie within that (FMA): the mask allowance.
    let off_ray_m = |k: u64| f32::from_bits(!((k >> 32) as u32));
    let chosen = keys.iter().filter(|&&k| k != 0).count();
    let differ: Vec<usize> = (0..keys.len())
        .filter(|&p| {
            let (c, g) = (keys[p], g[p]);
            (c as u32) != (g as u32)
                || (c == 0) != (g == 0)
                || (c != 0 && (off_ray_m(c) - off_ray_m(g)).abs() > OFF_RAY_TOL_M)
        })
        .collect();
    eprintln!(
        "fuse_select: {chosen} of {} pixels chose a surfel; {} differ",
        keys.len(),
        differ.len()
    );
    assert!(chosen > 1000, "too few choices for a real test");
    let allowed = (keys.len() as f64 * MASK_MISMATCH_FRACTION).ceil() as usize;
    assert!(
        differ.len() <= allowed,
        "{} pixels chose differently; first pixel {:?}: cpu {:x} gpu {:x}",
        differ.len(),
        differ.first(),
        differ.first().map_or(0, |&p| keys[p]),
        differ.first().map_or(0, |&p| g[p])
    );
    // Put the map back for the caller's own fuse step.
    gpu.upload_map(map).unwrap();
}

pub(super) fn tests() -> Vec<Test> {
    vec![
        gpu("fuse_matches_twins", |ctx| {
            fuse_matches_twins(gpu_backend(ctx), Profile::Assignment, None)
        }),
        gpu("robust_fuse_matches_twins", |ctx| {
            fuse_matches_twins(gpu_backend(ctx), Profile::Robust, None)
        }),
        gpu("robust_fuse_matches_twins_in_small_chunks", |ctx| {
            fuse_matches_twins(
                small_chunk_backend(ctx),
                Profile::Robust,
                Some(SMALL_CHUNK_SURFELS),
            )
        }),
    ]
}
