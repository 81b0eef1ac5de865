// Point clouds: PLY (both readers), PCD, KITTI .bin and text clouds. The first byte picks
// the reader, the rest is the file.
#![no_main]
use libfuzzer_sys::fuzz_target;

#[path = "common.rs"]
mod common;

fuzz_target!(|data: &[u8]| {
    let Some((&pick, body)) = data.split_first() else {
        return;
    };
    match pick % 5 {
        0 => drop(wgslam::io::read_ply(&common::as_file("c.ply", body))),
        1 => drop(wgslam::scan::read::read_ply_xyz(&common::as_file(
            "c.ply", body,
        ))),
        2 => drop(wgslam::scan::read::read_pcd(&common::as_file(
            "c.pcd", body,
        ))),
        3 => drop(wgslam::scan::read::read_kitti_bin(&common::as_file(
            "c.bin", body,
        ))),
        _ => drop(wgslam::scan::read::read_xyz_text(&common::as_file(
            "c.xyz", body,
        ))),
    }
});
