//! The loop-closure pose graph, solved on the host in f64: nodes are camera poses (camera
//! to world) of some tracked frames, edges are measured relative poses between two nodes
//! (odometry between consecutive nodes, as tracking measured it; a verified loop between
//! a frame and an old keyframe). Gauss-Newton on SE(3) with left perturbations, the first
//! node held fixed.
//!
//! An edge `(i, j, z)` says `T_i⁻¹ T_j = z`; its residual is `log(z⁻¹ T_i⁻¹ T_j)`, a twist
//! (radians, metres: a degree weighs as 17 mm), times the edge's weight. Jacobians are
//! central differences (12 residual evaluations per edge and iteration: the graph is small,
//! and a hand-derived SE(3) Jacobian is a bug farm). The normal equations are dense, 6 x
//! (nodes - 1) square, solved by Cholesky (nalgebra): the graph has one node per
//! [`crate::slam::params::LoopSettings::node_stride`] tracked frames and per keyframe, a
//! few hundred on the sequences here (a 600 x 600 solve, milliseconds); see
//! `docs/loop-closure.md` for what a much longer sequence costs.
//!
//! After [`PoseGraph::optimise`], each node's correction is its new pose times its old
//! pose's inverse, a world-frame transform; frames between two nodes take the two
//! corrections blended ([`interpolate`]), and so do surfels (`deform_surfels`).

use glam::DMat4;
use nalgebra::{DMatrix, DVector};

use crate::geometry::se3;

/// Gauss-Newton stops when the largest update entry (radians or metres) is below this.
pub const CONVERGED_STEP: f64 = 1e-9;
/// Most Gauss-Newton iterations per optimisation (a loop's error is a few centimetres to
/// decimetres: it converges in 2-4).
pub const MAX_ITERATIONS: usize = 20;
/// Central-difference step of the numeric Jacobians (radians, metres): small against the
/// residuals' curvature, large against f64 rounding of poses near 1-10 m.
const JACOBIAN_STEP: f64 = 1e-6;
/// Levenberg damping added to the diagonal: keeps the solve defined when a node is tied
/// by a single edge, and changes the solution far below a micrometre.
const DAMPING: f64 = 1e-9;

/// One pose of the graph.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Node {
    /// Sequence position of the frame.
    pub frame: u32,
    /// The current estimate, camera to world.
    pub t_cam_to_world: DMat4,
}

/// What an edge measures.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub enum EdgeKind {
    /// Tracking's relative motion between consecutive nodes.
    Odometry,
    /// A verified loop: the frame registered against an old keyframe.
    Loop,
}

/// A measured relative pose `z = T_from⁻¹ T_to` (camera to world poses).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Edge {
    pub from: usize,
    pub to: usize,
    pub z: DMat4,
    /// Multiplies the residual (the square root of an isotropic information).
    pub weight: f64,
    pub kind: EdgeKind,
}

/// How an optimisation went.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Optimised {
    pub iterations: usize,
    /// Weighted squared residuals summed over edges, before and after.
    pub cost_before: f64,
    pub cost_after: f64,
}

/// Nodes in frame order, and edges.
#[derive(Debug, Clone, Default)]
pub struct PoseGraph {
    nodes: Vec<Node>,
    edges: Vec<Edge>,
}

impl PoseGraph {
    /// The nodes, in frame order.
    pub fn nodes(&self) -> &[Node] {
        &self.nodes
    }

    /// The edges.
    pub fn edges(&self) -> &[Edge] {
        &self.edges
    }

    /// The node of `frame`, if it is one.
    pub fn node_of(&self, frame: u32) -> Option<usize> {
        self.nodes.binary_search_by_key(&frame, |n| n.frame).ok()
    }

    /// Adds `frame` (after every node so far) at `t_cam_to_world`, tied to the last node by
    /// an odometry edge of `weight` measuring their relative pose as estimated now (the
    /// frame was tracked against a map consistent with the last node's estimate). Returns
    /// its index; a frame already a node is not added twice.
    pub fn add_node(&mut self, frame: u32, t_cam_to_world: DMat4, weight: f64) -> usize {
        if let Some(last) = self.nodes.last() {
            if last.frame == frame {
                return self.nodes.len() - 1;
            }
            assert!(
                last.frame < frame,
                "pose-graph nodes are added in frame order"
            );
            let z = se3::inverse_rigid(&last.t_cam_to_world) * t_cam_to_world;
            let from = self.nodes.len() - 1;
            self.edges.push(Edge {
                from,
                to: from + 1,
                z,
                weight,
                kind: EdgeKind::Odometry,
            });
        }
        self.nodes.push(Node {
            frame,
            t_cam_to_world,
        });
        self.nodes.len() - 1
    }

