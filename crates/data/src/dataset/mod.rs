//! RGB-D sequences on disk as the public datasets ship them: layout detection, frame lists,
//! ground truth (one trajectory file or a pose file per frame), intrinsics and depth scale
//! from the dataset's own files, and decoding one frame at a time.
//!
//! Layouts ([`Layout`]): TUM RGB-D, ICL-NUIM, ETH3D SLAM, Bonn (`tum.rs`, `icl.rs`,
//! `eth3d.rs`, `bonn.rs`), the 7-Scenes / 3DMatch / tsdf-fusion frame files
//! (`seven_scenes.rs`), ScanNet's SensReader export (`scannet.rs`) and Replica as NICE-SLAM
//! ships it (`replica.rs`); `detect.rs` picks one. Every file is read through [`source`]:
//! the disk ([`open`]), or files held in memory or given to a web page ([`open_with`]).
//!
//! Not a preprocessor: frames come back at the depth image's full resolution with raw `u16`
//! depth; scaling to metres (divide by [`Sequence::depth_scale`]), filtering and
//! downsampling happen elsewhere. Ground-truth poses are `t_cam_to_world` in metres,
//! exactly as the dataset gives them.

#[cfg(not(target_arch = "wasm32"))]
pub(crate) mod bag;
pub(crate) mod bonn;
pub(crate) mod camera_json;
pub(crate) mod checks;
pub use checks::repeated_stamps_note;
pub use interface::Interface;
pub use matrix_file::pose_from_row_major;
pub(crate) mod detect;
pub(crate) mod eth3d;
pub mod frame;
pub(crate) mod icl;
pub(crate) mod in_memory;
mod interface;
pub(crate) mod matrix_file;
pub(crate) mod numbered;
pub(crate) mod replica;
pub(crate) mod scannet;
pub(crate) mod seven_scenes;
pub mod source;
mod stamped;
pub(crate) mod tum;
pub(crate) mod undistort;

use std::ops::RangeInclusive;
use std::path::{Path, PathBuf};

use glam::DMat4;

use crate::geometry::camera::{Distortion, Intrinsics};
use crate::{Error, Result};

pub use frame::RawFrame;
pub use in_memory::{open_in_memory, HeldBytes, InMemoryFiles};
pub use source::DatasetFiles;

/// Raw depth units per metre when neither the options, `camera.json` nor the layout say
/// otherwise (TUM RGB-D, ICL-NUIM, ETH3D and Bonn all use 5000).
pub const DEFAULT_DEPTH_SCALE: f32 = 5000.0;
/// Default association window in seconds (the TUM benchmark tools' default).
pub const DEFAULT_MAX_TIME_DIFF: f64 = 0.02;

/// How to open a sequence; every field overrides what the directory says.
#[derive(Debug, Clone, PartialEq)]
pub struct SequenceOptions {
    /// Ground-truth trajectory (TUM format, associated by stamp) to use instead of the
    /// layout's own ground truth.
    pub gt_path: Option<PathBuf>,
    /// Intrinsics to use instead of `camera.json` or the layout's. For layouts whose frames
    /// carry no size elsewhere (7-Scenes, ScanNet, Replica) the image size is the depth
    /// images' and only `fx, fy, cx, cy` are taken from here.
    pub intrinsics: Option<Intrinsics>,
    /// The lens of the camera `intrinsics` give (a preset's: `--camera fr1`), removed from
    /// every frame; with `intrinsics` set it replaces `camera.json`'s lens as their pinhole
    /// values replace its, and `None` is then a pinhole camera.
    pub distortion: Option<Distortion>,
    /// Raw depth units per metre instead of `camera.json`'s or the layout's.
    pub depth_scale: Option<f32>,
    /// Largest |dt| in seconds (frame-number units where stamps are frame numbers) when
    /// associating streams and ground truth.
    pub max_time_diff: f64,
    /// The frames' order where a TUM-style list's stamps go backwards.
    pub stamp_order: StampOrder,
    /// Who opens the sequence: an error's remedy is worded for it.
    pub interface: Interface,
    /// A recording's depth topic (`sensor_msgs/Image`), when it has several.
    pub depth_topic: Option<String>,
    /// A recording's colour topic (`Image` or `CompressedImage`), when it has several.
    pub color_topic: Option<String>,
}

/// The order of a TUM-style sequence's frames (`rgb.txt`, `depth.txt`): what a list whose
/// stamps go backwards means is the user's to say (a note names the list either way).
#[derive(
    Debug,
    Clone,
    Copy,
    Default,
    PartialEq,
    Eq,
    serde::Serialize,
    serde::Deserialize,
    clap::ValueEnum,
)]
#[serde(rename_all = "lowercase")]
pub enum StampOrder {
    /// By stamp (the TUM benchmark's convention: lists are in time order).
    #[default]
    Time,
    /// By line of `depth.txt` (a recorder that wrote frames in order, but whose stamps are
    /// not times: per-frame intervals, a clock that was reset).
    File,
}

