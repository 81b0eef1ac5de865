//! Bonn RGB-D Dynamic Dataset: exactly the TUM RGB-D layout (`rgb.txt`, `depth.txt`,
//! `groundtruth.txt`, depth at 5000 per metre), recognised by its folder name
//! (`rgbd_bonn_*`, as the dataset's archives unpack) and read with the Bonn sensor's
//! published intrinsics.
//!
//! The ground truth is read as the file gives it (TUM format, camera-to-world); the
//! dataset's own evaluation first moves it from the motion-capture markers to the camera,
//! which a user does before passing `--gt` if they need it.

use std::path::Path;

use crate::geometry::camera::Intrinsics;

/// The Bonn dataset's published intrinsics of its Asus Xtion Pro Live (640x480), as the
/// dataset prints them (more digits than an f32 holds).
#[allow(clippy::excessive_precision)]
pub const INTRINSICS: Intrinsics = Intrinsics {
    width: 640,
    height: 480,
    fx: 542.822841,
    fy: 542.576870,
    cx: 315.593520,
    cy: 237.756098,
};

/// True when `root`'s own name starts with `rgbd_bonn_`.
pub fn is_bonn_name(root: &Path) -> bool {
    let name = std::fs::canonicalize(root)
        .ok()
        .and_then(|p| p.file_name().map(|n| n.to_string_lossy().into_owned()))
        .or_else(|| root.file_name().map(|n| n.to_string_lossy().into_owned()));
    name.is_some_and(|n| n.starts_with("rgbd_bonn_"))
}
