//! A run's tracking counts and its health verdict (`ok`, `degenerate`, `recovered`,
//! `LOST`) from its frames' outcomes; no tracking happens here.

use serde::Serialize;

use super::FrameOutcome;
use crate::slam::pipeline::TrackStatus;

/// Counts of how frames were tracked.
#[derive(Debug, Clone, Default, Serialize)]
pub struct TrackingCounts {
    pub given: usize,
    pub converged: usize,
    pub max_iterations: usize,
    pub stopped: usize,
    /// Frames placed by relocalisation after tracking from the last pose failed.
    pub relocalised: usize,
    /// Frames whose tracking was lost (not fused, no tracked pose).
    pub lost: usize,
    pub empty_depth: usize,
    /// Frames whose finest-level solve held at least one degenerate direction.
    pub degenerate: usize,
    /// Keyframes in the relocalisation database at the end.
    pub keyframes: usize,
    /// The longest run of consecutive frames without a tracked pose (lost or empty).
    pub longest_untracked_run: usize,
    /// The first lost frame's sequence position, if any.
    pub first_lost_frame: Option<usize>,
    /// Frames at the end of the run without a tracked pose (the run ended lost).
    pub untracked_at_end: usize,
    /// [`TrackingCounts::flag`]: `ok`, `degenerate`, `recovered` or `LOST`.
    pub health: String,
    /// ICP iterations (one system solved each, all levels) per frame, mean over the frames.
    pub icp_iterations_per_frame: f64,
    /// RGB-D tracking's photometric term at each frame's last iteration that had one;
    /// `None` when no frame had one (geometric tracking).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub photometric: Option<PhotometricSummary>,
}

/// The photometric term over a run ([`TrackingCounts::photometric`]).
#[derive(Debug, Clone, Default, Serialize)]
pub struct PhotometricSummary {
    /// Frames with a photometric term.
    pub frames: usize,
    /// Its inliers (model pixels used) per frame, mean.
    pub inliers_mean: f64,
    /// Its RMS intensity residual (0..1) over the frames' last iterations, the RMS of the
    /// frames' RMS values.
    pub rms: f64,
}

impl TrackingCounts {
    /// Frames placed by ICP (from the last pose or by relocalisation), not given.
    fn icp_tracked(&self) -> usize {
        self.converged + self.max_iterations + self.stopped + self.relocalised
    }

    /// Whether tracking never established itself: no frame had a pose at all (every depth
    /// empty), or, over more than one frame, none after the first was placed by ICP.
    fn never_established(&self) -> bool {
        let frames = self.icp_tracked() + self.given + self.lost + self.empty_depth;
        let placed = self.icp_tracked() + self.given;
        placed == 0 || (frames > 1 && self.given <= 1 && self.icp_tracked() == 0)
    }

    /// Whether most ICP-tracked frames held a degenerate direction (a plane or a corridor
    /// left the pose free along it, so the trajectory is unreliable there).
    fn mostly_degenerate(&self) -> bool {
        self.icp_tracked() > 0 && self.degenerate * 2 > self.icp_tracked()
    }

    /// The run's health in a word: `LOST` (the run ended without a tracked pose, or
    /// tracking never established itself), `recovered` (lost frames, but the run ended
    /// tracking), `degenerate` (no frame lost, but most tracked frames held a degenerate
    /// direction), `ok`.
    pub fn flag(&self) -> &'static str {
        if self.never_established() {
            return "LOST";
        }
        match (self.lost, self.untracked_at_end) {
            (0, _) if self.mostly_degenerate() => "degenerate",
            (0, _) => "ok",
            (_, 0) => "recovered",
            _ => "LOST",
        }
    }

    /// One line for the run summary.
    pub fn verdict(&self) -> String {
        if self.never_established() {
            return format!(
                "LOST: tracking never established itself (no frame after the first was \
                 tracked: {} lost, {} with no depth, {} given); check the depth images and \
                 that consecutive frames overlap",
                self.lost, self.empty_depth, self.given
            );
        }
        match self.flag() {
            "ok" => "ok (no frame lost)".into(),
            "degenerate" => format!(
                "degenerate: {} of {} tracked frames held a direction the geometry did not \
                 constrain (a plane or a corridor); the trajectory is unreliable along it",
                self.degenerate,
                self.icp_tracked()
            ),
            flag => format!(
                "{flag}: {} frame(s) lost from frame {} on (longest run {}), {} relocalised{}",
                self.lost,
                self.first_lost_frame.unwrap_or_default(),
                self.longest_untracked_run,
                self.relocalised,
                match self.untracked_at_end {
                    0 => String::new(),
                    n => format!("; the last {n} frame(s) have no pose"),
                }
            ),
        }
    }
}