impl Default for SequenceOptions {
    fn default() -> Self {
        SequenceOptions {
            gt_path: None,
            intrinsics: None,
            distortion: None,
            depth_scale: None,
            max_time_diff: DEFAULT_MAX_TIME_DIFF,
            stamp_order: StampOrder::Time,
            interface: Interface::CommandLine,
            depth_topic: None,
            color_topic: None,
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
    /// ETH3D SLAM: TUM-like, with `associated.txt` and the intrinsics in `calibration.txt`.
    Eth3d,
    /// Bonn RGB-D Dynamic: the TUM layout in a folder named `rgbd_bonn_*`, with the Bonn
    /// sensor's published intrinsics.
    Bonn,
    /// 7-Scenes / 3DMatch / tsdf-fusion: `frame-NNNNNN.{color.jpg|color.png, depth.png,
    /// pose.txt}`, optional `camera-intrinsics.txt`, optionally in `seq-NN/` folders
    /// (stamps are frame numbers).
    SevenScenes,
    /// ScanNet SensReader export: `color/N.jpg`, `depth/N.png`, `pose/N.txt`,
    /// `intrinsic/intrinsic_{depth,color}.txt` (stamps are frame numbers).
    ScanNet,
    /// Replica as NICE-SLAM ships it: `results/frameNNNNNN.jpg`, `results/depthNNNNNN.png`,
    /// `traj.txt`, `cam_params.json` (stamps are frame numbers).
    Replica,
    /// A ROS 1 `.bag` file (`bag.rs`; not among the detected folder layouts).
    Ros1Bag,
    /// A ROS 2 bag: a folder with `metadata.yaml` and one `.mcap` or `.db3` file.
    Ros2Bag,
    /// A single `.mcap` file.
    Mcap,
}

impl Layout {
    /// The order `detect::detect` tries the layouts in: the TUM-like layouts with an
    /// extra telltale (ETH3D's `calibration.txt`, Bonn's folder name) before plain TUM.
    pub const DETECTION_ORDER: [Layout; 7] = [
        Layout::Eth3d,
        Layout::Bonn,
        Layout::Tum,
        Layout::IclNuim,
        Layout::SevenScenes,
        Layout::ScanNet,
        Layout::Replica,
    ];

    /// The layout's name as users know it.
    pub fn name(self) -> &'static str {
        match self {
            Layout::Tum => "TUM RGB-D",
            Layout::IclNuim => "ICL-NUIM",
            Layout::Eth3d => "ETH3D SLAM",
            Layout::Bonn => "Bonn RGB-D Dynamic",
            Layout::SevenScenes => "7-Scenes/3DMatch frame files",
            Layout::ScanNet => "ScanNet export",
            Layout::Replica => "Replica (NICE-SLAM)",
            Layout::Ros1Bag => "ROS 1 bag",
            Layout::Ros2Bag => "ROS 2 bag",
            Layout::Mcap => "MCAP recording",
        }
    }
}

/// One associated frame: its stamp, both image paths and its ground truth if any.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameRecord {
    /// Depth stamp in seconds (TUM, ETH3D, Bonn), or the frame index or number (ICL-NUIM,
    /// 7-Scenes, ScanNet, Replica).
    pub timestamp: f64,
    pub rgb_path: PathBuf,
    pub depth_path: PathBuf,
    /// Ground-truth camera-to-world pose (metres): the frame's pose file, or the nearest
    /// ground-truth stamp within the window.
    pub gt_cam_to_world: Option<DMat4>,
}

/// What a layout's images need beyond decoding to become a [`RawFrame`].
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct FrameConventions {
    /// A raw depth value that also means "no reading", besides 0 (65535 in 7-Scenes).
    pub invalid_depth_raw: Option<u16>,
    /// Intrinsics of the colour camera when its images are not the depth images' pixels
    /// (ScanNet's 1296x968 colour): colour is resampled onto the depth image through them
    /// (same optical centre, as ScanNet's exports assume).
    pub color_intrinsics: Option<Intrinsics>,
    /// The lens of the camera the depth image's pixels belong to (TUM RGB-D's freiburg1
    /// and freiburg2: the colour camera's, which depth is registered to), removed from
    /// both images after decoding (`undistort.rs`); `None` for a pinhole camera.
    pub distortion: Option<Distortion>,
}