    /// Adds a loop edge: `T_from⁻¹ T_to` was measured as `z`.
    pub fn add_loop(&mut self, from: usize, to: usize, z: DMat4, weight: f64) {
        self.edges.push(Edge {
            from,
            to,
            z,
            weight,
            kind: EdgeKind::Loop,
        });
    }

    /// An edge's weighted residual at `poses`.
    fn residual(e: &Edge, poses: &[DMat4]) -> [f64; 6] {
        Self::residual_of(e, &poses[e.from], &poses[e.to])
    }

    /// An edge's weighted residual with its ends at `t_from` and `t_to`.
    fn residual_of(e: &Edge, t_from: &DMat4, t_to: &DMat4) -> [f64; 6] {
        let r = se3::log(&(se3::inverse_rigid(&e.z) * se3::inverse_rigid(t_from) * *t_to));
        r.map(|v| v * e.weight)
    }

    fn cost(&self, poses: &[DMat4]) -> f64 {
        self.edges
            .iter()
            .map(|e| Self::residual(e, poses).iter().map(|v| v * v).sum::<f64>())
            .sum()
    }

    /// Gauss-Newton over every node but the first; the nodes take the optimised poses.
    /// Returns the corrections, one per node: new pose times old pose inverse.
    pub fn optimise(&mut self) -> (Vec<DMat4>, Optimised) {
        let old: Vec<DMat4> = self.nodes.iter().map(|n| n.t_cam_to_world).collect();
        let mut poses = old.clone();
        let n = poses.len();
        let cost_before = self.cost(&poses);
        let mut iterations = 0;
        if n >= 2 {
            let dim = 6 * (n - 1);
            for _ in 0..MAX_ITERATIONS {
                iterations += 1;
                let mut h = DMatrix::<f64>::zeros(dim, dim);
                let mut g = DVector::<f64>::zeros(dim);
                for e in &self.edges {
                    let r0 = Self::residual(e, &poses);
                    // Jacobian blocks for the two ends (none for the fixed node 0).
                    let mut blocks: Vec<(usize, [[f64; 6]; 6])> = Vec::with_capacity(2);
                    for node in [e.from, e.to] {
                        if node == 0 || blocks.iter().any(|(b, _)| *b == node) {
                            continue;
                        }
                        let mut jac = [[0.0; 6]; 6]; // jac[k] = d r / d delta_k
                        for (k, col) in jac.iter_mut().enumerate() {
                            let mut d = [0.0; 6];
                            d[k] = JACOBIAN_STEP;
                            let moved = |d: &[f64; 6]| {
                                let p = se3::exp(d) * poses[node];
                                let from = if e.from == node { p } else { poses[e.from] };
                                let to = if e.to == node { p } else { poses[e.to] };
                                Self::residual_of(e, &from, &to)
                            };
                            let rp = moved(&d);
                            d[k] = -JACOBIAN_STEP;
                            let rm = moved(&d);
                            for i in 0..6 {
                                col[i] = (rp[i] - rm[i]) / (2.0 * JACOBIAN_STEP);
                            }
                        }
                        blocks.push((node, jac));
                    }
                    for (a, ja) in &blocks {
                        let oa = 6 * (a - 1);
                        for ka in 0..6 {
                            g[oa + ka] += (0..6).map(|i| ja[ka][i] * r0[i]).sum::<f64>();
                            for (b, jb) in &blocks {
                                let ob = 6 * (b - 1);
                                for kb in 0..6 {
                                    h[(oa + ka, ob + kb)] +=
                                        (0..6).map(|i| ja[ka][i] * jb[kb][i]).sum::<f64>();
                                }
                            }
                        }
                    }
                }
                for i in 0..dim {
                    h[(i, i)] += DAMPING;
                }
                let Some(chol) = h.cholesky() else {
                    break;
                };
                let step = chol.solve(&(-g));
                for (node, pose) in poses.iter_mut().enumerate().skip(1) {
                    let o = 6 * (node - 1);
                    let d = [0, 1, 2, 3, 4, 5].map(|k| step[o + k]);
                    *pose = se3::exp(&d) * *pose;
                }
                if step.amax() < CONVERGED_STEP {
                    break;
                }
            }
        }
        let cost_after = self.cost(&poses);
        let corrections = poses
            .iter()
            .zip(&old)
            .map(|(new, old)| *new * se3::inverse_rigid(old))
            .collect();
        for (node, pose) in self.nodes.iter_mut().zip(poses) {
            node.t_cam_to_world = pose;
        }
        (
            corrections,
            Optimised {
                iterations,
                cost_before,
                cost_after,
            },
        )
    }
}

