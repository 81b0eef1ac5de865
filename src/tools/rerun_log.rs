//! `wgslam run --rerun FILE.rrd`: a Rerun recording of a run (camera path, images, map) for
//! the Rerun viewer (`rerun FILE.rrd`). Built only with the `rerun` cargo feature; it is a
//! picture of the run, not an output wgslam reads back.
//!
//! Entities, all in the dataset's world frame (the ground truth's), metres:
//!
//! | entity | archetype | when |
//! |---|---|---|
//! | `world/camera` | `Transform3D`: the estimated camera-to-world pose | every frame with a pose |
//! | `world/camera/image` | `Pinhole`: the raw frames' intrinsics and size | static |
//! | `world/camera/image/rgb` | `Image`: the frame's colour, RGB8 | every frame |
//! | `world/camera/image/depth` | `DepthImage`: raw u16 depth, `meter` = depth units per metre | every frame |
//! | `world/trajectory/estimate` | `LineStrips3D`: the estimated camera path so far | every frame with a pose |
//! | `world/trajectory/ground_truth` | `LineStrips3D`: the ground-truth path over the run's frames | static, when there is one |
//! | `world/map` | `Points3D`: surfel positions, colours, radii (every k-th surfel, at most [`MAX_MAP_POINTS`]) | every N-th frame and after the last |
//!
//! Timelines: `frame` (position in the sequence) and `stamp` (the dataset's time stamp in
//! seconds, as a duration: TUM stamps are seconds since the epoch, ICL-NUIM's are frame
//! indices). The intrinsics are logged as they are: ICL-NUIM's negative `fy` makes the
//! camera's y axis point up, and the pinhole's matrix carries that, so images and points
//! project where the pipeline projects them.
//!
//! The recording streams into a temp file next to the target (`.NAME.tmp-PID-N`) and is
//! renamed over the target by [`RerunLog::finish`]; a run that fails or is killed leaves no
//! file that looks like a complete recording.

use std::path::{Path, PathBuf};

use crate::dataset::{RawFrame, Sequence};
use crate::layout::map::SurfelMap;
use crate::slam::pipeline::TrackStatus;
use crate::tools::run::{FrameObserver, FrameOutcome};
use crate::{Error, Result};

/// Most map points logged at once. The viewer draws a few hundred thousand points
/// smoothly, and every logged map is kept in the file (16 bytes a point with colour and
/// radius): a 1M-surfel map logged every 10th frame of 2000 would otherwise be 3 GB.
pub const MAX_MAP_POINTS: usize = 100_000;

/// Distance from the camera at which the viewer draws the image plane, metres: about the
/// depth of an indoor scene's near wall, so the frustum stays readable beside the map.
const IMAGE_PLANE_DISTANCE_M: f32 = 0.3;

/// Logs a run to a Rerun recording; a [`FrameObserver`] for [`crate::tools::run::run_observed`].
pub struct RerunLog {
    /// `None` once finished (or dropped).
    rec: Option<rerun::RecordingStream>,
    /// The recording's final path.
    path: PathBuf,
    /// Where it is written until [`RerunLog::finish`] renames it.
    tmp: PathBuf,
    /// Raw depth units per metre.
    depth_scale: f32,
    /// Log the map after every `map_every`-th frame of the run (counted from its first).
    map_every: usize,
    /// Frames shown so far.
    frames_seen: usize,
    /// True when the last frame shown logged the map (so the final map is already there).
    map_logged_last: bool,
    /// Estimated camera positions so far, world frame, metres.
    path_estimate: Vec<[f32; 3]>,
}

impl RerunLog {
    /// Starts a recording of a run over frames `first..=last` of `seq`, to be written to
    /// `path`; logs the intrinsics and the ground-truth path. `map_every` (>= 1): log the
    /// map after every `map_every`-th frame.
    pub fn create(
        path: &Path,
        seq: &Sequence,
        first: usize,
        last: usize,
        map_every: usize,
    ) -> Result<Self> {
        if map_every == 0 {
            return Err(Error::Argument(
                "--rerun-map-every must be at least 1".into(),
            ));
        }
        let tmp = crate::io::atomic::temp_path(path)?;
        let rec = rerun::RecordingStreamBuilder::new("wgslam")
            // The user asked for the file: the RERUN=off environment switch does not apply.
            .enabled(true)
            .save(&tmp)
            .map_err(|e| Error::write(&tmp, std::io::Error::other(e.to_string())))?;
        let log = RerunLog {
            rec: Some(rec),
            path: path.to_path_buf(),
            tmp,
            depth_scale: seq.depth_scale,
            map_every,
            frames_seen: 0,
            map_logged_last: false,
            path_estimate: Vec::new(),
        };
        let k = &seq.intrinsics;
        let pinhole = rerun::Pinhole::from_focal_length_and_resolution(
            [k.fx, k.fy],
            [k.width as f32, k.height as f32],
        )
        .with_principal_point([k.cx, k.cy])
        .with_image_plane_distance(IMAGE_PLANE_DISTANCE_M);
        log.log_static("world/camera/image", &pinhole)?;
        let gt: Vec<[f32; 3]> = seq.frames[first..=last]
            .iter()
            .filter_map(|f| f.gt_cam_to_world.as_ref())
            .map(|t| t.w_axis.truncate().as_vec3().to_array())
            .collect();
        if !gt.is_empty() {
            let strip =
                rerun::LineStrips3D::new([gt]).with_colors([rerun::Color::from_rgb(60, 200, 60)]);
            log.log_static("world/trajectory/ground_truth", &strip)?;
        }
        Ok(log)
    }

