//! The GPU map itself: growth from a tiny capacity, the capacity error, and culling by
//! block boxes (conservative on the CPU, boxes holding their surfels on both backends).

use super::{
    check_count, check_surfel, cpu_map_from_gt, root, slam, small_chunk_backend, surfel_key,
};
use super::{RUN_SURFEL_FRACTION_TOL, SMALL_CHUNK_SURFELS};
use crate::common::frames::{gt_at, load_frame, load_gt};
use crate::common::harness::{gpu, plain, Test};
use wgslam::cpu;
use wgslam::cpu::binding::Binding;
use wgslam::geometry::se3;
use wgslam::gpu::{GpuBackend, GpuContext};
use wgslam::layout::map::SurfelMap;
use wgslam::layout::BLOCK_SURFELS;
use wgslam::slam::backend::{Backend, Inspect};
use wgslam::slam::cpu_backend::CpuBackend;
use wgslam::slam::params::{PoseSource, Profile, SlamParams};
use wgslam::Error;

/// A tiny initial capacity forces the map buffers to grow during fusion; the result is
/// the same map as the CPU's.
fn map_grows_from_a_tiny_capacity(ctx: GpuContext) {
    let gpu = GpuBackend::with_map_layout(ctx, 1000, SMALL_CHUNK_SURFELS).unwrap();
    // Slots come in whole culling blocks.
    assert_eq!(gpu.capacity(), BLOCK_SURFELS as usize);
    let gt = load_gt(&root());
    let params = SlamParams {
        poses: PoseSource::GroundTruth,
        ..SlamParams::profile(Profile::Assignment)
    };
    let mut c = slam(CpuBackend::new(), params.clone());
    let mut g = slam(gpu, params);
    for i in 1..=3 {
        let f = load_frame(&root(), i);
        c.process(i as u32, &f.depth, &f.rgba, gt_at(&gt, i))
            .unwrap();
        g.process(i as u32, &f.depth, &f.rgba, gt_at(&gt, i))
            .unwrap();
    }
    let cap = g.backend.capacity();
    eprintln!(
        "capacity grew 1024 -> {cap} in {} chunks; surfels cpu {} gpu {}",
        g.backend.map_chunks(),
        c.backend.surfel_count().unwrap(),
        g.backend.surfel_count().unwrap()
    );
    assert!(g.backend.map_chunks() > 1, "the map grew past one chunk");
    assert!(cap >= g.backend.surfel_count().unwrap() + 76_800);
    let (nc, ng) = (
        c.backend.surfel_count().unwrap(),
        g.backend.surfel_count().unwrap(),
    );
    check_count("surfels", nc, ng, RUN_SURFEL_FRACTION_TOL);
    // The first frame's surfels survived every grow-by-copy: compare them sorted.
    let (cm, gm) = (
        c.backend.download_map().unwrap(),
        g.backend.download_map().unwrap(),
    );
    let first = |m: &SurfelMap| {
        let mut v: Vec<usize> = (0..m.len())
            .filter(|&i| m.weight(i) == 1.0 && m.last_frame(i) == 1)
            .collect();
        v.sort_by_key(|&i| surfel_key(m, i));
        v
    };
    let (fc, fg) = (first(&cm), first(&gm));
    assert!(fc.len() > 1000);
    // As many may differ as in the whole map (the tolerance is a fraction of all surfels).
    let allowed = (nc as f64 * RUN_SURFEL_FRACTION_TOL).ceil() as usize;
    assert!(
        fc.len().abs_diff(fg.len()) <= allowed,
        "{} vs {}",
        fc.len(),
        fg.len()
    );
    if fc.len() == fg.len() {
        for (&a, &b) in fc.iter().zip(&fg) {
            check_surfel("frame-1 surfel after growth", &cm, a, &gm, b);
        }
    }
}

