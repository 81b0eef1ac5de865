//! Loop closure: finding a return to a place seen long ago, verifying it, and bending the
//! trajectory and the map so the two visits agree (after ElasticFusion, Whelan et al.
//! 2015/2016: fern loops and a deformation of the map; here the deformation follows a
//! pose graph of frames, see `slam::pose_graph`).
//!
//! Per tracked frame ([`LoopClosure::record`]): its pose joins the trajectory; every
//! [`LoopSettings::node_stride`] tracked frames, and at every keyframe, a pose-graph node
//! (tied to the previous one by tracking's relative motion). A keyframe also keeps a
//! snapshot: its camera-frame vertex and normal maps at one pyramid level
//! ([`LoopClosure::level`]: the second-coarsest, 160 x 120 at the default 320 x 240 with
//! the robust three-level schedule: 614 KB per keyframe, so at most 1.2 GB at the
//! keyframe database's limit of 2,000; 40 keyframes, 25 MB, on 7-Scenes frames 0..299).
//!
//! Every [`LoopSettings::search_every_frames`] frames ([`LoopClosure::candidates`]): two
//! kinds of candidate keyframe, each at least [`LoopSettings::min_gap_frames`] old:
//! - global: the keyframe most alike in the fern database (appearance), at least
//!   [`LoopSettings::min_similarity`] alike;
//! - local: the keyframe whose pose, as now estimated, is nearest the frame's, within
//!   [`LoopSettings::local_radius_m`] / [`LoopSettings::local_angle_deg`]. This stands in
//!   for ElasticFusion's active/inactive split: map seen long ago that comes back into
//!   view is registered against directly, here through the keyframe that saw it.
//!
//! Verification (`slam::loop_closer`): the keyframe's snapshot, placed in the world
//! at the keyframe's pose, replaces the prediction at the snapshot's level, and ICP from
//! the frame's tracked pose registers the frame against it
//! ([`LoopSettings::verify_iterations`]). [`LoopClosure::judge`] accepts it when ICP did
//! not refuse a system, enough of the snapshot's pixels are inliers, the residual is small
//! and the correction is within ICP's basin. A rejected candidate is recorded with the
//! reason. An accepted loop within noise moves nothing. One above noise, once confirmed,
//! is optimised on a trial copy of the graph and bends only when the bend passes
//! [`BendCheck`](crate::slam::loops_check::BendCheck): its own disagreement mostly gone,
//! no other loop edge's raised (else it is recorded as rejected and nothing moves); then
//! every tracked pose, every keyframe and every surfel (`deform_surfels`) moves with the
//! corrections of the nodes nearest it in time.

use std::collections::HashMap;

use glam::DMat4;

use crate::geometry::se3::{self, pose_change};
use crate::layout::DeformNode;
use crate::slam::keyframes::KeyframeDatabase;
pub use crate::slam::loops_check::BendCheck;
use crate::slam::loops_check::{add_loop_edge, disagreements};
use crate::slam::params::LoopSettings;
use crate::slam::pose_graph::{self, Optimised, PoseGraph};
use crate::slam::solve::IcpIteration;

/// A keyframe's maps at the loop level: camera-frame vertices (`w = 1` valid) and
/// `normal_depth` (camera-frame normal, depth in `w`, zero where invalid).
#[derive(Debug, Clone)]
pub struct Snapshot {
    pub vertex: Vec<[f32; 4]>,
    pub normal_depth: Vec<[f32; 4]>,
    /// Pixels with a valid vertex and normal.
    pub valid: usize,
}

/// What an accepted loop did.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum LoopAction {
    /// The correction is within noise: the trajectory already agrees; nothing moves.
    Agrees,
    /// Above noise, first seen: waits for a second verification to confirm it.
    AwaitingConfirmation,
    /// Confirmed: the graph was optimised and the trajectory and the map bent.
    Bent,
}

/// Why a keyframe is a loop candidate.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum LoopKind {
    /// Its fern code is alike (appearance).
    Global,
    /// Its pose is near the frame's (geometry).
    Local,
}

/// A candidate: the keyframe's frame and why.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Candidate {
    pub keyframe_frame: u32,
    pub kind: LoopKind,
    /// Fern similarity (global candidates).
    pub similarity: Option<f64>,
}