    fn rec(&self) -> &rerun::RecordingStream {
        self.rec
            .as_ref()
            .expect("RerunLog used after finish (internal contract)")
    }

    fn encode_error(&self, e: impl std::fmt::Display) -> Error {
        Error::encode(format!("Rerun recording {}", self.path.display()), e)
    }

    fn log(&self, entity: &str, what: &impl rerun::AsComponents) -> Result<()> {
        self.rec()
            .log(entity, what)
            .map_err(|e| self.encode_error(e))
    }

    fn log_static(&self, entity: &str, what: &impl rerun::AsComponents) -> Result<()> {
        self.rec()
            .log_static(entity, what)
            .map_err(|e| self.encode_error(e))
    }

    /// Sets both timelines to frame `index` at dataset stamp `timestamp` (seconds).
    fn set_time(&self, index: usize, timestamp: f64) {
        let rec = self.rec();
        rec.set_time_sequence("frame", index as i64);
        rec.set_duration_secs("stamp", timestamp);
    }

    /// Logs every `stride`-th surfel of `map` (stride chosen so at most [`MAX_MAP_POINTS`]).
    fn log_map(&self, map: &SurfelMap) -> Result<()> {
        let stride = map.len().div_ceil(MAX_MAP_POINTS).max(1);
        let picked = (0..map.len()).step_by(stride);
        let positions: Vec<[f32; 3]> = picked.clone().map(|i| map.position(i)).collect();
        let colors: Vec<rerun::Color> = picked
            .clone()
            .map(|i| {
                let c = map.color[i];
                let byte = |v: f32| v.round().clamp(0.0, 255.0) as u8;
                rerun::Color::from_rgb(byte(c[0]), byte(c[1]), byte(c[2]))
            })
            .collect();
        // Radius in metres (colour's alpha slot); the assignment's profile keeps none (0),
        // which the viewer would draw as invisible points: give those a small fixed size.
        let radii: Vec<f32> = picked
            .map(|i| match map.color[i][3] {
                r if r > 0.0 => r,
                _ => FALLBACK_POINT_RADIUS_M,
            })
            .collect();
        let points = rerun::Points3D::new(positions)
            .with_colors(colors)
            .with_radii(radii);
        self.log("world/map", &points)
    }

    /// Logs the final `map` at the last frame's time (unless that frame logged it already),
    /// flushes, and renames the recording into place. Returns the path written.
    pub fn finish(mut self, map: &SurfelMap) -> Result<PathBuf> {
        if !self.map_logged_last {
            self.log_map(map)?;
        }
        let rec = self.rec.take().expect("finish runs once (it takes self)");
        rec.flush_blocking()
            .map_err(|e| Error::write(&self.tmp, std::io::Error::other(e.to_string())))?;
        // Dropping the last handle closes the file sink (its writer thread ends).
        drop(rec);
        std::fs::File::open(&self.tmp)
            .and_then(|f| f.sync_all())
            .map_err(|e| Error::write(&self.tmp, e))?;
        std::fs::rename(&self.tmp, &self.path).map_err(|e| Error::write(&self.path, e))?;
        Ok(self.path.clone())
    }
}

/// Point radius for surfels without one (the assignment's profile), metres: about a
/// pixel's footprint at 2 m with ICL-NUIM's 481 px focal length at 320x240.
const FALLBACK_POINT_RADIUS_M: f32 = 0.008;

impl FrameObserver for RerunLog {
    fn wants_map(&mut self, _index: usize) -> bool {
        (self.frames_seen + 1) % self.map_every == 0
    }

    fn frame(
        &mut self,
        raw: &RawFrame,
        outcome: &FrameOutcome,
        map: Option<&SurfelMap>,
    ) -> Result<()> {
        self.frames_seen += 1;
        self.set_time(outcome.index, outcome.timestamp);
        let size = [raw.width, raw.height];
        let rgb: &[u8] = bytemuck::cast_slice(&raw.rgb);
        self.log(
            "world/camera/image/rgb",
            &rerun::Image::from_rgb24(rgb.to_vec(), size),
        )?;
        let depth: &[u8] = bytemuck::cast_slice(&raw.depth);
        self.log(
            "world/camera/image/depth",
            &rerun::DepthImage::from_gray16(depth.to_vec(), size).with_meter(self.depth_scale),
        )?;
        // A frame with no depth before the first placed one has no pose (as in
        // `run::trajectory`); later ones keep the last pose, which is still where the
        // camera is believed to be.
        let placed =
            outcome.report.status != TrackStatus::EmptyDepth || !self.path_estimate.is_empty();
        if placed {
            let t = outcome.report.t_cam_to_world;
            let (_, rotation, translation) = t.to_scale_rotation_translation();
            let q = rotation.as_quat().normalize();
            let position = translation.as_vec3().to_array();
            self.log(
                "world/camera",
                &rerun::Transform3D::from_translation_rotation(
                    position,
                    rerun::Quaternion::from_xyzw(q.to_array()),
                ),
            )?;
            self.path_estimate.push(position);
            let strip = rerun::LineStrips3D::new([self.path_estimate.clone()])
                .with_colors([rerun::Color::from_rgb(230, 120, 30)]);
            self.log("world/trajectory/estimate", &strip)?;
        }
        if let Some(map) = map {
            self.log_map(map)?;
        }
        self.map_logged_last = map.is_some();
        Ok(())
    }
}

impl Drop for RerunLog {
    /// An unfinished recording (the run failed) is closed and its temp file removed.
    fn drop(&mut self) {
        if let Some(rec) = self.rec.take() {
            drop(rec);
            let _ = std::fs::remove_file(&self.tmp);
        }
    }
}
