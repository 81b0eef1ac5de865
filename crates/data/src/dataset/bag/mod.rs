//! Robot recordings read as a sequence: a ROS 1 `.bag` file ([`ros1`]), a ROS 2 bag folder
//! (`metadata.yaml` with one `.mcap` or `.db3` file) or a single `.mcap` file
//! ([`mcap_file`], [`db3`]). One streaming pass lists the topics, the depth and colour
//! messages' stamps and the camera's intrinsics; frames are decoded when
//! [`super::Sequence::load`] asks for them, one message at a time, never the whole file.
//!
//! Depth (`sensor_msgs/Image`, `16UC1` millimetres or `32FC1` metres) and colour (`Image`
//! or `CompressedImage`) are paired by header stamp within the TUM association window;
//! intrinsics (and a `plumb_bob` lens, removed as frames are decoded) come from the depth
//! camera's `sensor_msgs/CameraInfo`. Not read: other message types (tf, IMU, ...), split
//! bags (several files in one folder), other distortion models (a note says so).

pub(crate) mod db3;
pub(crate) mod mcap_file;
pub(crate) mod msg;
mod pixels;
pub(crate) mod ros1;
mod topics;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use super::source::{DatasetFiles, Entry};
use super::{FrameConventions, FrameRecord, Layout, RawFrame, Sequence, SequenceOptions};
use crate::geometry::camera::Intrinsics;
use crate::io::input::InputKind;
use crate::{Error, Result};
use msg::Wire;

/// A topic as its file declares it.
#[derive(Debug, Clone, PartialEq)]
pub struct Channel {
    pub topic: String,
    /// The message type, as written (`sensor_msgs/Image`, `sensor_msgs/msg/Image`).
    pub msg_type: String,
    /// How its messages are serialised; `None` for an encoding wgslam does not decode.
    pub wire: Option<Wire>,
}

/// A recording in one of the formats read: a streaming pass, and one message on demand.
pub(crate) trait Recording: std::fmt::Debug + Send + Sync {
    /// Calls `visit` with every message in the order of the file, one at a time.
    fn scan(&self, visit: &mut dyn FnMut(&Channel, &[u8]) -> Result<()>) -> Result<()>;
    /// The bytes of message `ordinal` (from 0, in the order of [`Recording::scan`]) of
    /// `topic`.
    fn message(&self, topic: &str, ordinal: usize) -> Result<Vec<u8>>;
}

/// Largest message or record read, bytes: the cap of one image file.
pub(crate) fn max_message_bytes() -> Result<u64> {
    InputKind::Image.max_bytes()
}

/// Which kind of recording `root` is, if it is one: a `.bag` file, a `.mcap` file, or a
/// folder with a `metadata.yaml` (a ROS 2 bag).
pub fn recording_layout(root: &Path) -> Option<Layout> {
    let ext = root.extension().and_then(|e| e.to_str()).unwrap_or("");
    if root.is_file() {
        match ext.to_ascii_lowercase().as_str() {
            "bag" => Some(Layout::Ros1Bag),
            "mcap" => Some(Layout::Mcap),
            "db3" => Some(Layout::Ros2Bag),
            _ => None,
        }
    } else if root.is_dir() && root.join("metadata.yaml").is_file() {
        Some(Layout::Ros2Bag)
    } else {
        None
    }
}

/// The recording file of a ROS 2 bag folder: its one `.mcap` or `.db3` file.
fn ros2_file(root: &Path) -> Result<PathBuf> {
    if root.is_file() {
        return Ok(root.to_path_buf());
    }
    let mut files: Vec<PathBuf> = std::fs::read_dir(root)
        .map_err(|e| Error::io(root, e))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            matches!(
                p.extension().and_then(|e| e.to_str()),
                Some("mcap") | Some("db3")
            )
        })
        .collect();
    files.sort();
    match files.len() {
        1 => Ok(files.remove(0)),
        0 => Err(Error::format(
            root,
            "a ROS 2 bag folder (metadata.yaml) without a .mcap or .db3 file",
        )),
        n => Err(Error::format(
            root,
            format!(
                "a ROS 2 bag split into {n} files is not read; merge them into one first \
                 (ros2 bag convert)"
            ),
        )),
    }
}

