//! The loop closer: what the frame loop does for loop closure after each fused frame
//! ([`close_loops`]); `slam::loops` holds the state and the rules (candidates, verdicts,
//! the pose graph). The frame is recorded (a keyframe with its snapshot); when it searches,
//! each candidate keyframe's snapshot replaces the prediction at the snapshot's pyramid
//! level and ICP from the frame's tracked pose registers the frame against it, most likely
//! candidate first, until one is accepted. A confirmed loop bends the map
//! (`deform_surfels`), the keyframes and the pose tracking goes on from.

use glam::DMat4;

use crate::geometry::se3;
use crate::slam::backend::Backend;
use crate::slam::loops::{LoopClosure, LoopRecord, Snapshot};
use crate::slam::recovery::{Offered, Recovery};
use crate::slam::tracker::{Icp, LevelEnd};
use crate::Result;

/// A frame that was just fused.
pub struct FusedFrame<'a> {
    pub frame_id: u32,
    /// The pose it was fused at, world to camera.
    pub t_world_to_cam: DMat4,
    /// Its fern code and whether it became a keyframe.
    pub offered: &'a Offered,
}

/// What loop closure did at a frame.
pub struct Closed {
    /// The candidates verified, accepted or rejected, in order.
    pub loops: Vec<LoopRecord>,
    /// The frame's pose after a loop bent the trajectory (world to camera): tracking goes
    /// on from it. `None` when nothing moved.
    pub t_world_to_cam: Option<DMat4>,
}

/// Loop closure after `frame` was fused: records its pose (and a keyframe's snapshot from
/// the backend), and when it searches, verifies its candidates by `icp` most likely first
/// until one is accepted; an accepted loop above noise moves the trajectory, `recovery`'s
/// keyframes and the map.
pub fn close_loops<B: Backend>(
    lc: &mut LoopClosure,
    icp: &mut Icp<'_, B>,
    recovery: &mut Recovery,
    frame: FusedFrame<'_>,
) -> Result<Closed> {
    let level = lc.level();
    let snapshot = match frame.offered.keyframe {
        true => {
            let (vertex, normal_depth) = icp.backend.frame_level(level)?;
            Some(Snapshot::new(vertex, normal_depth))
        }
        false => None,
    };
    let t_cam_to_world = se3::inverse_rigid(&frame.t_world_to_cam);
    lc.record(frame.frame_id, t_cam_to_world, snapshot);
    let mut closed = Closed {
        loops: vec![],
        t_world_to_cam: None,
    };
    if !lc.searches(frame.frame_id) {
        return Ok(closed);
    }
    let codes = &frame.offered.codes;
    let candidates = lc.candidates(frame.frame_id, &t_cam_to_world, codes, recovery.keyframes());
    let before = lc.loops().len();
    let iters = lc.settings().verify_iterations;
    for c in candidates {
        let prediction = lc.prediction(c.keyframe_frame, &lc.keyframe_pose(c.keyframe_frame));
        icp.backend.set_prediction(level, &prediction)?;
        let mut t = frame.t_world_to_cam;
        let mut iterations = Vec::new();
        // Geometric only: the snapshot prediction has no intensity.
        let refused = match icp.level(level, (iters, false), &mut t, &mut iterations)? {
            LevelEnd::Refused(why) => Some(why),
            _ => None,
        };
        let t_loop = se3::inverse_rigid(&t);
        let verdict = lc.judge(
            frame.frame_id,
            &c,
            &iterations,
            refused,
            &t_cam_to_world,
            &t_loop,
        );
        if verdict.is_ok() {
            let db = recovery.keyframes_mut();
            let (nodes, t_new) = lc.close(frame.frame_id, c.keyframe_frame, &t_loop, db);
            if let Some(nodes) = nodes {
                icp.backend.deform(&nodes)?;
                closed.t_world_to_cam = Some(se3::inverse_rigid(&t_new));
            }
            break;
        }
    }
    closed.loops = lc.loops()[before..].to_vec();
    Ok(closed)
}
