//! The input resolution of a run that sets none: every pixel where the GPU runs, every
//! second pixel in each direction where the CPU reference runs (docs/full-resolution.md).
//!
//! `input.downsample` is set by the user through `--downsample`, a parameter file's
//! `downsample` or `[input] downsample`, or a batch manifest's `downsample` field. When
//! none sets it, the backends that will run the frames decide, by one rule for every
//! command ([`default_downsample`]): the GPU alone runs the full frames (640x480 for a
//! Kinect; the robust profile's pyramid, gates and iteration budget per level are set for
//! them), and wherever the CPU reference runs, alone or beside the GPU over the same
//! frames (`bench`'s and a batch job's default, `compare`), every backend runs 320x240, a
//! quarter of the reference's work and one resolution for both. A run records where its
//! value came from in `metrics.json` (`downsample_from`) and says it in its summary.

use serde::{Deserialize, Serialize};

use super::ValidParams;
use crate::Result;

/// `input.downsample` of a run on the GPU backend alone when none is set: the full frames.
pub const GPU_DEFAULT_DOWNSAMPLE: u32 = 1;
/// `input.downsample` wherever the CPU reference runs when none is set: every second
/// pixel in each direction (both profiles' own value).
pub const CPU_DEFAULT_DOWNSAMPLE: u32 = 2;

/// Where a run's `input.downsample` came from (`metrics.json`'s `downsample_from`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum DownsampleFrom {
    /// The user set it (a flag, a parameter file, a batch manifest).
    Set,
    /// Unset; the GPU alone runs the frames: [`GPU_DEFAULT_DOWNSAMPLE`].
    GpuDefault,
    /// Unset; the CPU reference runs them, alone or beside the GPU:
    /// [`CPU_DEFAULT_DOWNSAMPLE`].
    CpuDefault,
}

impl DownsampleFrom {
    /// The words a run's summary gives its resolution (`None` where the user set it).
    pub fn describe(self) -> Option<&'static str> {
        match self {
            DownsampleFrom::Set => None,
            DownsampleFrom::GpuDefault => {
                Some("every pixel, the GPU backend's default; --downsample 2 for half")
            }
            DownsampleFrom::CpuDefault => Some(
                "every 2nd pixel, the default where the CPU reference runs; --downsample 1 \
                 for all",
            ),
        }
    }
}

/// The downsampling of frames that `backends` (by name, `cpu` or `gpu`: each backend
/// that runs the same frames) run when the user sets none, and why.
pub fn default_downsample(backends: &[&str]) -> (u32, DownsampleFrom) {
    match !backends.is_empty() && backends.iter().all(|b| *b == "gpu") {
        true => (GPU_DEFAULT_DOWNSAMPLE, DownsampleFrom::GpuDefault),
        false => (CPU_DEFAULT_DOWNSAMPLE, DownsampleFrom::CpuDefault),
    }
}

/// `params` for frames that `backends` run: as they are when `set` (the user set
/// `input.downsample`), else with [`default_downsample`]'s value; and where it came from.
pub fn for_backends(
    params: ValidParams,
    set: bool,
    backends: &[&str],
) -> Result<(ValidParams, DownsampleFrom)> {
    if set {
        return Ok((params, DownsampleFrom::Set));
    }
    let (downsample, from) = default_downsample(backends);
    Ok((params.with_downsample(downsample)?, from))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_gpu_alone_runs_every_pixel_and_the_cpu_anywhere_every_second() {
        assert_eq!(
            default_downsample(&["gpu"]),
            (1, DownsampleFrom::GpuDefault)
        );
        assert_eq!(
            default_downsample(&["cpu"]),
            (2, DownsampleFrom::CpuDefault)
        );
        assert_eq!(
            default_downsample(&["cpu", "gpu"]),
            (2, DownsampleFrom::CpuDefault)
        );
        assert_eq!(default_downsample(&[]), (2, DownsampleFrom::CpuDefault));
    }

    #[test]
    fn a_set_downsample_is_kept_whatever_the_backend() {
        let mut p = ValidParams::default().into_inner();
        p.input.downsample = 4;
        let p = p.validate().unwrap();
        let (kept, from) = for_backends(p.clone(), true, &["gpu"]).unwrap();
        assert_eq!((kept.input.downsample, from), (4, DownsampleFrom::Set));
        let (gpu, from) = for_backends(p, false, &["gpu"]).unwrap();
        assert_eq!(
            (gpu.input.downsample, from),
            (1, DownsampleFrom::GpuDefault)
        );
    }
}