/// Opens the recording at `root` as a sequence of layout `layout` ([`recording_layout`]).
pub(crate) fn open(root: &Path, layout: Layout, opts: &SequenceOptions) -> Result<Sequence> {
    let recording: Arc<dyn Recording> = match layout {
        Layout::Ros1Bag => Arc::new(ros1::Ros1::open(root)?),
        _ => {
            let file = ros2_file(root)?;
            if file.extension().and_then(|e| e.to_str()) == Some("db3") {
                Arc::new(db3::Db3::open(&file)?)
            } else {
                Arc::new(mcap_file::McapFile::new(&file)?)
            }
        }
    };
    let survey = topics::survey(recording.as_ref(), root)?;
    let choice = topics::choose(&survey, root, opts)?;
    let mut notes = choice.notes.clone();
    // The lens comes with the pinhole values: the options', else the camera info's.
    let (intrinsics, distortion) = match (opts.intrinsics, &choice.camera) {
        (Some(k), _) => (
            Intrinsics {
                width: choice.depth_size.0,
                height: choice.depth_size.1,
                ..k
            },
            opts.distortion,
        ),
        (None, Some(camera)) => *camera,
        (None, None) => {
            return Err(Error::Argument(format!(
                "{}: no sensor_msgs/CameraInfo for the depth topic {}; {}",
                root.display(),
                choice.depth.topic,
                opts.interface.intrinsics_remedy(false)
            )))
        }
    };
    super::checks::intrinsics_in_bounds(&intrinsics, &root.display().to_string())?;
    if let Some(lens) = &distortion {
        let from = match opts.intrinsics {
            Some(_) => "--camera".to_string(),
            None => format!("the camera info of {}", root.display()),
        };
        notes.push(super::camera_json::lens_note(lens, &from));
    }
    let depth_scale = opts.depth_scale.unwrap_or(choice.depth_scale);
    if !(depth_scale.is_finite() && depth_scale > 0.0) {
        return Err(Error::Argument(format!(
            "depth scale must be positive, got {depth_scale}"
        )));
    }
    let frames = pair(root, &choice, opts.max_time_diff, &mut notes);
    if frames.is_empty() {
        return Err(Error::format(
            root,
            format!(
                "no depth message of {} has a colour message within {} s",
                choice.depth.topic, opts.max_time_diff
            ),
        ));
    }
    super::checks::stamps_distinct(root, &frames)?;
    let conventions = FrameConventions {
        distortion,
        ..FrameConventions::default()
    };
    let camera = (intrinsics, depth_scale, conventions);
    let mut seq = Sequence::opened(root, layout, camera, frames, notes);
    let source = BagFrames {
        recording,
        depth_topic: choice.depth.topic.clone(),
        color: choice.color.clone().map(|c| (c.topic, c.compressed)),
        wires: survey.wires(),
        depth_scale,
    };
    super::tum::attach_ground_truth(&mut seq, opts.gt_path.as_ref(), opts)?;
    seq.files = Some(super::SharedFiles(Arc::new(source)));
    Ok(seq)
}

/// The frame list: each depth message (by stamp) with the nearest colour message within
/// `max_dt`; a depth message without one is left out (a note counts them).
fn pair(
    root: &Path,
    choice: &topics::Choice,
    max_dt: f64,
    notes: &mut Vec<String>,
) -> Vec<FrameRecord> {
    let name = |topic: &str, ordinal: usize| {
        PathBuf::from(format!("{}:{topic}#{ordinal}", root.display()))
    };
    let mut depth: Vec<(f64, usize)> = choice.depth.stamps.iter().copied().zip(0..).collect();
    depth.sort_by(|a, b| a.0.total_cmp(&b.0));
    let color: Option<(Vec<f64>, Vec<usize>)> = choice.color.as_ref().map(|c| {
        let mut by_stamp: Vec<(f64, usize)> = c.stamps.iter().copied().zip(0..).collect();
        by_stamp.sort_by(|a, b| a.0.total_cmp(&b.0));
        by_stamp.into_iter().unzip()
    });
    let mut frames = Vec::with_capacity(depth.len());
    for &(t, d) in &depth {
        let rgb_path = match (&choice.color, &color) {
            (Some(c), Some((stamps, ordinals))) => {
                match super::tum::nearest_within(stamps, t, max_dt) {
                    Some(k) => name(&c.topic, ordinals[k]),
                    None => continue,
                }
            }
            _ => name("", 0),
        };
        frames.push(FrameRecord {
            timestamp: t,
            rgb_path,
            depth_path: name(&choice.depth.topic, d),
            gt_cam_to_world: None,
        });
    }
    let unpaired = depth.len() - frames.len();
    if unpaired > 0 {
        notes.push(format!(
            "{unpaired} of {} depth messages have no colour message within {max_dt} s and \
             are left out",
            depth.len()
        ));
    }
    frames
}

