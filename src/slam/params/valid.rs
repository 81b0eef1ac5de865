//! [`ValidParams`]: [`SlamParams`] that [`SlamParams::validate`] has checked, the only
//! parameters the pipeline's entry points take (`Slam::new`, `Slam::for_sequence`,
//! `tools::run::run`, `tools::compare::compare`, ...). Validation runs once, where the
//! parameters are made (the command line's, a parameter file's, a batch job's, the Python
//! and web APIs'), and a run never checks them again: what it gets cannot be out of range,
//! because nothing but [`SlamParams::validate`] makes a `ValidParams` and nothing changes
//! one but the setters here, each of which keeps it valid.
//!
//! Not a second schema: it reads as the [`SlamParams`] inside (`Deref`), and is recorded
//! (`metrics.json`) as that.
//!
//! Un-validated parameters do not reach a run; this does not compile:
//!
//! ```compile_fail
//! # fn f(backend: wgslam::slam::cpu_backend::CpuBackend, seq: &wgslam::Sequence) {
//! let params = wgslam::SlamParams::profile(wgslam::Profile::Robust);
//! let _ = wgslam::run(backend, seq, 0, 1, params, |_| {});
//! # }
//! ```
//!
//! and this does:
//!
//! ```no_run
//! # fn f(backend: wgslam::slam::cpu_backend::CpuBackend, seq: &wgslam::Sequence) -> wgslam::Result<()> {
//! let params = wgslam::SlamParams::profile(wgslam::Profile::Robust).validate()?;
//! let _ = wgslam::run(backend, seq, 0, 1, params, |_| {});
//! # Ok(()) }
//! ```

use std::ops::Deref;

use super::{PoseSource, Profile, SlamParams};
use crate::Result;

/// [`SlamParams`] whose every value is in range and whose sections agree
/// ([`SlamParams::validate`], the one way to make one). Read it as a `&SlamParams`
/// (`Deref`); change it only through its setters, or take the parameters out
/// ([`ValidParams::into_inner`]) and validate them again.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
#[serde(transparent)]
pub struct ValidParams(SlamParams);

impl SlamParams {
    /// Checks every value's range, and that loop closure has the keyframe database it
    /// searches, and returns the parameters as [`ValidParams`], which a run takes without
    /// checking them again. The error ([`crate::Error::Argument`]) names the key of the
    /// first value out of range in backquotes (`` `icp.dist_m` ``, see
    /// [`SlamParams::with_keys`]; the command line adds the flag that sets it).
    pub fn validate(self) -> Result<ValidParams> {
        #[cfg(test)]
        VALIDATIONS.with(|n| n.set(n.get() + 1));
        self.check()?;
        Ok(ValidParams(self))
    }
}

#[cfg(test)]
thread_local! {
    /// How many times [`SlamParams::validate`] ran on this thread (tests count a run's).
    static VALIDATIONS: std::cell::Cell<usize> = const { std::cell::Cell::new(0) };
}

/// How many times [`SlamParams::validate`] has run on this thread.
#[cfg(test)]
pub(crate) fn validations_on_this_thread() -> usize {
    VALIDATIONS.with(|n| n.get())
}

impl ValidParams {
    /// The values of `profile`, validated (both profiles are valid: the test
    /// `validate::tests::both_profiles_are_valid`).
    pub fn profile(profile: Profile) -> ValidParams {
        SlamParams::profile(profile)
            .validate()
            .expect("a profile's values are valid")
    }

    /// The parameters, to change and validate again.
    pub fn into_inner(self) -> SlamParams {
        self.0
    }

    /// The same parameters with poses from `poses` (any pose source is valid).
    pub fn with_poses(mut self, poses: PoseSource) -> ValidParams {
        self.0.poses = poses;
        self
    }

    /// The same parameters with `input.depth_scale` raw depth units per metre; the value
    /// is checked as [`SlamParams::validate`] checks it (the same function), and the rest
    /// is not checked again.
    pub fn with_depth_scale(mut self, depth_scale: f32) -> Result<ValidParams> {
        super::validate::check_depth_scale(depth_scale)?;
        self.0.input.depth_scale = depth_scale;
        Ok(self)
    }

    /// The same parameters with `input.downsample` `downsample`, checked as
    /// [`SlamParams::validate`] checks it (the same function); the rest is not checked
    /// again.
    pub fn with_downsample(mut self, downsample: u32) -> Result<ValidParams> {
        super::validate::check_downsample(downsample)?;
        self.0.input.downsample = downsample;
        Ok(self)
    }
}

impl Deref for ValidParams {
    type Target = SlamParams;

    fn deref(&self) -> &SlamParams {
        &self.0
    }
}

impl Default for ValidParams {
    /// The robust profile's values ([`SlamParams::default`]).
    fn default() -> Self {
        ValidParams::profile(Profile::Robust)
    }
}