/// A map capped below what the second frame may need fails with Error::Capacity naming
/// the surfels, bytes and limit, instead of writing out of bounds or dropping the frame.
fn map_capacity_error(ctx: GpuContext) {
    let gpu = GpuBackend::with_initial_capacity(ctx, 1000)
        .unwrap()
        .with_max_surfels(100_000);
    let gt = load_gt(&root());
    let params = SlamParams {
        poses: PoseSource::GroundTruth,
        ..SlamParams::profile(Profile::Assignment)
    };
    let mut g = slam(gpu, params);
    let f = load_frame(&root(), 1);
    // Frame 1: 0 + 76,800 pixels fit in 100,000.
    g.process(1, &f.depth, &f.rgba, gt_at(&gt, 1)).unwrap();
    let f = load_frame(&root(), 2);
    match g.process(2, &f.depth, &f.rgba, gt_at(&gt, 2)) {
        Err(Error::Capacity(msg)) => {
            eprintln!("{msg}");
            assert!(msg.contains("100000 surfels"), "{msg}");
        }
        other => panic!("expected Error::Capacity, got {other:?}"),
    }
}

// ---------------------------------------------------------------------------------------
// Culling by block boxes.

/// True when every surfel lies inside its block's box (`bounds` as the backends keep it).
fn surfels_in_their_boxes(map: &SurfelMap, bounds: &[[u32; 4]]) -> Result<(), String> {
    for i in 0..map.len() {
        let b = i / BLOCK_SURFELS as usize;
        let (lo, hi) = (
            cpu::decode_corner(bounds[2 * b]),
            cpu::decode_corner(bounds[2 * b + 1]),
        );
        let p = glam::Vec3::from(map.position(i));
        if p.cmplt(lo).any() || p.cmpgt(hi).any() {
            return Err(format!(
                "surfel {i} at {p} outside block {b}'s box {lo}..{hi}"
            ));
        }
    }
    Ok(())
}

/// Culling never drops a surfel that would land in the image: project_model's twin with
/// the real boxes gives the same index map as with boxes that hold the whole world, from
/// a pose that sees the map and from that pose tilted about its horizontal axis (a block
/// is a few image rows of one frame, so tilting moves some out of view while others stay)
/// and turned about its vertical axis until it faces away (where every block is culled):
/// the equality is tested where culling does something.
fn culling_is_conservative() {
    let params = SlamParams::profile(Profile::Robust);
    let (s, gt) = cpu_map_from_gt(4, &params);
    let map = s.backend.map();
    let bounds = cpu::block_bounds::whole_map_bounds(&map.position_weight);
    surfels_in_their_boxes(map, &bounds).unwrap();
    // One box per block holding the whole world (1000 km either way).
    let corner = |x: f32| {
        let e = wgslam::layout::ordered_from_f32(x);
        [e, e, e, 0]
    };
    let world: Vec<[u32; 4]> = (0..bounds.len())
        .map(|e| corner(if e % 2 == 0 { -1.0e6 } else { 1.0e6 }))
        .collect();
    let t_seen = se3::inverse_rigid(gt_at(&gt, 6).unwrap());
    let blocks = bounds.len() / 2;
    let mut partial = 0;
    let tilt = |d: f64| {
        (
            format!("tilted {d} deg"),
            glam::DMat4::from_rotation_x(d.to_radians()),
        )
    };
    let turn = |d: f64| {
        (
            format!("turned {d} deg"),
            glam::DMat4::from_rotation_y(d.to_radians()),
        )
    };
    let poses = [
        turn(0.0),
        tilt(10.0),
        tilt(20.0),
        tilt(-20.0),
        turn(45.0),
        turn(180.0),
    ];
    for (i, (label, turn)) in poses.iter().enumerate() {
        let proj = wgslam::layout::ProjectParams {
            surfel_count: map.len() as u32,
            ..s.project_params(&(*turn * t_seen))
        };
        let n = (proj.camera.width * proj.camera.height) as usize;
        let splat = |b: &[[u32; 4]]| {
            let mut index = vec![0u64; n];
            crate::common::project_map(&proj, map, Some(b), Binding::write(&mut index));
            index
        };
        let (culled_index, full_index) = (splat(&bounds), splat(&world));
        let cam = wgslam::cpu::camera_intrinsics(&proj.camera);
        let culled = (0..blocks)
            .filter(|&b| {
                let (lo, hi) = (
                    cpu::decode_corner(bounds[2 * b]),
                    cpu::decode_corner(bounds[2 * b + 1]),
                );
                !cpu::block_visible(
                    &proj.t_world_to_cam,
                    cam,
                    proj.camera.width,
                    proj.camera.height,
                    lo,
                    hi,
                )
            })
            .count();
        let covered = full_index.iter().filter(|&&k| k != 0).count();
        eprintln!("{label}: {culled} of {blocks} blocks culled; {covered} pixels covered");
        assert_eq!(
            culled_index, full_index,
            "{label}: culling changed the index map"
        );
        if i == 0 {
            assert!(covered > 1000, "the map is in view");
        }
        if i == poses.len() - 1 {
            assert_eq!(covered, 0, "facing away, nothing is in view");
            assert_eq!(culled, blocks, "facing away, every block is culled");
        }
        if culled > 0 && covered > 0 {
            partial += 1;
        }
    }
    assert!(
        partial > 0,
        "no pose culled some blocks with surfels in view"
    );
}

