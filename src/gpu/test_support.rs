//! Shared skip/require logic for tests that need a GPU adapter (unit, integration, bench).
//!
//! Without an adapter a GPU test prints `SKIP: ...` and passes, unless the environment sets
//! `WGSLAM_REQUIRE_GPU=1` (CI with lavapipe), in which case it fails. Not a test harness.

use super::context::GpuContext;
use crate::Error;

/// Environment variable that turns a missing adapter from a skip into a failure.
pub const REQUIRE_GPU_ENV: &str = "WGSLAM_REQUIRE_GPU";

/// True when `WGSLAM_REQUIRE_GPU=1`.
pub fn gpu_required() -> bool {
    std::env::var(REQUIRE_GPU_ENV).is_ok_and(|v| v == "1")
}

/// The context for a GPU test named `test`, or `None` after printing why the test is
/// skipped. Panics (failing the test) when no adapter is found and [`gpu_required`], or
/// when an adapter exists but the device cannot be created.
pub fn gpu_or_skip(test: &str) -> Option<GpuContext> {
    match GpuContext::new() {
        Ok(ctx) => Some(ctx),
        Err(Error::NoAdapter(why)) if !gpu_required() => {
            eprintln!(
                "SKIP: {test}: no GPU adapter ({why}); set {REQUIRE_GPU_ENV}=1 to fail instead"
            );
            None
        }
        Err(e) => panic!("{test}: cannot open the GPU: {e}"),
    }
}
