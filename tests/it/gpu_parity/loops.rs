//! Loop closure's GPU steps against the CPU: `deform_surfels` against its twin (a map of
//! bundled frames spread over many small chunks, nodes with real rotations), and the two
//! copies a loop's verification makes (a pyramid level down, a prediction up).

use super::{cpu_map_from_gt, slam, small_chunk_backend, NORMAL_TOL, VERTEX_TOL_M};
use crate::common::frames::load_frame;
use crate::common::harness::{gpu, Test};
use glam::{DMat4, DVec3};
use wgslam::geometry::se3;
use wgslam::gpu::GpuContext;
use wgslam::layout::DeformNode;
use wgslam::slam::backend::{Backend, Inspect};
use wgslam::slam::cpu_backend::CpuBackend;
use wgslam::slam::loops::deform_node;
use wgslam::slam::params::SlamParams;

/// A node at `frame` correcting by a rotation of `deg` degrees about `axis` and a
/// translation `t` (metres): the size of a real loop's correction.
fn node(frame: u32, axis: DVec3, deg: f64, t: DVec3) -> DeformNode {
    let w = axis.normalize() * deg.to_radians();
    let c = DMat4::from_translation(t) * se3::exp(&[w.x, w.y, w.z, 0.0, 0.0, 0.0]);
    deform_node(frame, &c)
}

/// The map of bundled frames 1..=6 (last frames 1..6) deformed on both backends by three
/// nodes (frames 2, 4, 5: surfels before the first, between two, and after the last): the
/// same positions and normals within the kernels' float tolerances, weights and frames
/// bit for bit, and every surfel moved (the kernel ran over every chunk).
fn deform_matches_twin(ctx: GpuContext) {
    let params = SlamParams::default();
    let (mut cpu_slam, _) = cpu_map_from_gt(6, &params);
    let map = cpu_slam.backend.download_map().unwrap();
    let nodes = [
        node(2, DVec3::Z, 1.0, DVec3::new(0.01, 0.0, 0.0)),
        node(
            4,
            DVec3::new(1.0, 1.0, 0.0),
            2.0,
            DVec3::new(0.0, -0.02, 0.01),
        ),
        node(5, DVec3::X, -1.5, DVec3::new(0.03, 0.01, -0.02)),
    ];
    let mut gpu = small_chunk_backend(ctx);
    gpu.upload_map(&map).unwrap();
    assert!(gpu.map_chunks() > 4, "the map spans many chunks");
    gpu.deform(&nodes).unwrap();
    cpu_slam.backend.deform(&nodes).unwrap();
    let (c, g) = (
        cpu_slam.backend.download_map().unwrap(),
        gpu.download_map().unwrap(),
    );
    assert_eq!(c.len(), g.len());
    for i in 0..c.len() {
        let (pc, pg, p0) = (c.position(i), g.position(i), map.position(i));
        let dp = (0..3).map(|k| (pc[k] - pg[k]).abs()).fold(0.0, f32::max);
        assert!(
            dp <= VERTEX_TOL_M,
            "surfel {i}: position cpu {pc:?} gpu {pg:?}"
        );
        let moved = (0..3).map(|k| (pc[k] - p0[k]).abs()).fold(0.0, f32::max);
        assert!(moved > 1e-3, "surfel {i} did not move: {p0:?} -> {pc:?}");
        let (nc, ng) = (c.normal(i), g.normal(i));
        let dn = (0..3).map(|k| (nc[k] - ng[k]).abs()).fold(0.0, f32::max);
        assert!(dn <= NORMAL_TOL, "surfel {i}: normal cpu {nc:?} gpu {ng:?}");
        assert_eq!(
            c.weight(i).to_bits(),
            g.weight(i).to_bits(),
            "surfel {i} weight"
        );
        assert_eq!(c.last_frame(i), g.last_frame(i), "surfel {i} frame");
        assert_eq!(c.color[i], g.color[i], "surfel {i} colour");
    }
}

/// A pyramid level of the frame comes down equal on both backends (the preprocess parity
/// bounds), and a prediction written into a level reads back unchanged.
fn loop_copies_round_trip(ctx: GpuContext) {
    let params = SlamParams::default();
    let f = load_frame(&super::root(), 1);
    let mut c = slam(CpuBackend::new(), params.clone());
    let mut g = slam(super::gpu_backend(ctx), params);
    c.process(1, &f.depth, &f.rgba, None).unwrap();
    g.process(1, &f.depth, &f.rgba, None).unwrap();
    let level = 1;
    let (cv, cn) = c.backend.frame_level(level).unwrap();
    let (gv, gn) = g.backend.frame_level(level).unwrap();
    super::check_vec4_map("frame level vertex", &cv, &gv, VERTEX_TOL_M);
    super::check_vec4_map(
        "frame level normal_depth",
        &cn,
        &gn,
        NORMAL_TOL.max(VERTEX_TOL_M),
    );
    // A prediction needs the level's maps to exist: predict once (the second frame does).
    c.process(2, &f.depth, &f.rgba, None).unwrap();
    g.process(2, &f.depth, &f.rgba, None).unwrap();
    let shifted: Vec<[f32; 4]> = cv.iter().map(|v| [v[0] + 0.5, v[1], v[2], v[3]]).collect();
    for b in [&mut c.backend as &mut dyn TestBackend, &mut g.backend] {
        b.set(level, &shifted, &cn);
        let (pv, pn) = b.get(level);
        assert_eq!(pv, shifted, "prediction vertex read back");
        assert_eq!(pn, cn, "prediction normal read back");
    }
}

/// The two backends as one type for the round trip.
trait TestBackend {
    fn set(&mut self, level: usize, v: &[[f32; 4]], n: &[[f32; 4]]);
    fn get(&mut self, level: usize) -> (Vec<[f32; 4]>, Vec<[f32; 4]>);
}

impl<B: Backend + Inspect> TestBackend for B {
    fn set(&mut self, level: usize, v: &[[f32; 4]], n: &[[f32; 4]]) {
        self.set_prediction(level, &(v.to_vec(), n.to_vec()))
            .unwrap();
    }
    fn get(&mut self, level: usize) -> (Vec<[f32; 4]>, Vec<[f32; 4]>) {
        self.download_prediction(level).unwrap()
    }
}

pub fn tests() -> Vec<Test> {
    vec![
        gpu("deform_surfels_matches_twin", deform_matches_twin),
        gpu("loop_copies_round_trip", loop_copies_round_trip),
    ]
}