/// An opened sequence: the associated frame list, intrinsics and depth scale.
#[derive(Debug, Clone, PartialEq)]
pub struct Sequence {
    pub root: PathBuf,
    pub layout: Layout,
    /// Intrinsics of the full-resolution depth images.
    pub intrinsics: Intrinsics,
    /// Raw depth units per metre.
    pub depth_scale: f32,
    /// Frames in order of depth stamp; positions in this list are "frame numbers".
    pub frames: Vec<FrameRecord>,
    /// How frames are decoded (invalid depth value, colour camera).
    pub conventions: FrameConventions,
    /// What opening decided on the user's behalf (defaults used, frames without ground
    /// truth), one line each, for the command line to print.
    pub notes: Vec<String>,
    /// Where the images are read from when not from disk ([`open_with`]: in memory, the
    /// browser's files); `None` for a sequence opened from a folder.
    pub files: Option<SharedFiles>,
}

/// A sequence's file source, shared by its clones; two are equal when they are the same
/// source.
#[derive(Debug, Clone)]
pub struct SharedFiles(pub std::sync::Arc<dyn DatasetFiles>);

impl PartialEq for SharedFiles {
    fn eq(&self, other: &Self) -> bool {
        std::sync::Arc::ptr_eq(&self.0, &other.0)
    }
}

/// What a layout's own files say about a sequence, before the options apply.
pub(crate) struct Listing {
    /// Frames in order, with ground truth where the layout has it per frame.
    pub frames: Vec<FrameRecord>,
    /// A TUM trajectory to associate with the frames by stamp.
    pub gt_file: Option<PathBuf>,
    /// Intrinsics from the dataset's files (or the layout's published ones).
    pub intrinsics: Option<Intrinsics>,
    /// Why there are none and how to give them, when `intrinsics` is `None`.
    pub no_intrinsics: String,
    /// The depth images' size, for layouts with no other record of it: given intrinsics
    /// take this size.
    pub image_size: Option<(u32, u32)>,
    /// Raw depth units per metre from the dataset or the layout's convention.
    pub depth_scale: Option<f32>,
    pub conventions: FrameConventions,
    pub notes: Vec<String>,
}

/// Opens the sequence in `root`: detects the layout ([`Layout`]), lists and associates the
/// frames, attaches ground truth (`opts.gt_path` > the layout's trajectory file or pose
/// files) and settles intrinsics (override > `camera.json` > the dataset's intrinsics file
/// or the layout's published values; plain TUM has none) and depth scale (override >
/// `camera.json` > the layout's > 5000). Every listed image file must exist; images are
/// only decoded by [`Sequence::load`].
/// A recording (ROS 1 `.bag`, ROS 2 bag folder, `.mcap` file) is read from its messages.
pub fn open(root: &Path, opts: &SequenceOptions) -> Result<Sequence> {
    #[cfg(not(target_arch = "wasm32"))]
    if let Some(layout) = bag::recording_layout(root) {
        checks::max_time_diff(opts)?;
        return bag::open(root, layout, opts);
    }
    open_here(root, opts)
}

/// [`open`] over the files of `files` instead of the disk (every layout, the same checks and
/// errors); the sequence keeps `files` to decode its frames from.
pub fn open_with(
    files: std::sync::Arc<dyn DatasetFiles>,
    root: &Path,
    opts: &SequenceOptions,
) -> Result<Sequence> {
    let seq = source::with_source(&files, || open_here(root, opts))?;
    Ok(Sequence {
        files: Some(SharedFiles(files)),
        ..seq
    })
}

