//! RGB-D sequences on disk: layout detection (TUM RGB-D or ICL-NUIM), frame lists,
//! ground truth, intrinsics, and decoding one frame at a time.
//!
//! Not a preprocessor: frames come back at full resolution with raw `u16` depth; scaling to
//! metres (divide by [`Sequence::depth_scale`]), filtering and downsampling happen elsewhere.
//! Ground-truth poses are `t_cam_to_world` in metres, exactly as the dataset gives them.

pub(crate) mod frame;
pub(crate) mod icl;
pub(crate) mod tum;

use std::ops::RangeInclusive;
use std::path::{Path, PathBuf};

use glam::DMat4;
use serde::Deserialize;

use crate::geometry::camera::Intrinsics;
use crate::io::trajectory::read_tum;
use crate::{Error, Result};

pub use frame::RawFrame;

/// Raw depth units per metre when neither the options nor `camera.json` say otherwise.
pub const DEFAULT_DEPTH_SCALE: f32 = 5000.0;
/// Default association window in seconds (the TUM benchmark tools' default).
pub const DEFAULT_MAX_TIME_DIFF: f64 = 0.02;

/// How to open a sequence; every field overrides what the directory says.
#[derive(Debug, Clone, PartialEq)]
pub struct SequenceOptions {
    /// Ground-truth trajectory to use instead of the layout's default file.
    pub gt_path: Option<PathBuf>,
    /// Intrinsics to use instead of `camera.json` or the layout's default.
    pub intrinsics: Option<Intrinsics>,
    /// Raw depth units per metre instead of `camera.json`'s or [`DEFAULT_DEPTH_SCALE`].
    pub depth_scale: Option<f32>,
    /// Largest |dt| in seconds (index units for ICL-NUIM) when associating streams.
    pub max_time_diff: f64,
}

impl Default for SequenceOptions {
    fn default() -> Self {
        SequenceOptions {
            gt_path: None,
            intrinsics: None,
            depth_scale: None,
            max_time_diff: DEFAULT_MAX_TIME_DIFF,
        }
    }
}

/// Directory layout of a sequence.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Layout {
    /// TUM RGB-D: `rgb.txt`, `depth.txt`, optional `groundtruth.txt` (stamps in seconds).
    Tum,
    /// ICL-NUIM TUM-compatible: `associations.txt` and `*.gt.freiburg` (stamps are indices).
    IclNuim,
}

/// One associated frame: its stamp, both image paths and its ground truth if any.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameRecord {
    /// Depth stamp in seconds (TUM) or the frame index (ICL-NUIM).
    pub timestamp: f64,
    pub rgb_path: PathBuf,
    pub depth_path: PathBuf,
    /// Ground-truth camera-to-world pose (metres), nearest GT stamp within the window.
    pub gt_cam_to_world: Option<DMat4>,
}

/// An opened sequence: the associated frame list, intrinsics and depth scale.
#[derive(Debug, Clone, PartialEq)]
pub struct Sequence {
    pub root: PathBuf,
    pub layout: Layout,
    /// Intrinsics of the full-resolution images.
    pub intrinsics: Intrinsics,
    /// Raw depth units per metre.
    pub depth_scale: f32,
    /// Frames in order of depth stamp; positions in this list are "frame numbers".
    pub frames: Vec<FrameRecord>,
}

/// `camera.json` in a dataset directory: intrinsics in pixels, optional depth scale.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct CameraJson {
    width: u32,
    height: u32,
    fx: f32,
    fy: f32,
    cx: f32,
    cy: f32,
    depth_scale: Option<f32>,
}

fn read_camera_json(path: &Path) -> Result<Option<CameraJson>> {
    if !path.exists() {
        return Ok(None);
    }
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    let cam: CameraJson = serde_json::from_str(&text).map_err(|e| {
        Error::format(
            path,
            format!("expected {{width, height, fx, fy, cx, cy[, depth_scale]}}: {e}"),
        )
    })?;
    let finite = [cam.fx, cam.fy, cam.cx, cam.cy]
        .iter()
        .all(|v| v.is_finite());
    if !finite || cam.fx == 0.0 || cam.fy == 0.0 || cam.width == 0 || cam.height == 0 {
        return Err(Error::format(
            path,
            "width/height must be positive and fx, fy finite and non-zero",
        ));
    }
    Ok(Some(cam))
}

fn detect_layout(root: &Path) -> Result<Layout> {
    if !root.is_dir() {
        let kind = if root.exists() {
            std::io::ErrorKind::NotADirectory
        } else {
            std::io::ErrorKind::NotFound
        };
        return Err(Error::io(
            root,
            std::io::Error::new(kind, "dataset directory does not exist"),
        ));
    }
    // rgb.txt/depth.txt win: TUM users often add an associations.txt of their own.
    if root.join("rgb.txt").is_file() && root.join("depth.txt").is_file() {
        Ok(Layout::Tum)
    } else if root.join("associations.txt").is_file() {
        Ok(Layout::IclNuim)
    } else {
        Err(Error::format(
            root,
            "not a dataset: expected rgb.txt and depth.txt (TUM RGB-D) or associations.txt \
             (ICL-NUIM)",
        ))
    }
}

