//! Frame-to-model tracking: ICP coarse to fine from a start pose against the map's
//! prediction ([`Icp`]: the backend's `predict` and `icp_system` steps and the host solve),
//! and the tracking-health test of its result ([`Tracker::attempt`]; `slam::health`).
//!
//! A level stops when the increment is below `icp.min_increment`, within the pose's own
//! noise (`icp.stop_chi2`), or reverses the previous one (`icp.stop_on_reversal`), or at
//! its budget; the reason is recorded on the level's last iteration
//! ([`LevelStop`], `frames.json`). On real depth (7-Scenes, SUN3D, noisy ICL-NUIM) the
//! increments of the finest levels stop shrinking at 10-50 micrometres and 1e-5 rad, the
//! noise of projective association, so before the noise test 50-65 % of the frames ran to
//! the limit (measurements at `params::ROBUST_STOP_CHI2`); the coarsest level sometimes
//! flips between two correspondence sets with equal and opposite steps ([`reverses`]).
//!
//! The [`Tracker`] holds what tracking carries from frame to frame: the last tracked pose,
//! the frames since it, and the health test's running values. It does not decide what
//! happens after a failed attempt (relocalisation: `slam::recovery`; the frame loop:
//! `slam::pipeline`).

use glam::DMat4;

use crate::geometry::se3::Twist;
use crate::layout::{gpu_mat4, IcpParams, ProjectParams};
use crate::slam::backend::{Backend, PyramidLevel};
use crate::slam::health::{HealthMonitor, TrackingHealth};
use crate::slam::params::{SlamParams, Tracking};
use crate::slam::report::TrackStatus;
use crate::slam::solve::{
    increment_size, update_pose, IcpIteration, LevelStop, NormalEquations, PhotometricTerm,
};
use crate::Result;

/// The kernels' parameters one frame's ICP reads, made once per frame from the pipeline's
/// settings and intrinsics (`slam::step_params`): the coarser pyramid levels', and
/// `project_model`'s and, per pyramid level, `icp_reduce`'s at some pose. Each use sets its
/// own pose ([`IcpSteps::project_at`], [`IcpSteps::icp_at`]); nothing else in them depends
/// on it. `project` holds the map's surfel count before this frame's fusion: tracking's.
#[derive(Clone)]
pub struct IcpSteps {
    pub pyramid: Vec<PyramidLevel>,
    pub project: ProjectParams,
    /// One entry per pyramid level, level 0 (the full maps) first.
    pub icp: Vec<IcpParams>,
}

impl IcpSteps {
    /// `project_model`/`predict_model`'s parameters at world-to-camera pose `t`.
    pub fn project_at(&self, t_world_to_cam: &DMat4) -> ProjectParams {
        ProjectParams {
            t_world_to_cam: gpu_mat4(t_world_to_cam),
            ..self.project
        }
    }

    /// The same steps with filter 2's angle gate at level 0 replaced by
    /// `cos_normal_threshold` (the second attempt's wider gate: `Slam::process`).
    pub fn with_level0_gate(&self, cos_normal_threshold: f32) -> IcpSteps {
        let mut steps = self.clone();
        steps.icp[0].cos_normal_threshold = cos_normal_threshold;
        steps
    }

    /// `icp_reduce`'s parameters at pyramid `level` and world-to-camera pose `t`.
    pub fn icp_at(&self, level: usize, t_world_to_cam: &DMat4) -> IcpParams {
        IcpParams {
            t_world_to_cam: gpu_mat4(t_world_to_cam),
            ..self.icp[level]
        }
    }
}

/// ICP over a backend: the backend, the run's settings and this frame's kernel
/// parameters, lent by the pipeline for one part of the frame.
pub struct Icp<'a, B: Backend> {
    pub backend: &'a mut B,
    pub params: &'a SlamParams,
    pub steps: &'a IcpSteps,
}

/// How ICP at one pyramid level ended ([`Icp::level`]).
pub enum LevelEnd {
    /// The increment test passed.
    Converged,
    /// The level's budget of iterations ran out.
    MaxIterations,
    /// A system was refused (why); the last good pose is kept.
    Refused(String),
}