/// After a robust run (merges moving surfels, compaction, appends) every surfel lies in
/// its block's box on both backends, the GPU's map in small chunks; after an upload, every
/// GPU box is its twin's.
fn block_boxes_hold_their_surfels(ctx: GpuContext) {
    let gt = load_gt(&root());
    let params = SlamParams::profile(Profile::Robust);
    let mut c = slam(CpuBackend::new(), params.clone());
    let mut g = slam(small_chunk_backend(ctx), params);
    let last = 12;
    for i in 1..=last {
        let f = load_frame(&root(), i);
        c.process(i as u32, &f.depth, &f.rgba, gt_at(&gt, i))
            .unwrap();
        g.process(i as u32, &f.depth, &f.rgba, gt_at(&gt, i))
            .unwrap();
    }
    // A predict refreshes the boxes of the blocks the last fusion appended to.
    let proj = c.project_params(&se3::inverse_rigid(gt_at(&gt, last).unwrap()));
    let pyramid = c.pyramid_levels();
    c.backend.predict(&proj, &pyramid).unwrap();
    g.backend.predict(&proj, &pyramid).unwrap();
    let cm = c.backend.download_map().unwrap();
    surfels_in_their_boxes(&cm, c.backend.block_boxes()).unwrap();
    let gm = g.backend.download_map().unwrap();
    let gb = g.backend.download_block_bounds().unwrap();
    surfels_in_their_boxes(&gm, &gb).unwrap();
    eprintln!(
        "{} / {} surfels in {} / {} blocks inside their boxes ({} GPU chunks)",
        cm.len(),
        gm.len(),
        cm.len().div_ceil(BLOCK_SURFELS as usize),
        gb.len() / 2,
        g.backend.map_chunks()
    );
    // Every box recomputed (an upload makes them all stale; merges since their last
    // computation only grew them): block_bounds against its twin, exactly (min and max do
    // not depend on the order of the workgroup's tree).
    g.backend.upload_map(&gm).unwrap();
    g.backend.predict(&proj, &pyramid).unwrap();
    let gb = g.backend.download_block_bounds().unwrap();
    let twin = cpu::block_bounds::whole_map_bounds(&gm.position_weight);
    assert!(gb.len() >= twin.len(), "{} GPU box entries", gb.len());
    if let Some(e) = (0..twin.len()).find(|&e| gb[e] != twin[e]) {
        panic!(
            "block_boxes: block {} {} gpu {:?} twin {:?}",
            e / 2,
            ["min", "max"][e % 2],
            gb[e],
            twin[e]
        );
    }
}

pub(super) fn tests() -> Vec<Test> {
    vec![
        gpu(
            "map_grows_from_a_tiny_capacity",
            map_grows_from_a_tiny_capacity,
        ),
        gpu("map_capacity_error", map_capacity_error),
        plain("culling_is_conservative", culling_is_conservative),
        gpu(
            "block_boxes_hold_their_surfels",
            block_boxes_hold_their_surfels,
        ),
    ]
}