/// Opens the sequence in `root`: detects the layout, associates frames, attaches ground
/// truth and settles intrinsics (override > `camera.json` > layout default; TUM has no
/// default) and depth scale (override > `camera.json` > 5000). Every listed image file
/// must exist; images are only decoded by [`Sequence::load`].
pub fn open(root: &Path, opts: &SequenceOptions) -> Result<Sequence> {
    if !(opts.max_time_diff.is_finite() && opts.max_time_diff >= 0.0) {
        return Err(Error::Argument(format!(
            "max time difference must be finite and >= 0, got {}",
            opts.max_time_diff
        )));
    }
    let layout = detect_layout(root)?;
    let camera = read_camera_json(&root.join("camera.json"))?;

    let intrinsics = match (opts.intrinsics, &camera, layout) {
        (Some(k), _, _) => k,
        (None, Some(c), _) => Intrinsics {
            width: c.width,
            height: c.height,
            fx: c.fx,
            fy: c.fy,
            cx: c.cx,
            cy: c.cy,
        },
        (None, None, Layout::IclNuim) => Intrinsics::ICL_NUIM,
        (None, None, Layout::Tum) => {
            return Err(Error::Argument(format!(
                "{}: TUM RGB-D sequences do not record their intrinsics; pass --intrinsics \
                 (a preset such as fr1, fr2, fr3, or fx,fy,cx,cy) or add a camera.json",
                root.display()
            )))
        }
    };
    let depth_scale = opts
        .depth_scale
        .or(camera.as_ref().and_then(|c| c.depth_scale))
        .unwrap_or(DEFAULT_DEPTH_SCALE);
    if !(depth_scale.is_finite() && depth_scale > 0.0) {
        return Err(Error::Argument(format!(
            "depth scale must be positive, got {depth_scale}"
        )));
    }

    // (stamp, rgb, depth) in order of depth stamp.
    let (pairs, default_gt): (Vec<(f64, PathBuf, PathBuf)>, Option<PathBuf>) = match layout {
        Layout::Tum => {
            let rgb = tum::read_list(&root.join("rgb.txt"))?;
            let depth = tum::read_list(&root.join("depth.txt"))?;
            let rs: Vec<f64> = rgb.iter().map(|e| e.stamp).collect();
            let ds: Vec<f64> = depth.iter().map(|e| e.stamp).collect();
            let pairs = tum::associate(&ds, &rs, opts.max_time_diff)
                .into_iter()
                .map(|(id, ir)| (ds[id], root.join(&rgb[ir].path), root.join(&depth[id].path)))
                .collect();
            let gt = root.join("groundtruth.txt");
            (pairs, gt.is_file().then_some(gt))
        }
        Layout::IclNuim => {
            let assoc = icl::read_associations(&root.join("associations.txt"))?;
            let pairs = assoc
                .into_iter()
                .map(|a| (a.stamp, root.join(a.rgb_path), root.join(a.depth_path)))
                .collect();
            (pairs, icl::find_ground_truth(root)?)
        }
    };
    if pairs.is_empty() {
        return Err(Error::format(
            root,
            format!(
                "empty sequence: no colour/depth pairs{}",
                if layout == Layout::Tum {
                    format!(" within {} s of each other", opts.max_time_diff)
                } else {
                    String::new()
                }
            ),
        ));
    }
    for (_, rgb, depth) in &pairs {
        for p in [rgb, depth] {
            if !p.is_file() {
                return Err(Error::io(
                    p,
                    std::io::Error::new(
                        std::io::ErrorKind::NotFound,
                        "image listed by the dataset does not exist",
                    ),
                ));
            }
        }
    }

    let gt_path = opts.gt_path.clone().or(default_gt);
    let gt = match &gt_path {
        Some(p) => {
            let mut g = read_tum(p)?;
            g.sort_by(|a, b| a.0.total_cmp(&b.0));
            g
        }
        None => Vec::new(),
    };
    let gt_stamps: Vec<f64> = gt.iter().map(|g| g.0).collect();
    let frames = pairs
        .into_iter()
        .map(|(stamp, rgb_path, depth_path)| FrameRecord {
            timestamp: stamp,
            rgb_path,
            depth_path,
            gt_cam_to_world: tum::nearest_within(&gt_stamps, stamp, opts.max_time_diff)
                .map(|k| gt[k].1),
        })
        .collect();

    Ok(Sequence {
        root: root.to_path_buf(),
        layout,
        intrinsics,
        depth_scale,
        frames,
    })
}

impl Sequence {
    /// Number of associated frames.
    pub fn len(&self) -> usize {
        self.frames.len()
    }

    /// Never true for an opened sequence ([`open`] rejects empty ones).
    pub fn is_empty(&self) -> bool {
        self.frames.is_empty()
    }

    /// Frames `first..=last` by position in the associated sequence; an error if empty or
    /// outside `0..len`.
    pub fn select(&self, first: usize, last: usize) -> Result<RangeInclusive<usize>> {
        let n = self.frames.len();
        if first > last || last >= n {
            return Err(Error::Argument(format!(
                "frame range {first}..{last} is outside the sequence {} (frames 0..{})",
                self.root.display(),
                n.saturating_sub(1)
            )));
        }
        Ok(first..=last)
    }