/// One ICP run from a start pose ([`Icp::track`]): where it ended, how, and its iterations.
pub struct Track {
    pub t_world_to_cam: DMat4,
    pub status: TrackStatus,
    pub iterations: Vec<IcpIteration>,
}

impl<B: Backend> Icp<'_, B> {
    /// Frame-to-model ICP from `t_start` (world to camera): predict once (every level) at
    /// it, then iterate coarse to fine, each level starting from the pose the coarser one
    /// reached.
    pub fn track(&mut self, t_start: DMat4) -> Result<Track> {
        self.backend
            .predict(&self.steps.project_at(&t_start), &self.steps.pyramid)?;
        let mut t = t_start;
        let mut iterations = Vec::new();
        let mut status = TrackStatus::MaxIterations;
        let params = self.params;
        let schedule = &params.icp.level_iters;
        for (i, &max_iters) in schedule.iter().enumerate() {
            let level = schedule.len() - 1 - i;
            // RGB-D tracking adds the photometric term at the finest levels.
            let photometric = params.icp.tracking == Tracking::Rgbd
                && params.icp.photometric_levels.contains(&level);
            let budget = (max_iters, photometric);
            status = match self.level(level, budget, &mut t, &mut iterations)? {
                LevelEnd::Converged => TrackStatus::Converged,
                LevelEnd::MaxIterations => TrackStatus::MaxIterations,
                // The very first system: nothing to start from.
                LevelEnd::Refused(why) if iterations.len() == 1 => {
                    return Ok(Track {
                        t_world_to_cam: t_start,
                        status: TrackStatus::Lost(why),
                        iterations,
                    })
                }
                // A later one: keep the last good pose and go on at the next finer level
                // (at the finest, stop there).
                LevelEnd::Refused(why) => TrackStatus::Stopped(why),
            };
        }
        // The finest level's outcome.
        Ok(Track {
            t_world_to_cam: t,
            status,
            iterations,
        })
    }

    /// Up to `max_iters` ICP iterations at pyramid `level` against its prediction, from
    /// `t` (world to camera), which each solved system updates; each iteration is
    /// appended to `iterations`. With `photometric` each iteration adds the photometric
    /// term (`Backend::rgbd_system`). Ends at convergence, at the budget, or at a refused
    /// system (`t` then keeps the last good pose).
    pub fn level(
        &mut self,
        level: usize,
        (max_iters, photometric): (usize, bool),
        t: &mut DMat4,
        iterations: &mut Vec<IcpIteration>,
    ) -> Result<LevelEnd> {
        let icp = &self.params.icp;
        let mut previous: Option<Twist> = None;
        // The noise stop's bar: the photometric iterations' own where set.
        let stop_chi2 = match icp.photometric_stop_chi2 {
            bar if photometric && bar > 0.0 => bar,
            _ => icp.stop_chi2,
        };
        for _ in 0..max_iters {
            let ip = self.steps.icp_at(level, t);
            let (eq, photo) = match photometric {
                false => (self.backend.icp_system(level, &ip)?, None),
                true => {
                    let [geometric, photometric] = self.backend.rgbd_system(level, &ip)?;
                    (geometric, Some(NormalEquations::decode(&photometric)))
                }
            };
            let eq = NormalEquations::decode(&eq);
            let system = match &photo {
                Some(p) => eq.with_photometric(p, icp.photometric_weight),
                None => eq,
            };
            let solved = system.solve_guarded(icp.degenerate_eigen_ratio);
            let mut it = IcpIteration {
                level,
                inliers: eq.inliers,
                mean_sq_residual: eq.mean_sq_residual(),
                eigen_ratio: None,
                held_directions: 0,
                increment: None,
                step_chi2: None,
                stop: None,
                photometric: photo.as_ref().map(PhotometricTerm::of),
            };
            let s = match solved {
                Ok(s) => s,
                Err(e) => {
                    it.stop = Some(LevelStop::Refused);
                    iterations.push(it);
                    return Ok(LevelEnd::Refused(e.to_string()));
                }
            };
            let (r, tr) = increment_size(&s.x);
            // The noise stop judges the step in the geometric term's covariance, also with
            // the photometric term: in the combined one the steps of projective
            // association's noise stay above the bar and a third of the noisy ICL-NUIM frames
            // ran level 0 to its budget (measured: `docs/rgbd-tracking.md`).
            let chi2 = eq.step_chi2(&s.x);
            it.eigen_ratio = Some(s.eigen_ratio);
            it.held_directions = s.held_directions;
            it.increment = Some((r, tr));
            it.step_chi2 = Some(chi2);
            let reversal = icp.stop_on_reversal && previous.is_some_and(|p| reverses(&p, &s.x));
            let x = match reversal {
                true => s.x.map(|v| 0.5 * v),
                false => s.x,
            };
            *t = update_pose(t, &x);
            previous = Some(s.x);
            it.stop = if r < icp.min_increment && tr < icp.min_increment {
                Some(LevelStop::MinIncrement)
            } else if chi2 < stop_chi2 {
                Some(LevelStop::WithinNoise)
            } else if reversal {
                Some(LevelStop::Reversal)
            } else {
                None
            };
            let stopped = it.stop.is_some();
            iterations.push(it);
            if stopped {
                return Ok(LevelEnd::Converged);
            }
        }
        if let Some(last) = iterations.last_mut() {
            last.stop = Some(LevelStop::Budget);
        }
        Ok(LevelEnd::MaxIterations)
    }

    /// Source pixels that pass filter 1 at level 0 at `t` (`icp_candidates`), for the
    /// health test's inlier fraction; `None` without the test.
    fn candidates_at(&mut self, t: &DMat4) -> Result<Option<u64>> {
        match self.params.health {
            Some(_) => Ok(Some(
                self.backend.count_candidates(&self.steps.icp_at(0, t))?,
            )),
            None => Ok(None),
        }
    }
}

