//! Shared helpers for integration tests: where the data is, and skipping with a reason.

#![allow(dead_code)]

use std::path::PathBuf;

/// The bundled real frames (always present in a clone).
pub fn bundled_icl() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("assets/icl_living_room_kt2")
}

/// The full ICL-NUIM sequence in `../shared/data`, or `None` with a printed reason.
pub fn shared_icl() -> Option<PathBuf> {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/data/icl_living_room_kt2");
    if p.join("associations.txt").is_file() {
        Some(p)
    } else {
        eprintln!(
            "SKIP: {} is absent; this test needs the full 210-frame sequence",
            p.display()
        );
        None
    }
}

/// A fresh empty directory under the system temp dir.
pub fn temp_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("wgslam-test-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).expect("create temp dir");
    d
}
