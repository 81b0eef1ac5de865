//! The check a confirmed loop's bend must pass before it moves anything
//! ([`BendCheck`], used by `slam::loops`' `LoopClosure::close`): on a trial optimisation
//! of the pose graph with the loop's edge, the bend must take most of the disagreement it
//! was measured from off its edge and must not raise any other loop edge's (bent or
//! loops that bent the map before), so loop closure never trades one place's agreement
//! for another's. Not the verification of a loop (`LoopClosure::judge`).

use glam::DMat4;

use crate::geometry::se3;
use crate::slam::params::LoopSettings;
use crate::slam::pose_graph::{EdgeKind, PoseGraph};

/// What a trial optimisation of the graph with a confirmed loop's edge did to the edges'
/// disagreements (`metrics.json`): the norm of an edge's residual twist, unweighted, in
/// the graph's metric (metres, a radian weighing as a metre). The loop bends the map only
/// when its own disagreement drops to at most `max_left_fraction` of what it was and no
/// other loop edge's grows by more than `other_edge_slack_m` (`LoopClosure::close`).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct BendCheck {
    /// The new loop edge's disagreement before and after the trial optimisation.
    pub loop_before: f64,
    pub loop_after: f64,
    /// The largest growth of another loop edge's disagreement (0 when none grew).
    pub other_loop_growth: f64,
    /// The largest odometry edge's disagreement after (how hard the bend pulls on
    /// tracking's own measurements).
    pub odometry_after_max: f64,
}

impl BendCheck {
    /// The check of `graph`'s edge `new_edge` from the edges' disagreements `before` and
    /// `after` an optimisation (one entry per edge, [`disagreements`]).
    pub(crate) fn of(graph: &PoseGraph, new_edge: usize, before: &[f64], after: &[f64]) -> Self {
        let mut check = BendCheck {
            loop_before: before[new_edge],
            loop_after: after[new_edge],
            other_loop_growth: 0.0,
            odometry_after_max: 0.0,
        };
        for (i, e) in graph.edges().iter().enumerate() {
            match e.kind {
                EdgeKind::Loop if i != new_edge => {
                    check.other_loop_growth = check.other_loop_growth.max(after[i] - before[i]);
                }
                EdgeKind::Loop => {}
                EdgeKind::Odometry => {
                    check.odometry_after_max = check.odometry_after_max.max(after[i]);
                }
            }
        }
        check
    }

    /// `Err(why)` when the bend would not reduce its own disagreement enough or would
    /// raise another loop's.
    pub(crate) fn verdict(&self, s: &LoopSettings) -> Result<(), String> {
        if self.loop_after > s.max_left_fraction * self.loop_before {
            Err(format!(
                "the graph contradicts it: the bend leaves {:.1} of its {:.1} mm (at most {:.0} %)",
                1e3 * self.loop_after,
                1e3 * self.loop_before,
                100.0 * s.max_left_fraction
            ))
        } else if self.other_loop_growth > s.other_edge_slack_m {
            Err(format!(
                "the bend would raise another loop's disagreement by {:.1} mm (at most {:.1})",
                1e3 * self.other_loop_growth,
                1e3 * s.other_edge_slack_m
            ))
        } else {
            Ok(())
        }
    }
}

/// Every edge's disagreement at the graph's current poses: the norm of
/// `log(z⁻¹ T_from⁻¹ T_to)`, unweighted (metres, a radian weighing as a metre).
pub fn disagreements(graph: &PoseGraph) -> Vec<f64> {
    let nodes = graph.nodes();
    graph
        .edges()
        .iter()
        .map(|e| {
            let d = se3::inverse_rigid(&e.z)
                * se3::inverse_rigid(&nodes[e.from].t_cam_to_world)
                * nodes[e.to].t_cam_to_world;
            se3::log(&d).iter().map(|v| v * v).sum::<f64>().sqrt()
        })
        .collect()
}

/// Adds to `graph` a node for `frame` at `current` (camera to world; none when it is
/// one already) and the loop edge from the keyframe of `keyframe_frame` that the
/// verification measured (`t_loop`: the frame's verified pose, camera to world). Returns
/// the edge's index.
pub(crate) fn add_loop_edge(
    graph: &mut PoseGraph,
    frame: u32,
    keyframe_frame: u32,
    current: &DMat4,
    t_loop: &DMat4,
    weight: f64,
) -> usize {
    let to = graph.add_node(frame, *current, 1.0);
    let from = graph
        .node_of(keyframe_frame)
        .expect("every keyframe is a pose-graph node");
    let t_keyframe = graph.nodes()[from].t_cam_to_world;
    let z = se3::inverse_rigid(&t_keyframe) * *t_loop;
    graph.add_loop(from, to, z, weight);
    graph.edges().len() - 1
}
