//! What the frame loop says about each frame: how its pose was obtained
//! ([`TrackStatus`]), the relocalisation attempts made for it, and the whole
//! [`FrameReport`] that `frames.json`, the console and the tests read. Data only: the
//! tracker (`slam::tracker`), the recovery (`slam::recovery`) and the loop closer
//! (`slam::loop_closer`) fill it in, `slam::pipeline` puts it together.

use glam::DMat4;

use crate::slam::health::TrackingHealth;
use crate::slam::keyframes::Match;
use crate::slam::loops::LoopRecord;
use crate::slam::solve::IcpIteration;

/// How a frame's pose was obtained.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub enum TrackStatus {
    /// The first frame (ground truth or identity) or a ground-truth pose.
    Given,
    /// ICP converged (increment below threshold) at the finest level within its budget.
    Converged,
    /// ICP used all of the finest level's iterations; the last pose is kept.
    MaxIterations,
    /// ICP refused a later system at the finest level; the last good pose is kept. (A
    /// refused system at a coarser level ends that level only; the finer ones go on.)
    Stopped(String),
    /// Tracking from the last pose failed, and ICP from the pose of the keyframe that was
    /// frame `keyframe_frame` passed the health test: the frame is fused there.
    Relocalised { keyframe_frame: u32 },
    /// Tracking lost: ICP refused the first system, or its result failed the health test,
    /// and no relocalisation passed. The frame is not fused and has no tracked pose.
    Lost(String),
    /// No valid depth pixel: skipped, not fused, no tracked pose.
    EmptyDepth,
}

impl TrackStatus {
    /// Whether the frame has a pose the run stands by (written to `trajectory.tum`, fused).
    pub fn is_tracked(&self) -> bool {
        !matches!(self, TrackStatus::Lost(_) | TrackStatus::EmptyDepth)
    }
}

/// One relocalisation attempt: ICP against the map from a keyframe's pose, or from the pose
/// that matching the frame's features with a keyframe's gave.
#[derive(Debug, Clone, serde::Serialize)]
pub struct RelocalisationAttempt {
    /// The keyframe and how alike its fern code is.
    pub keyframe: Match,
    /// RANSAC inliers of the feature matches the start pose came from; `None` when ICP
    /// started from the keyframe's own pose.
    pub feature_inliers: Option<usize>,
    /// The result's health (`None` when ICP refused its first system).
    pub health: Option<TrackingHealth>,
    /// `None` when accepted, else why not.
    pub rejected: Option<String>,
}

/// The second attempt from the last tracked pose, with filter 2's angle gate at level 0
/// widened to `icp.full_res_normal_deg` (at full resolution only: `Slam::process`).
#[derive(Debug, Clone, serde::Serialize)]
pub struct WideGateAttempt {
    /// Level 0's angle gate, degrees.
    pub normal_deg: f32,
    /// Its ICP iterations, all levels.
    pub iterations: usize,
    /// Its health (`None` when ICP refused its first system).
    pub health: Option<TrackingHealth>,
    /// `None` when accepted, else why not.
    pub rejected: Option<String>,
}

/// What the pipeline did with one frame.
#[derive(Debug, Clone, serde::Serialize)]
pub struct FrameReport {
    /// Pose of the camera, camera to world: the tracked pose, or for a frame without one
    /// (lost, empty depth) the last tracked pose, which is not written as this frame's.
    #[serde(skip)]
    pub t_cam_to_world: DMat4,
    pub status: TrackStatus,
    /// ICP iterations of the tracking attempt from the last tracked pose.
    pub iterations: Vec<IcpIteration>,
    /// The health of that attempt (`None` for a given pose or without the test).
    pub health: Option<TrackingHealth>,
    /// The second attempt from the last tracked pose with the wider full-resolution angle
    /// gate, made when the first failed (`None` when none was made).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub wide_gate: Option<WideGateAttempt>,
    /// Relocalisation attempts after those failed, in order (empty when none were made).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub relocalisation: Vec<RelocalisationAttempt>,
    /// Whether the frame became a relocalisation keyframe.
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub keyframe: bool,
    /// Loop candidates verified at this frame, accepted or rejected (empty when none).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub loops: Vec<LoopRecord>,
    /// Surfels in the map this frame was tracked against: before its own fusion, after the
    /// last fused frame's (and its removal of unstable surfels). Not the count after this
    /// frame: on a GPU that is known only once the fusion has run, and waiting for it would
    /// cost every frame a round trip (issue 48); the next frame's report has it, and the
    /// final map's size is that of the map written.
    pub surfels_before: usize,
}