/// The correction of `frame` from the corrections of the nodes (`frames` sorted, one
/// correction each): the two nodes bracketing it blended in SE(3) by frame,
/// `C_a exp(w log(C_a⁻¹ C_b))`; before the first node or after the last, that node's.
/// The same bracketing as `deform_surfels` (which blends the corrected points linearly:
/// the two differ by second-order terms of the corrections' difference).
pub fn interpolate(frames: &[u32], corrections: &[DMat4], frame: u32) -> DMat4 {
    assert_eq!(frames.len(), corrections.len());
    let k = frames.partition_point(|&f| f <= frame);
    if frames.is_empty() {
        return DMat4::IDENTITY;
    }
    if k == 0 {
        return corrections[0];
    }
    if k == frames.len() {
        return corrections[k - 1];
    }
    let (a, b) = (k - 1, k);
    let w = (frame - frames[a]) as f64 / (frames[b] - frames[a]) as f64;
    let delta = se3::log(&(se3::inverse_rigid(&corrections[a]) * corrections[b]));
    corrections[a] * se3::exp(&delta.map(|v| v * w))
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    fn at(x: f64, y: f64, yaw_deg: f64) -> DMat4 {
        se3::exp(&[0.0, 0.0, yaw_deg.to_radians(), 0.0, 0.0, 0.0])
            * DMat4::from_translation(DVec3::new(x, y, 0.0))
    }

    /// A square walked with drift: odometry says each side turns 90 degrees and 1 m, but
    /// the estimates (what tracking gave) drift by 2 degrees and 2 cm per side; a loop edge
    /// from the last node back to the first says they coincide. The optimised poses must
    /// be far closer to the true square than the drifted ones.
    #[test]
    fn a_loop_pulls_a_drifting_square_back() {
        let truth: Vec<DMat4> = (0..=4)
            .map(|i| {
                let yaw = 90.0 * i as f64;
                let c = [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0), (0.0, 0.0)][i];
                DMat4::from_translation(DVec3::new(c.0, c.1, 0.0))
                    * se3::exp(&[0.0, 0.0, yaw.to_radians(), 0.0, 0.0, 0.0])
            })
            .collect();
        let mut drifted = vec![truth[0]];
        for i in 1..=4 {
            let step = se3::inverse_rigid(&truth[i - 1]) * truth[i] * at(0.02, 0.0, 2.0);
            drifted.push(drifted[i - 1] * step);
        }
        let mut g = PoseGraph::default();
        for (i, p) in drifted.iter().enumerate() {
            g.add_node(10 * i as u32, *p, 1.0);
        }
        g.add_loop(4, 0, DMat4::IDENTITY, 1.0);
        let err = |poses: &[DMat4]| {
            poses
                .iter()
                .zip(&truth)
                .map(|(p, t)| se3::translation_norm(&(se3::inverse_rigid(t) * *p)))
                .fold(0.0, f64::max)
        };
        let before = err(&drifted);
        let (corrections, report) = g.optimise();
        let after: Vec<DMat4> = g.nodes().iter().map(|n| n.t_cam_to_world).collect();
        // The odometry carries the drift, so the loop's error is spread over the cycle's
        // five edges: at best a fifth of the cost remains (less once rotation and
        // translation trade off).
        assert!(report.cost_after < 0.25 * report.cost_before, "{report:?}");
        assert!(
            err(&after) < 0.5 * before,
            "worst error {:.4} m after, {before:.4} m before",
            err(&after)
        );
        // The corrections take the old poses to the new ones.
        for (c, (old, new)) in corrections.iter().zip(drifted.iter().zip(&after)) {
            assert!((*c * *old).abs_diff_eq(*new, 1e-12));
        }
        // Node 0 is fixed.
        assert!(corrections[0].abs_diff_eq(DMat4::IDENTITY, 1e-12));
    }

    #[test]
    fn interpolation_brackets_by_frame() {
        let c = [
            DMat4::IDENTITY,
            DMat4::from_translation(DVec3::new(1.0, 0.0, 0.0)),
        ];
        let f = [10, 20];
        assert_eq!(interpolate(&f, &c, 5), c[0]);
        assert_eq!(interpolate(&f, &c, 25), c[1]);
        let mid = interpolate(&f, &c, 15);
        assert!((mid.w_axis.x - 0.5).abs() < 1e-12);
    }
}