/// [`open`] over the current source ([`source::current`]).
fn open_here(root: &Path, opts: &SequenceOptions) -> Result<Sequence> {
    checks::max_time_diff(opts)?;
    let layout = detect::detect(root)?;
    checks::stamp_order_applies(root, layout, opts)?;
    let camera = camera_json::read(&root.join("camera.json"))?;
    let listing = match layout {
        Layout::Tum | Layout::IclNuim | Layout::Eth3d | Layout::Bonn => {
            stamped::listing(root, layout, opts)?
        }
        Layout::SevenScenes => seven_scenes::list(root)?,
        Layout::ScanNet => scannet::list(root)?,
        Layout::Replica => replica::list(root)?,
        Layout::Ros1Bag | Layout::Ros2Bag | Layout::Mcap => {
            unreachable!("detect() returns folder layouts only")
        }
    };

    let intrinsics = match (opts.intrinsics, &camera, listing.intrinsics) {
        (Some(k), _, _) => match listing.image_size {
            Some((width, height)) => Intrinsics { width, height, ..k },
            None => k,
        },
        (None, Some(c), _) => {
            Intrinsics::from_floats([c.fx, c.fy, c.cx, c.cy], (c.width, c.height))
        }
        (None, None, Some(k)) => k,
        (None, None, None) => {
            return Err(Error::Argument(format!(
                "{}; {}",
                listing.no_intrinsics,
                opts.interface.intrinsics_remedy(layout == Layout::Tum)
            )))
        }
    };
    let source = match (opts.intrinsics, &camera) {
        (Some(_), _) => "--intrinsics".to_string(),
        (None, Some(_)) => root.join("camera.json").display().to_string(),
        (None, None) => format!("the {layout:?} dataset's intrinsics in {}", root.display()),
    };
    checks::intrinsics_in_bounds(&intrinsics, &source)?;
    // The lens comes with the pinhole values: the options', else camera.json's.
    let distortion = match (opts.intrinsics, &camera) {
        (Some(_), _) => opts.distortion,
        (None, Some(c)) => match c.distortion {
            Some(coefficients) => Distortion::from_coefficients(coefficients)
                .map_err(|why| Error::Argument(format!("{source}: {why}")))?,
            None => None,
        },
        (None, None) => listing.conventions.distortion,
    };
    let depth_scale = opts
        .depth_scale
        .or(camera.as_ref().and_then(|c| c.depth_scale))
        .or(listing.depth_scale)
        .unwrap_or(DEFAULT_DEPTH_SCALE);
    if !(depth_scale.is_finite() && depth_scale > 0.0) {
        return Err(Error::Argument(format!(
            "depth scale must be positive, got {depth_scale}"
        )));
    }

    for f in &listing.frames {
        for p in [&f.rgb_path, &f.depth_path] {
            frame::check_image_file(p, "image listed by the dataset")?;
        }
    }

    let frames = listing.frames;
    checks::stamps_distinct(root, &frames)?;
    let mut notes = listing.notes;
    if let Some(d) = &distortion {
        let from = opts.intrinsics.map_or(source.as_str(), |_| "--camera");
        notes.push(camera_json::lens_note(d, from));
    }
    let conventions = FrameConventions {
        distortion,
        ..listing.conventions
    };
    let camera = (intrinsics, depth_scale, conventions);
    let mut seq = Sequence::opened(root, layout, camera, frames, notes);
    tum::attach_ground_truth(
        &mut seq,
        opts.gt_path.as_ref().or(listing.gt_file.as_ref()),
        opts,
    )?;
    Ok(seq)
}

impl Sequence {
    /// A sequence opened from a folder or a recording (a file source other than the disk is
    /// set after); its camera: intrinsics, depth scale and how its frames are decoded.
    pub(crate) fn opened(
        root: &Path,
        layout: Layout,
        (intrinsics, depth_scale, conventions): (Intrinsics, f32, FrameConventions),
        frames: Vec<FrameRecord>,
        notes: Vec<String>,
    ) -> Sequence {
        Sequence {
            root: root.to_path_buf(),
            layout,
            intrinsics,
            depth_scale,
            frames,
            conventions,
            notes,
            files: None,
        }
    }

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

    /// The note on the ground truth's jumps within the frames `range` (a run's, as
    /// [`Sequence::select`] gives it; see `checks::jump_note`): frames outside a run
    /// are not its concern.
    pub fn jump_note(&self, range: RangeInclusive<usize>) -> Option<String> {
        let first = *range.start();
        checks::jump_note(self.frames.get(range)?, first)
    }

    /// Decodes frame `i` (position in [`Sequence::frames`]); checks pixel formats, that
    /// colour and depth have the same size (or resamples colour through the colour camera's
    /// intrinsics, [`FrameConventions`]), and that the size matches the intrinsics; removes
    /// the lens's distortion, if any ([`FrameConventions::distortion`]).
    pub fn load(&self, i: usize) -> Result<RawFrame> {
        let f = self.frames.get(i).ok_or_else(|| {
            Error::Argument(format!(
                "frame {i} is outside the sequence (frames 0..{})",
                self.frames.len().saturating_sub(1)
            ))
        })?;
        let load = || {
            frame::load_frame(
                &f.rgb_path,
                &f.depth_path,
                &self.intrinsics,
                &self.conventions,
            )
        };
        let frame = match &self.files {
            Some(files) => match files.0.frame(&f.rgb_path, &f.depth_path, &self.intrinsics) {
                Some(frame) => frame,
                None => source::with_source(&files.0, load),
            },
            None => load(),
        }?;
        Ok(match &self.conventions.distortion {
            Some(lens) => undistort::undistort(&frame, &self.intrinsics, lens),
            None => frame,
        })
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

    /// Where a run over the whole sequence starts by default: the first frame with ground
    /// truth (ICL-NUIM's frame 0 has none), so the map and trajectory share the ground
    /// truth's world frame; 0 without any.
    pub fn default_first_frame(&self) -> usize {
        self.frames
            .iter()
            .position(|f| f.gt_cam_to_world.is_some())
            .unwrap_or(0)
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
            conventions: FrameConventions::default(),
            notes: Vec::new(),
            files: None,
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