    /// Decodes frame `i` (position in [`Sequence::frames`]); checks pixel formats, that
    /// colour and depth have the same size, and that the size matches the intrinsics.
    pub fn load(&self, i: usize) -> Result<RawFrame> {
        let f = self.frames.get(i).ok_or_else(|| {
            Error::Argument(format!(
                "frame {i} is outside the sequence (frames 0..{})",
                self.frames.len().saturating_sub(1)
            ))
        })?;
        frame::load_frame(
            &f.rgb_path,
            &f.depth_path,
            (self.intrinsics.width, self.intrinsics.height),
        )
    }

    /// A long sequence that revisits frames `first..=last`: forwards, backwards, forwards
    /// ... until `total` frames (for the long-sequence benchmark: the camera passes over
    /// the same scene again and again, as a long real sequence does). Each frame keeps its
    /// images and ground truth; its stamp becomes its new position (0, 1, ...), so stamps
    /// increase and the trajectory associates with [`Sequence::ground_truth`] by stamp.
    /// A pass is `last - first` frames (the turning frames are not repeated).
    pub fn revisiting(&self, first: usize, last: usize, total: usize) -> Result<Sequence> {
        self.select(first, last)?;
        if last == first || total == 0 {
            return Err(Error::Argument(format!(
                "a revisiting sequence needs at least two frames to go back and forth over and \
                 a length of at least one (got frames {first}..{last}, length {total})"
            )));
        }
        let period = 2 * (last - first);
        let frames = (0..total)
            .map(|k| {
                let phase = k % period;
                let i = if phase <= last - first {
                    first + phase
                } else {
                    last - (phase - (last - first))
                };
                FrameRecord {
                    timestamp: k as f64,
                    ..self.frames[i].clone()
                }
            })
            .collect();
        Ok(Sequence {
            frames,
            ..self.clone()
        })
    }

    /// True when at least one frame has a ground-truth pose.
    pub fn has_ground_truth(&self) -> bool {
        self.frames.iter().any(|f| f.gt_cam_to_world.is_some())
    }

    /// `(timestamp, t_cam_to_world)` of every frame that has ground truth.
    pub fn ground_truth(&self) -> Vec<(f64, DMat4)> {
        self.frames
            .iter()
            .filter_map(|f| f.gt_cam_to_world.map(|g| (f.timestamp, g)))
            .collect()
    }
}

/// Parses an inclusive frame range `"A..B"` (e.g. `1..200`) for the command line.
pub fn parse_range(s: &str) -> Result<(usize, usize)> {
    let bad = || {
        Error::Argument(format!(
            "frame range {s:?} must look like A..B with whole numbers A <= B (inclusive)"
        ))
    };
    let (a, b) = s.trim().split_once("..").ok_or_else(bad)?;
    let a: usize = a.trim().parse().map_err(|_| bad())?;
    let b: usize = b.trim().parse().map_err(|_| bad())?;
    if a > b {
        return Err(bad());
    }
    Ok((a, b))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranges_parse() {
        assert_eq!(parse_range("1..200").unwrap(), (1, 200));
        assert_eq!(parse_range(" 3..3 ").unwrap(), (3, 3));
        for bad in ["", "5", "5..", "..5", "a..b", "9..2", "-1..3", "1..=3"] {
            assert!(parse_range(bad).is_err(), "{bad:?} accepted");
        }
    }

    #[test]
    fn revisiting_goes_back_and_forth_with_increasing_stamps() {
        let frame = |i: usize| FrameRecord {
            timestamp: 100.0 + i as f64,
            rgb_path: PathBuf::from(format!("rgb{i}")),
            depth_path: PathBuf::from(format!("d{i}")),
            gt_cam_to_world: Some(DMat4::from_translation(glam::DVec3::X * i as f64)),
        };
        let seq = Sequence {
            root: PathBuf::from("r"),
            layout: Layout::Tum,
            intrinsics: Intrinsics::ICL_NUIM,
            depth_scale: DEFAULT_DEPTH_SCALE,
            frames: (0..6).map(frame).collect(),
        };
        let r = seq.revisiting(1, 3, 9).unwrap();
        let order: Vec<String> = r
            .frames
            .iter()
            .map(|f| f.rgb_path.display().to_string())
            .collect();
        assert_eq!(
            order,
            ["rgb1", "rgb2", "rgb3", "rgb2", "rgb1", "rgb2", "rgb3", "rgb2", "rgb1"]
        );
        for (k, f) in r.frames.iter().enumerate() {
            assert_eq!(f.timestamp, k as f64);
            let i: f64 = f.depth_path.display().to_string()[1..].parse().unwrap();
            assert_eq!(
                f.gt_cam_to_world.unwrap().w_axis.x,
                i,
                "ground truth follows the frame"
            );
        }
        assert!(seq.revisiting(2, 2, 5).is_err());
        assert!(seq.revisiting(1, 6, 5).is_err());
    }
}
