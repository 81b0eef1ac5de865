// The dataset layouts' lists and calibration files, opened in memory as a folder would be:
// the first byte picks which file of a small ICL-NUIM, TUM, ETH3D or ScanNet folder the
// rest replaces (the images are empty: opening reads lists, not pixels).
#![no_main]
use libfuzzer_sys::fuzz_target;
use std::path::Path;
use wgslam::dataset::{open_in_memory, InMemoryFiles};

const ICL: &[&str] = &["associations.txt", "camera.json"];
const TUM: &[&str] = &["rgb.txt", "depth.txt", "groundtruth.txt", "camera.json"];
const ETH3D: &[&str] = &["associated.txt", "calibration.txt", "groundtruth.txt"];
const SCANNET: &[&str] = &[
    "pose/0.txt",
    "intrinsic/intrinsic_depth.txt",
    "intrinsic/intrinsic_color.txt",
];

fuzz_target!(|data: &[u8]| {
    let Some((&pick, body)) = data.split_first() else {
        return;
    };
    let (files, images): (&[&str], &[&str]) = match pick % 4 {
        0 => (ICL, &["rgb/0.png", "depth/0.png"]),
        1 => (TUM, &["rgb/0.png", "depth/0.png"]),
        2 => (ETH3D, &["rgb/0.png", "depth/0.png"]),
        _ => (SCANNET, &["color/0.jpg", "depth/0.png"]),
    };
    let target = files[(pick as usize / 4) % files.len()];
    let root = Path::new("/wgslam-fuzz/seq");
    let mut held = InMemoryFiles::default();
    for f in files.iter().chain(images) {
        let bytes = if *f == target {
            body.to_vec()
        } else {
            Vec::new()
        };
        held.insert(root.join(f), bytes);
    }
    let _ = open_in_memory(root, held, 0.02);
});