/// An increment reverses its predecessor when it points back along it (cosine below
/// [`REVERSAL_COS`]) and undoes at least [`REVERSAL_MIN_RATIO`] of it: projective
/// association flipping between two correspondence sets gives steps of equal size and
/// opposite sign (measured on 7-Scenes: the coarsest level alternating between 1,916 and
/// 1,924 inliers with 0.5 mm steps for all its ten iterations), while a converging
/// Gauss-Newton step shrinks from one iteration to the next.
/// Rotation (rad) and translation (m) are compared as one 6-vector: at the 1-4 m of the
/// scenes here a radian moves a point by a few metres, so neither part dominates a
/// reversal.
pub fn reverses(previous: &Twist, x: &Twist) -> bool {
    let dot: f64 = previous.iter().zip(x).map(|(a, b)| a * b).sum();
    let norm = |v: &Twist| v.iter().map(|a| a * a).sum::<f64>().sqrt();
    let (np, nx) = (norm(previous), norm(x));
    np > 0.0 && nx > 0.0 && dot < REVERSAL_COS * np * nx && nx >= REVERSAL_MIN_RATIO * np
}

/// See [`reverses`].
pub const REVERSAL_COS: f64 = -0.7;
/// See [`reverses`].
pub const REVERSAL_MIN_RATIO: f64 = 0.5;

/// Where an attempt starts and which health test judges it.
#[derive(Debug, Clone, Copy)]
pub struct Start {
    /// The start pose, world to camera.
    pub t_world_to_cam: DMat4,
    /// Frames since the last tracked one, or `None` not to judge the motion (see
    /// [`HealthMonitor::measure`]).
    pub motion_gap: Option<u32>,
    /// Whether the stricter recovery test ([`HealthMonitor::judge_recovery`]) applies.
    pub recovery: bool,
}

impl Start {
    /// From the last tracked pose, `gap` frames on (1: the next frame). After lost frames
    /// it is a recovery.
    pub fn from_last(t_world_to_cam: DMat4, gap: u32) -> Self {
        Start {
            t_world_to_cam,
            motion_gap: Some(gap),
            recovery: gap != 1,
        }
    }

    /// From a keyframe's pose: a recovery, whose motion is not judged.
    pub fn from_keyframe(t_world_to_cam: DMat4) -> Self {
        Start {
            t_world_to_cam,
            motion_gap: None,
            recovery: true,
        }
    }

    /// From the pose that matching features gave: the tracking test applies, not the
    /// stricter recovery one, whose residual bound assumes the view overlaps the map as
    /// much as during tracking; the motion is not judged.
    pub fn from_features(t_world_to_cam: DMat4) -> Self {
        Start {
            t_world_to_cam,
            motion_gap: None,
            recovery: false,
        }
    }
}

