//! The bundled ICL-NUIM frames read with the image crate directly (not through
//! `wgslam::dataset`), for tests that feed kernels and twins raw frames: 640x480 raw depth
//! (u16, 5000 per metre) and packed RGBA, and the ground-truth poses by frame index.

use std::path::Path;

use glam::DMat4;
use wgslam::geometry::se3;
use wgslam::layout::pack_rgba8;

/// One raw frame: depth (`u16`, row-major 640x480) and colour packed by [`pack_rgba8`].
pub struct Frame {
    pub depth: Vec<u16>,
    pub rgba: Vec<u32>,
}

/// Frame `i` of the ICL-NUIM layout in `root` (`depth/{i}.png`, `rgb/{i}.png`); panics
/// naming the file when it cannot be read or is not 640x480.
pub fn load_frame(root: &Path, i: usize) -> Frame {
    let depth = image::open(root.join(format!("depth/{i}.png")))
        .unwrap_or_else(|e| panic!("depth/{i}.png: {e}"))
        .into_luma16();
    let rgb = image::open(root.join(format!("rgb/{i}.png")))
        .unwrap_or_else(|e| panic!("rgb/{i}.png: {e}"))
        .into_rgb8();
    assert_eq!(depth.dimensions(), (640, 480));
    assert_eq!(rgb.dimensions(), (640, 480));
    Frame {
        depth: depth.into_raw(),
        rgba: rgb.pixels().map(|p| pack_rgba8(p.0)).collect(),
    }
}

/// Ground truth camera-to-world by frame index, from `root/livingRoom2.gt.freiburg`
/// (`i tx ty tz qx qy qz qw`); `None` for frames without ground truth (frame 0).
pub fn load_gt(root: &Path) -> Vec<Option<DMat4>> {
    let text = std::fs::read_to_string(root.join("livingRoom2.gt.freiburg")).unwrap();
    let mut gt = Vec::new();
    for line in text.lines().filter(|l| !l.trim().is_empty()) {
        let v: Vec<f64> = line
            .split_whitespace()
            .map(|s| s.parse().unwrap())
            .collect();
        let i = v[0] as usize;
        if gt.len() <= i {
            gt.resize(i + 1, None);
        }
        gt[i] = Some(se3::from_tum([v[1], v[2], v[3]], [v[4], v[5], v[6], v[7]]));
    }
    gt
}

/// Ground truth of frame `i`, if any.
pub fn gt_at(gt: &[Option<DMat4>], i: usize) -> Option<&DMat4> {
    gt.get(i).and_then(|g| g.as_ref())
}
