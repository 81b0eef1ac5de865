//! Shared helpers for the integration tests: running the executable ([`cli`]), the harness that shows a skipped test as
//! ignored with its reason ([`harness`]), naga checks of WGSL ([`wgsl`]), raw bundled
//! frames and ground truth ([`frames`]), the bundled LiDAR pair and nearest-neighbour
//! kernel inputs ([`scans`]), and where the data is. Each test file includes it with `mod common;` and uses what it needs.

#![allow(dead_code)]

pub mod cli;
pub mod frames;
pub mod harness;
pub mod scans;
pub mod wgsl;

use std::path::{Path, PathBuf};

/// The bundled real frames (always present in a clone).
pub fn bundled_icl() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("assets/icl_living_room_kt2")
}

/// The same 24 frames with Kinect-like depth noise (depth only; the colour images are the
/// clean subset's, which are byte-identical).
pub fn bundled_icl_noisy() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("assets/icl_living_room_kt2_noisy")
}

/// The full 210-frame ICL-NUIM sequence inside the shared data directory that
/// [`harness::shared`] tests receive (`../shared/data`).
pub fn shared_icl(data: &Path) -> PathBuf {
    data.join("icl_living_room_kt2")
}

/// The full noisy sequence (frames 0..209) inside the shared data directory.
pub fn shared_icl_noisy(data: &Path) -> PathBuf {
    data.join("icl_living_room_kt2_noisy")
}

/// A fresh empty directory under the system temp dir.
pub fn temp_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("wgslam-test-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).expect("create temp dir");
    d
}