/// One verified candidate, accepted or not (`metrics.json`'s `loops`).
#[derive(Debug, Clone, serde::Serialize)]
pub struct LoopRecord {
    /// The frame that returned.
    pub frame: u32,
    /// The keyframe it returned to.
    pub keyframe_frame: u32,
    pub kind: LoopKind,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub similarity: Option<f64>,
    /// The verification's last ICP iteration.
    pub inliers: u64,
    pub inlier_fraction: f64,
    pub rms_m: f64,
    /// How far the verified pose is from the tracked one, metres and degrees.
    pub correction_m: f64,
    pub correction_deg: f64,
    /// `None` when accepted, else why not.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rejected: Option<String>,
    /// What an accepted loop did (`None` when rejected).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub action: Option<LoopAction>,
    /// The pose-graph optimisation the loop started (loops that bent the map).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub optimised: Option<Optimised>,
    /// The check of a confirmed loop's bend on a trial optimisation (bent or rejected).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub check: Option<BendCheck>,
}

/// One tracked frame's pose as now estimated, after every closure so far
/// (`trajectory.tum`; the pose as tracked is the frame's report's).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackedPose {
    pub frame: u32,
    /// Camera to world.
    pub estimate: DMat4,
}

/// Loop closure's state: snapshots, the pose graph, the trajectory, the loops found.
#[derive(Debug, Clone)]
pub struct LoopClosure {
    settings: LoopSettings,
    level: usize,
    snapshots: HashMap<u32, Snapshot>,
    graph: PoseGraph,
    poses: Vec<TrackedPose>,
    tracked_since_node: u32,
    /// No search before this frame (searches are spaced, and paused after a closure).
    next_search: u32,
    /// An accepted correction above noise awaiting confirmation: its frame and the
    /// world-frame correction it measured (verified pose times tracked pose inverse).
    pending: Option<(u32, DMat4)>,
    loops: Vec<LoopRecord>,
}

impl LoopClosure {
    /// Loop closure with snapshots at pyramid `level`.
    pub fn new(settings: LoopSettings, level: usize) -> Self {
        LoopClosure {
            settings,
            level,
            snapshots: HashMap::new(),
            graph: PoseGraph::default(),
            poses: Vec::new(),
            tracked_since_node: 0,
            next_search: 0,
            pending: None,
            loops: Vec::new(),
        }
    }

    /// The snapshots' pyramid level.
    pub fn level(&self) -> usize {
        self.level
    }

    /// The settings this loop closure was made with (the run's `loop_closure`).
    pub fn settings(&self) -> &LoopSettings {
        &self.settings
    }

    /// Every tracked frame's pose, in order.
    pub fn poses(&self) -> &[TrackedPose] {
        &self.poses
    }

    /// Every verified candidate, in order.
    pub fn loops(&self) -> &[LoopRecord] {
        &self.loops
    }

    /// The pose of the keyframe of `frame` as now estimated (its graph node's), camera to
    /// world.
    pub fn keyframe_pose(&self, frame: u32) -> DMat4 {
        let node = self
            .graph
            .node_of(frame)
            .expect("every keyframe is a pose-graph node");
        self.graph.nodes()[node].t_cam_to_world
    }

    /// The pose graph (for tests and reports).
    pub fn graph(&self) -> &PoseGraph {
        &self.graph
    }

    /// A tracked frame at `t_cam_to_world`: joins the trajectory, and the graph every
    /// `node_stride` frames and at keyframes (`snapshot` given).
    pub fn record(&mut self, frame: u32, t_cam_to_world: DMat4, snapshot: Option<Snapshot>) {
        self.poses.push(TrackedPose {
            frame,
            estimate: t_cam_to_world,
        });
        let keyframe = snapshot.is_some();
        if let Some(s) = snapshot {
            self.snapshots.insert(frame, s);
        }
        if self.graph.nodes().is_empty()
            || keyframe
            || self.tracked_since_node + 1 >= self.settings.node_stride
        {
            self.graph.add_node(frame, t_cam_to_world, 1.0);
            self.tracked_since_node = 0;
        } else {
            self.tracked_since_node += 1;
        }
    }

    /// Whether `frame` searches for loops (spaced by `search_every_frames`, none during
    /// the cool-down after a closure).
    pub fn searches(&mut self, frame: u32) -> bool {
        if frame < self.next_search {
            return false;
        }
        self.next_search = frame + self.settings.search_every_frames;
        true
    }