/// How the run's frames were tracked (`keyframes`: the database's size at the end).
pub fn tracking_counts(frames: &[FrameOutcome], keyframes: usize) -> TrackingCounts {
    let mut counts = TrackingCounts {
        keyframes,
        ..TrackingCounts::default()
    };
    let mut run = 0;
    for f in frames {
        match f.report.status {
            TrackStatus::Given => counts.given += 1,
            TrackStatus::Converged => counts.converged += 1,
            TrackStatus::MaxIterations => counts.max_iterations += 1,
            TrackStatus::Stopped(_) => counts.stopped += 1,
            TrackStatus::Relocalised { .. } => counts.relocalised += 1,
            TrackStatus::Lost(_) => {
                counts.lost += 1;
                counts.first_lost_frame.get_or_insert(f.index);
            }
            TrackStatus::EmptyDepth => counts.empty_depth += 1,
        }
        if f.report.health.is_some_and(|h| h.held_directions > 0) {
            counts.degenerate += 1;
        }
        run = if f.report.status.is_tracked() {
            0
        } else {
            run + 1
        };
        counts.longest_untracked_run = counts.longest_untracked_run.max(run);
    }
    // Empty frames at the very start are not a failure (the run starts at the first
    // usable one); at the end they are.
    counts.untracked_at_end = if frames.iter().any(|f| f.report.status.is_tracked()) {
        run
    } else {
        frames.len()
    };
    counts.health = counts.flag().to_string();
    let iterations: usize = frames.iter().map(|f| f.report.iterations.len()).sum();
    counts.icp_iterations_per_frame = iterations as f64 / frames.len().max(1) as f64;
    let last_terms: Vec<_> = frames
        .iter()
        .filter_map(|f| f.report.iterations.iter().rev().find_map(|i| i.photometric))
        .collect();
    if !last_terms.is_empty() {
        let n = last_terms.len() as f64;
        counts.photometric = Some(PhotometricSummary {
            frames: last_terms.len(),
            inliers_mean: last_terms.iter().map(|p| p.inliers as f64).sum::<f64>() / n,
            rms: (last_terms.iter().map(|p| p.rms * p.rms).sum::<f64>() / n).sqrt(),
        });
    }
    counts
}

#[cfg(test)]
mod tests {
    use super::TrackingCounts;

    #[test]
    fn runs_that_never_tracked_or_were_mostly_degenerate_are_not_ok() {
        // (case, given, converged, degenerate, empty depth (all at the end), flag)
        let cases = [
            ("healthy", 1, 9, 2, 0, "ok"),
            ("all depth empty", 0, 0, 0, 3, "LOST"),
            ("only the first frame", 1, 0, 0, 5, "LOST"),
            ("flat wall", 1, 59, 59, 0, "degenerate"),
            ("ground-truth poses", 10, 0, 0, 0, "ok"),
            ("one frame", 1, 0, 0, 0, "ok"),
        ];
        for (case, given, converged, degenerate, empty, flag) in cases {
            let t = TrackingCounts {
                given,
                converged,
                degenerate,
                empty_depth: empty,
                untracked_at_end: empty,
                ..TrackingCounts::default()
            };
            assert_eq!(t.flag(), flag, "{case}");
            let verdict = t.verdict();
            assert!(verdict.starts_with(flag), "{case}: {verdict}");
            if flag == "LOST" {
                assert!(verdict.contains("never established"), "{case}: {verdict}");
            }
        }
        let wall = TrackingCounts {
            given: 1,
            converged: 59,
            degenerate: 59,
            ..TrackingCounts::default()
        };
        assert!(wall.verdict().contains("59 of 59"), "{}", wall.verdict());
    }
}
