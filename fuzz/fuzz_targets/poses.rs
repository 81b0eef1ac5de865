// Trajectories and matrix files: TUM trajectories, 4x4 matrices, AirSim poses. The first
// byte picks the reader, the rest is the file.
#![no_main]
use libfuzzer_sys::fuzz_target;

#[path = "common.rs"]
mod common;

const READERS: &[common::FileReader] = &[
    ("t.txt", |p| drop(wgslam::io::read_tum(p))),
    ("m.txt", |p| drop(wgslam::scan::read::read_matrix4(p))),
    ("p.txt", |p| drop(wgslam::scan::odometry::read_airsim_pose(p))),
];

fuzz_target!(|data: &[u8]| common::read_picked(data, READERS));