    /// The candidates of a frame at `t_cam_to_world` with fern code `codes`: the best
    /// global one, then the best local one when it is another keyframe.
    pub fn candidates(
        &self,
        frame: u32,
        t_cam_to_world: &DMat4,
        codes: &[u32],
        db: &KeyframeDatabase,
    ) -> Vec<Candidate> {
        let s = &self.settings;
        let old_enough = |kf_frame: u32| {
            kf_frame + s.min_gap_frames <= frame && self.snapshots.contains_key(&kf_frame)
        };
        let mut out = Vec::new();
        let global = db
            .nearest(codes, db.len())
            .into_iter()
            .filter(|m| m.similarity >= s.min_similarity && old_enough(m.frame_id))
            .max_by(|a, b| {
                a.similarity
                    .total_cmp(&b.similarity)
                    .then(b.frame_id.cmp(&a.frame_id))
            });
        if let Some(m) = global {
            out.push(Candidate {
                keyframe_frame: m.frame_id,
                kind: LoopKind::Global,
                similarity: Some(m.similarity),
            });
        }
        let t_world_to_cam = se3::inverse_rigid(t_cam_to_world);
        let local = (0..db.len())
            .map(|i| db.keyframe(i))
            .filter(|kf| old_enough(kf.frame_id))
            .map(|kf| {
                (
                    kf.frame_id,
                    pose_change(&kf.t_world_to_cam, &t_world_to_cam),
                )
            })
            .filter(|(_, (m, deg))| *m <= s.local_radius_m && *deg <= s.local_angle_deg)
            .min_by(|a, b| a.1 .0.total_cmp(&b.1 .0));
        if let Some((kf_frame, _)) = local {
            if out.iter().all(|c| c.keyframe_frame != kf_frame) {
                out.push(Candidate {
                    keyframe_frame: kf_frame,
                    kind: LoopKind::Local,
                    similarity: None,
                });
            }
        }
        out
    }

    /// The snapshot of the keyframe of `frame` placed in the world at `t_cam_to_world`
    /// (the keyframe's pose as now estimated): a prediction's vertex and normal maps
    /// (world frame, `w = 1` valid, zero where invalid).
    pub fn prediction(
        &self,
        keyframe_frame: u32,
        t_cam_to_world: &DMat4,
    ) -> (Vec<[f32; 4]>, Vec<[f32; 4]>) {
        let s = &self.snapshots[&keyframe_frame];
        let t = t_cam_to_world.as_mat4();
        s.vertex
            .iter()
            .zip(&s.normal_depth)
            .map(|(v, nd)| {
                if v[3] > 0.0 && nd[3] > 0.0 {
                    let p = t.transform_point3(glam::Vec3::new(v[0], v[1], v[2]));
                    let n = t.transform_vector3(glam::Vec3::new(nd[0], nd[1], nd[2]));
                    ([p.x, p.y, p.z, 1.0], [n.x, n.y, n.z, 1.0])
                } else {
                    ([0.0; 4], [0.0; 4])
                }
            })
            .unzip()
    }

    /// The verification's verdict on `candidate`: ICP's `iterations` against the snapshot
    /// (`refused`: ICP refused a system) moved the frame from `t_tracked` to `t_loop`
    /// (camera to world). Records it; `Ok` when the loop is accepted.
    pub fn judge(
        &mut self,
        frame: u32,
        candidate: &Candidate,
        iterations: &[IcpIteration],
        refused: Option<String>,
        t_tracked: &DMat4,
        t_loop: &DMat4,
    ) -> Result<(), String> {
        let s = self.settings;
        let valid = self.snapshots[&candidate.keyframe_frame].valid.max(1);
        let last = iterations.last();
        let inliers = last.map_or(0, |it| it.inliers);
        let rms_m = last.map_or(f64::INFINITY, |it| it.mean_sq_residual.max(0.0).sqrt());
        let inlier_fraction = inliers as f64 / valid as f64;
        let (correction_m, correction_deg) = camera_change(t_tracked, t_loop);
        let verdict = if let Some(why) = refused {
            Err(format!("ICP refused a system: {why}"))
        } else if inlier_fraction < s.min_inlier_fraction {
            Err(format!(
                "inliers {:.0} % of the keyframe's pixels (at least {:.0} %)",
                100.0 * inlier_fraction,
                100.0 * s.min_inlier_fraction
            ))
        } else if rms_m > s.max_rms_m {
            Err(format!(
                "RMS residual {:.1} mm (at most {:.1} mm)",
                1e3 * rms_m,
                1e3 * s.max_rms_m
            ))
        } else if correction_m > s.max_correction_m || correction_deg > s.max_correction_deg {
            Err(format!(
                "correction {:.0} mm / {correction_deg:.1} deg (at most {:.0} mm / {} deg)",
                1e3 * correction_m,
                1e3 * s.max_correction_m,
                s.max_correction_deg
            ))
        } else {
            Ok(())
        };
        self.loops.push(LoopRecord {
            frame,
            keyframe_frame: candidate.keyframe_frame,
            kind: candidate.kind,
            similarity: candidate.similarity,
            inliers,
            inlier_fraction,
            rms_m,
            correction_m,
            correction_deg,
            rejected: verdict.clone().err(),
            action: None,
            optimised: None,
            check: None,
        });
        verdict
    }

