// Trajectories and matrix files: TUM trajectories, 4x4 matrices, AirSim poses. The first
// byte picks the reader, the rest is the file.
#![no_main]
use libfuzzer_sys::fuzz_target;

#[path = "common.rs"]
mod common;

fuzz_target!(|data: &[u8]| {
    let Some((&pick, body)) = data.split_first() else {
        return;
    };
    match pick % 3 {
        0 => drop(wgslam::io::read_tum(&common::as_file("t.txt", body))),
        1 => drop(wgslam::scan::read::read_matrix4(&common::as_file(
            "m.txt", body,
        ))),
        _ => drop(wgslam::scan::odometry::read_airsim_pose(&common::as_file(
            "p.txt", body,
        ))),
    }
});
