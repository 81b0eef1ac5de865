// Point clouds: PLY (both readers), PCD, KITTI .bin and text clouds. The first byte picks
// the reader, the rest is the file.
#![no_main]
use libfuzzer_sys::fuzz_target;
use wgslam::scan::read;

#[path = "common.rs"]
mod common;

const READERS: &[common::FileReader] = &[
    ("c.ply", |p| drop(wgslam::io::read_ply(p))),
    ("c.ply", |p| drop(read::read_ply_xyz(p))),
    ("c.pcd", |p| drop(read::read_pcd(p))),
    ("c.bin", |p| drop(read::read_kitti_bin(p))),
    ("c.xyz", |p| drop(read::read_xyz_text(p))),
];

fuzz_target!(|data: &[u8]| common::read_picked(data, READERS));