    /// After an accepted loop of `frame` to the keyframe of `keyframe_frame`, which put
    /// the frame at `t_loop` (camera to world). Within noise nothing moves. Above noise and
    /// confirmed,
    /// the graph with the loop's edge is optimised on trial and kept only when the bend
    /// passes [`BendCheck`] (else the loop is recorded as rejected); then every tracked
    /// pose and the keyframe database move. Returns the deformation's node table for
    /// `deform_surfels` (`None` when nothing moves) and the frame's new pose. Pauses the
    /// search for the cool-down after a loop that agreed or bent.
    pub fn close(
        &mut self,
        frame: u32,
        keyframe_frame: u32,
        t_loop: &DMat4,
        db: &mut KeyframeDatabase,
    ) -> (Option<Vec<DeformNode>>, DMat4) {
        let s = self.settings;
        let current = self.poses.last().expect("the frame was recorded").estimate;
        let correction = *t_loop * se3::inverse_rigid(&current);
        let record = self.loops.last_mut().expect("judge() recorded the loop");
        let small = record.correction_m < s.min_correction_m
            && record.correction_deg < s.min_correction_deg;
        if small {
            record.action = Some(LoopAction::Agrees);
            self.pending = None;
            self.next_search = frame + s.cooldown_frames;
            return (None, current);
        }
        let window = s.confirm_within_searches * s.search_every_frames;
        // Where the pending correction puts this frame against where this loop does.
        let confirmed = self.pending.is_some_and(|(f, c)| {
            let (m, deg) = camera_change(&(c * current), t_loop);
            frame <= f + window && m <= s.confirm_agreement_m && deg <= s.confirm_agreement_deg
        });
        if !confirmed {
            record.action = Some(LoopAction::AwaitingConfirmation);
            self.pending = Some((frame, correction));
            return (None, current);
        }
        self.pending = None;
        let mut trial = self.graph.clone();
        let edge = add_loop_edge(
            &mut trial,
            frame,
            keyframe_frame,
            &current,
            t_loop,
            s.loop_weight,
        );
        let before = disagreements(&trial);
        let (corrections, optimised) = trial.optimise();
        let check = BendCheck::of(&trial, edge, &before, &disagreements(&trial));
        record.check = Some(check);
        if let Err(why) = check.verdict(&s) {
            record.rejected = Some(why);
            return (None, current);
        }
        record.action = Some(LoopAction::Bent);
        record.optimised = Some(optimised);
        self.next_search = frame + s.cooldown_frames;
        self.graph = trial;
        self.tracked_since_node = 0;
        let frames: Vec<u32> = self.graph.nodes().iter().map(|n| n.frame).collect();
        for p in &mut self.poses {
            p.estimate = pose_graph::interpolate(&frames, &corrections, p.frame) * p.estimate;
        }
        db.correct(|f| pose_graph::interpolate(&frames, &corrections, f));
        let nodes = frames
            .iter()
            .zip(&corrections)
            .map(|(&frame, c)| deform_node(frame, c))
            .collect();
        let new_current = self.poses.last().expect("recorded").estimate;
        (Some(nodes), new_current)
    }
}

/// The change between two camera-to-world poses as the camera sees it: how far its
/// centre moved (metres) and how far it turned (degrees), wherever the world's origin is
/// ([`pose_change`] of the world-to-camera poses). The difference of the camera-to-world
/// poses themselves would add the turn times the camera's distance from the origin: on
/// TUM fr1/rpy, 2.2 m from the motion-capture origin, 20 mm to a 0.5 degree turn.
fn camera_change(a_cam_to_world: &DMat4, b_cam_to_world: &DMat4) -> (f64, f64) {
    pose_change(
        &se3::inverse_rigid(a_cam_to_world),
        &se3::inverse_rigid(b_cam_to_world),
    )
}

/// `deform_surfels`' table entry for the node of `frame` with the world-frame rigid
/// `correction` (f64 to f32: rounding of a few micrometres at room scale).
pub fn deform_node(frame: u32, correction: &DMat4) -> DeformNode {
    let m = correction.as_mat4();
    DeformNode {
        frame,
        _pad0: 0,
        _pad1: 0,
        _pad2: 0,
        rows: [0, 1, 2].map(|r| {
            let row = m.row(r);
            [row.x, row.y, row.z, row.w]
        }),
    }
}

impl Snapshot {
    /// A snapshot from a pyramid level's `vertex` and `normal_depth` maps.
    pub fn new(vertex: Vec<[f32; 4]>, normal_depth: Vec<[f32; 4]>) -> Self {
        let valid = vertex
            .iter()
            .zip(&normal_depth)
            .filter(|(v, n)| v[3] > 0.0 && n[3] > 0.0)
            .count();
        Snapshot {
            vertex,
            normal_depth,
            valid,
        }
    }
}

// The bend check's tests (slam::loops_check) drive a whole LoopClosure, so they live here.
#[cfg(test)]
mod tests;