/// One ICP run from a start pose and what the health test made of it.
pub struct Attempt {
    pub t_world_to_cam: DMat4,
    pub status: TrackStatus,
    pub iterations: Vec<IcpIteration>,
    pub health: Option<TrackingHealth>,
    /// `Err(why)` when ICP refused its first system or the health test failed.
    pub verdict: std::result::Result<(), String>,
}

/// What tracking carries from frame to frame.
#[derive(Debug, Clone, Default)]
pub struct Tracker {
    /// Last tracked world-to-camera pose, `None` before the first frame.
    t_world_to_cam: Option<DMat4>,
    /// Frames processed since the last tracked one (0 right after a tracked frame).
    frames_since_tracked: u32,
    monitor: HealthMonitor,
}

impl Tracker {
    /// The last tracked pose (the next frame's ICP starts from it), `None` before the
    /// first frame.
    pub fn t_world_to_cam(&self) -> Option<DMat4> {
        self.t_world_to_cam
    }

    /// Replaces the last tracked pose (after a loop closure bent the trajectory, or to put
    /// one tracker into another's state).
    pub fn set_t_world_to_cam(&mut self, t_world_to_cam: Option<DMat4>) {
        self.t_world_to_cam = t_world_to_cam;
    }

    /// Frames processed since the last tracked one (0 right after a tracked frame).
    pub fn frames_since_tracked(&self) -> u32 {
        self.frames_since_tracked
    }

    /// ICP from `start` and the health test of its result.
    pub fn attempt<B: Backend>(&self, icp: &mut Icp<'_, B>, start: Start) -> Result<Attempt> {
        let Track {
            t_world_to_cam: t,
            status,
            iterations,
        } = icp.track(start.t_world_to_cam)?;
        let candidates = match status {
            TrackStatus::Lost(_) => None,
            _ => icp.candidates_at(&t)?,
        };
        let params = icp.params;
        let settings = &params.health;
        let health = match (settings, candidates) {
            (Some(s), Some(c)) => {
                let (t_start, gap) = (&start.t_world_to_cam, start.motion_gap);
                self.monitor.measure(s, &iterations, c, t_start, &t, gap)
            }
            _ => None,
        };
        let verdict = match (&status, settings, &health) {
            (TrackStatus::Lost(why), _, _) => Err(why.clone()),
            (_, Some(s), Some(h)) if start.recovery => self.monitor.judge_recovery(s, h),
            (_, Some(s), Some(h)) => self.monitor.judge(s, h),
            _ => Ok(()),
        };
        Ok(Attempt {
            t_world_to_cam: t,
            status,
            iterations,
            health,
            verdict,
        })
    }

    /// A frame fused at `t_world_to_cam`: the next frame tracks from it. `health` (the
    /// fused pose's) joins the typical values; its motion only when `motion_counts`
    /// ([`HealthMonitor::record`]).
    pub fn tracked(
        &mut self,
        t_world_to_cam: DMat4,
        health: Option<&TrackingHealth>,
        motion_counts: bool,
    ) {
        self.t_world_to_cam = Some(t_world_to_cam);
        self.frames_since_tracked = 0;
        if let Some(h) = health {
            self.monitor.record(h, motion_counts);
        }
    }

    /// A frame without a tracked pose (lost, or without depth).
    pub fn missed(&mut self) {
        self.frames_since_tracked += 1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Equal and opposite steps reverse; a shrinking converging step, an orthogonal one
    /// and a small step back after a large one (an overshoot being corrected) do not.
    #[test]
    fn reversal_is_an_equal_step_back() {
        let x = [1e-4, 0.0, 0.0, 5e-4, -2e-4, 0.0];
        let back = x.map(|v| -0.9 * v);
        assert!(reverses(&x, &back));
        assert!(!reverses(&x, &x.map(|v| 0.1 * v)));
        assert!(!reverses(&x, &x.map(|v| -0.2 * v)));
        assert!(!reverses(&x, &[0.0, 1e-4, 0.0, 2e-4, 5e-4, 1e-4]));
        assert!(!reverses(&[0.0; 6], &back));
    }
}
