//! What one GPU stream asks of the device per frame, as `wgslam bench` counts it between
//! the frames of its plain pass: submissions, host waits and read-back bytes, beside the
//! ICP iterations that each need one round trip.

use serde::{Deserialize, Serialize};

/// One frame's submissions, waits and read-back in `bench::bench_frames`.
pub(crate) struct FrameCounts {
    pub submissions: u64,
    /// `queue.submit` calls this stream's thread made (its own and other streams'
    /// submissions in one call, `GpuContext::share`).
    pub device_submissions: u64,
    pub waits: u64,
    /// Waits served by another stream's device wait (`GpuContext::share`).
    pub shared_waits: u64,
    pub readback_bytes: u64,
    pub icp_iterations: usize,
    /// Not a keyframe, no relocalisation, no loop-closure check: the frames whose
    /// read-back the budget bounds.
    pub plain: bool,
}

/// Submissions and read-back per frame, as counted between the frames of the plain pass.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct RoundTrips {
    /// Frames that are not keyframes and neither relocalised nor checked a loop.
    pub plain_frames: usize,
    /// ICP iterations (submit-and-wait round trips of `icp_system`) per frame, mean.
    pub icp_iterations_per_frame: f64,
    /// `queue.submit` calls of this stream's thread per frame, every frame, mean: equal to
    /// the submissions alone; fewer, summed over every stream, where streams sharing a
    /// queue combine their submissions.
    #[serde(default)]
    pub device_submissions_per_frame: f64,
    /// Host device waits of this stream's own per frame, every frame, mean.
    #[serde(default)]
    pub waits_per_frame: f64,
    /// Waits per frame served by another stream's device wait on the shared queue (0 with
    /// one stream), every frame, mean.
    #[serde(default)]
    pub shared_waits_per_frame: f64,
    /// Submissions beyond one per ICP iteration on a plain frame: mean and most.
    pub plain_submissions_beyond_icp_mean: f64,
    pub plain_submissions_beyond_icp_max: u64,
    /// Host waits for the device beyond one per ICP iteration (its system's read-back) on a
    /// plain frame: mean and most. 0 when preprocess, predict and fuse wait for nothing.
    pub plain_waits_beyond_icp_mean: f64,
    pub plain_waits_beyond_icp_max: u64,
    /// Bytes read back on a plain frame: mean and most.
    pub plain_readback_bytes_mean: f64,
    pub plain_readback_bytes_max: u64,
}

impl RoundTrips {
    /// The figures of a pass whose frames counted `counts`.
    pub(crate) fn of(counts: &[FrameCounts]) -> RoundTrips {
        let plain: Vec<&FrameCounts> = counts.iter().filter(|c| c.plain).collect();
        // Mean and most of `f` over the plain frames.
        let mean_max = |f: &dyn Fn(&FrameCounts) -> u64| {
            let sum: u64 = plain.iter().map(|c| f(c)).sum();
            let max = plain.iter().map(|c| f(c)).max().unwrap_or(0);
            (sum as f64 / plain.len().max(1) as f64, max)
        };
        let its = |c: &FrameCounts| c.icp_iterations as u64;
        let submissions = mean_max(&|c| c.submissions.saturating_sub(its(c)));
        let waits = mean_max(&|c| c.waits.saturating_sub(its(c)));
        let readback = mean_max(&|c| c.readback_bytes);
        let n = counts.len().max(1) as f64;
        let per_frame =
            |f: &dyn Fn(&FrameCounts) -> u64| counts.iter().map(f).sum::<u64>() as f64 / n;
        RoundTrips {
            plain_frames: plain.len(),
            icp_iterations_per_frame: per_frame(&|c| c.icp_iterations as u64),
            device_submissions_per_frame: per_frame(&|c| c.device_submissions),
            waits_per_frame: per_frame(&|c| c.waits),
            shared_waits_per_frame: per_frame(&|c| c.shared_waits),
            plain_submissions_beyond_icp_mean: submissions.0,
            plain_submissions_beyond_icp_max: submissions.1,
            plain_waits_beyond_icp_mean: waits.0,
            plain_waits_beyond_icp_max: waits.1,
            plain_readback_bytes_mean: readback.0,
            plain_readback_bytes_max: readback.1,
        }
    }
}
