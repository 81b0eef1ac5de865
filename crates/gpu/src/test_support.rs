//! Opening the GPU for a test (integration tests, examples), with the skip-or-fail rule in
//! one place. Not a test harness: the integration tests' harness (`tests/it/common/harness.rs`)
//! turns a skip into an `ignored` trial with its reason.
//!
//! Without an adapter a GPU test is skipped, unless the environment sets
//! `WGSLAM_REQUIRE_GPU=1` (CI with lavapipe), in which case it fails. An adapter whose
//! device cannot be created always fails: that is a broken driver, not a missing one.

use super::context::GpuContext;
use crate::Error;

/// Environment variable that turns a missing adapter from a skip into a failure.
pub const REQUIRE_GPU_ENV: &str = "WGSLAM_REQUIRE_GPU";

/// True when `WGSLAM_REQUIRE_GPU=1`.
pub fn gpu_required() -> bool {
    std::env::var(REQUIRE_GPU_ENV).is_ok_and(|v| v == "1")
}

/// Why a GPU test cannot have a context.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum NoGpu {
    /// No adapter and [`gpu_required`] is false: report the test as skipped with this
    /// reason (it names the backends tried and the adapters seen).
    Skip(String),
    /// No adapter although [`gpu_required`], or the device could not be created: the test
    /// fails with this message.
    Fail(String),
}

/// Opens a fresh [`GpuContext`] for one test ([`GpuContext::new`], as every backend does),
/// or says whether the test is skipped or failed without one. Prints nothing itself.
pub fn gpu_for_test() -> Result<GpuContext, NoGpu> {
    match GpuContext::new() {
        Ok(ctx) => Ok(ctx),
        Err(Error::NoAdapter(why)) if !gpu_required() => Err(NoGpu::Skip(format!(
            "no GPU adapter ({why}); set {REQUIRE_GPU_ENV}=1 to fail instead"
        ))),
        Err(Error::NoAdapter(why)) => Err(NoGpu::Fail(format!(
            "no GPU adapter ({why}) and {REQUIRE_GPU_ENV}=1"
        ))),
        Err(e) => Err(NoGpu::Fail(format!("cannot open the GPU: {e}"))),
    }
}