/// The ordinal of a frame path `pair` made (`<root>:<topic>#<ordinal>`).
fn ordinal_of(path: &Path) -> Result<usize> {
    path.to_str()
        .and_then(|s| s.rsplit_once('#'))
        .and_then(|(_, n)| n.parse().ok())
        .ok_or_else(|| Error::format(path, "not a message of the recording"))
}

/// A recording as the source of a sequence's frames: decodes the depth and colour messages
/// a frame names.
#[derive(Debug)]
struct BagFrames {
    recording: Arc<dyn Recording>,
    depth_topic: String,
    /// The colour topic and whether it is a `CompressedImage`; `None`: grey colour.
    color: Option<(String, bool)>,
    wires: BTreeMap<String, Wire>,
    /// Raw units per metre a `32FC1` image is converted at.
    depth_scale: f32,
}

/// Colour of every pixel of a recording without a colour topic (mid-grey).
const NO_COLOR_GREY: [u8; 3] = [128; 3];

impl BagFrames {
    fn decode(&self, rgb: &Path, depth: &Path, k: &Intrinsics) -> Result<RawFrame> {
        let wire = |t: &str| self.wires.get(t).copied().unwrap_or(Wire::Cdr);
        let bytes = self
            .recording
            .message(&self.depth_topic, ordinal_of(depth)?)?;
        fn why(path: &Path) -> impl Fn(String) -> Error + '_ {
            move |what| Error::Image {
                path: path.to_path_buf(),
                what,
            }
        }
        let img = msg::image(&bytes, wire(&self.depth_topic)).map_err(why(depth))?;
        let (w, h) = (img.width, img.height);
        if (w, h) != (k.width, k.height) {
            return Err(why(depth)(format!(
                "depth image is {w}x{h} but the intrinsics are for {}x{}",
                k.width, k.height
            )));
        }
        let depth_px = pixels::depth_scaled(&img, Some(self.depth_scale)).map_err(why(depth))?;
        let rgb_px = match &self.color {
            None => vec![NO_COLOR_GREY; depth_px.len()],
            Some((topic, compressed)) => {
                let bytes = self.recording.message(topic, ordinal_of(rgb)?)?;
                let (cw, ch, px) =
                    pixels::any_color(&bytes, wire(topic), *compressed).map_err(why(rgb))?;
                if (cw, ch) != (w, h) {
                    return Err(why(rgb)(format!(
                        "colour image is {cw}x{ch} but its depth image is {w}x{h}"
                    )));
                }
                px
            }
        };
        Ok(RawFrame {
            width: w,
            height: h,
            depth: depth_px,
            rgb: rgb_px,
        })
    }
}

impl DatasetFiles for BagFrames {
    fn entry(&self, _path: &Path) -> std::io::Result<Entry> {
        Err(std::io::Error::new(
            std::io::ErrorKind::NotFound,
            "a recording's frames are messages, not files",
        ))
    }
    fn list(&self, _dir: &Path) -> std::io::Result<Vec<PathBuf>> {
        self.entry(_dir).map(|_| Vec::new())
    }
    fn read(&self, path: &Path, _kind: InputKind) -> Result<Vec<u8>> {
        Err(Error::io(path, self.entry(path).unwrap_err()))
    }
    fn frame(&self, rgb: &Path, depth: &Path, depth_k: &Intrinsics) -> Option<Result<RawFrame>> {
        Some(self.decode(rgb, depth, depth_k))
    }
}

/// Where the `ordinal`-th message of `topic` is, from a recording's per-topic index (a
/// `.db3`'s row ids, a ROS 1 bag's chunk places); an error naming the recording at `path`
/// when it has no such message.
fn nth_message<T: Copy>(
    index: &std::sync::Mutex<std::collections::HashMap<String, Vec<T>>>,
    topic: &str,
    ordinal: usize,
    path: &Path,
) -> Result<T> {
    index
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .get(topic)
        .and_then(|at| at.get(ordinal).copied())
        .ok_or_else(|| Error::format(path, format!("no message {ordinal} of {topic}")))
}
