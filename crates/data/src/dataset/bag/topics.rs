//! A recording's topics: one streaming pass that counts every topic's messages and keeps
//! the image topics' stamps and encodings and the first `CameraInfo` of each camera
//! ([`survey`]), then the choice of the depth, colour and camera-info topics ([`choose`]):
//! the user's `--depth-topic` / `--color-topic`, or the only candidate of each kind.

use std::collections::BTreeMap;
use std::path::Path;

use super::msg::{self, Wire};
use super::{Channel, Recording};
use crate::dataset::SequenceOptions;
use crate::geometry::camera::{Distortion, Intrinsics};
use crate::{Error, Result};

/// What a topic's messages are, as far as frames go.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    Image,
    Compressed,
    CameraInfo,
    Other,
}

fn kind_of(channel: &Channel) -> Kind {
    if channel.wire.is_none() {
        return Kind::Other;
    }
    match channel.msg_type.replace("/msg/", "/").as_str() {
        "sensor_msgs/Image" => Kind::Image,
        "sensor_msgs/CompressedImage" => Kind::Compressed,
        "sensor_msgs/CameraInfo" => Kind::CameraInfo,
        _ => Kind::Other,
    }
}

/// One topic after the pass.
#[derive(Debug, Clone)]
pub struct TopicSurvey {
    channel: Channel,
    kind: Kind,
    count: usize,
    /// The first message's encoding (`Image`) or format (`CompressedImage`).
    encoding: String,
    /// The first image's width and height.
    size: (u32, u32),
    /// Header stamps of an image topic's messages, in file order.
    stamps: Vec<f64>,
    /// The first `CameraInfo` of a camera-info topic.
    info: Option<msg::CameraInfo>,
}

/// Every topic of a recording, by name.
#[derive(Debug, Default)]
pub struct Survey {
    topics: BTreeMap<String, TopicSurvey>,
}

impl Survey {
    /// Each decodable topic's wire format.
    pub fn wires(&self) -> BTreeMap<String, Wire> {
        self.topics
            .iter()
            .filter_map(|(t, s)| Some((t.clone(), s.channel.wire?)))
            .collect()
    }
}

/// Reads every message's header once (images are not decoded): counts, stamps, encodings,
/// camera infos. A message of an image or camera-info topic that does not decode is an
/// error naming the topic and the message.
pub fn survey(recording: &dyn Recording, root: &Path) -> Result<Survey> {
    let mut s = Survey::default();
    recording.scan(&mut |channel, bytes| {
        let t = s
            .topics
            .entry(channel.topic.clone())
            .or_insert_with(|| TopicSurvey {
                channel: channel.clone(),
                kind: kind_of(channel),
                count: 0,
                encoding: String::new(),
                size: (0, 0),
                stamps: Vec::new(),
                info: None,
            });
        let n = t.count;
        t.count += 1;
        let wire = channel.wire.unwrap_or(Wire::Cdr);
        let bad = |why: String| {
            Error::format(
                root,
                format!(
                    "message {n} of topic {} ({}): {why}",
                    channel.topic, channel.msg_type
                ),
            )
        };
        match t.kind {
            Kind::Image => {
                let img = msg::image(bytes, wire).map_err(bad)?;
                if n == 0 {
                    t.encoding = img.encoding.clone();
                    t.size = (img.width, img.height);
                }
                t.stamps.push(img.stamp);
            }
            Kind::Compressed => {
                let c = msg::compressed(bytes, wire).map_err(bad)?;
                if n == 0 {
                    t.encoding = c.format.clone();
                }
                t.stamps.push(c.stamp);
            }
            Kind::CameraInfo if n == 0 => {
                t.info = Some(msg::camera_info(bytes, wire).map_err(bad)?)
            }
            _ => {}
        }
        Ok(())
    })?;
    Ok(s)
}

/// A chosen image topic.
#[derive(Debug, Clone)]
pub struct Chosen {
    pub topic: String,
    pub stamps: Vec<f64>,
    pub compressed: bool,
}

/// The topics a sequence is read from, and what they say.
#[derive(Debug, Clone)]
pub struct Choice {
    pub depth: Chosen,
    pub color: Option<Chosen>,
    /// Width and height of the depth images.
    pub depth_size: (u32, u32),
    /// Intrinsics from the depth camera's `CameraInfo`, if there is one, and its lens
    /// (`plumb_bob` coefficients that are not all zero).
    pub camera: Option<(Intrinsics, Option<Distortion>)>,
    /// Raw units per metre: 1000 for `16UC1` (millimetres), [`FLOAT_DEPTH_SCALE`] for
    /// `32FC1`.
    pub depth_scale: f32,
    pub notes: Vec<String>,
}

/// Raw units per metre `32FC1` depth (metres) is stored at: the TUM benchmark's 5000
/// (0.2 mm steps, up to 13.1 m), so millimetre depth written as float metres comes back
/// exactly (5 units a millimetre); `--depth-scale` chooses another.
pub const FLOAT_DEPTH_SCALE: f32 = 5000.0;

fn is_depth(t: &TopicSurvey) -> bool {
    t.kind == Kind::Image && matches!(t.encoding.as_str(), "16UC1" | "32FC1")
}

fn is_color(t: &TopicSurvey) -> bool {
    match t.kind {
        Kind::Image => matches!(
            t.encoding.as_str(),
            "rgb8" | "bgr8" | "rgba8" | "bgra8" | "mono8"
        ),
        Kind::Compressed => !t.encoding.contains("compressedDepth"),
        _ => false,
    }
}

/// The image topics, a line each, for an error that asks the user to choose.
fn listing(s: &Survey) -> String {
    let lines: Vec<String> = s
        .topics
        .values()
        .filter(|t| matches!(t.kind, Kind::Image | Kind::Compressed))
        .map(|t| {
            format!(
                "  {} ({}, {}, {} messages)",
                t.channel.topic,
                t.channel.msg_type,
                if t.encoding.is_empty() {
                    "-"
                } else {
                    &t.encoding
                },
                t.count
            )
        })
        .collect();
    if lines.is_empty() {
        "  (no sensor_msgs/Image or CompressedImage topic)".into()
    } else {
        lines.join("\n")
    }
}

/// The one topic of a kind: the user's, or the only candidate.
fn pick<'a>(
    s: &'a Survey,
    root: &Path,
    given: Option<&str>,
    role: &str,
    fits: fn(&TopicSurvey) -> bool,
    required: bool,
) -> Result<Option<&'a TopicSurvey>> {
    let flag = format!("--{role}-topic");
    let fail = |why: String| {
        Error::format(
            root,
            format!(
                "{why}; the image topics are:\n{}\npass {flag} TOPIC (depth: sensor_msgs/Image \
                 16UC1 or 32FC1; colour: Image rgb8, bgr8, rgba8, bgra8, mono8 or a JPEG/PNG \
                 CompressedImage)",
                listing(s)
            ),
        )
    };
    if let Some(name) = given {
        return match s.topics.get(name) {
            Some(t) if fits(t) => Ok(Some(t)),
            Some(_) => Err(fail(format!(
                "topic {name} is not a {role} image topic wgslam reads"
            ))),
            None => Err(fail(format!("the recording has no topic {name}"))),
        };
    }
    let found: Vec<&TopicSurvey> = s.topics.values().filter(|t| fits(t)).collect();
    match found.len() {
        1 => Ok(Some(found[0])),
        0 if !required => Ok(None),
        0 => Err(fail(format!("no {role} image topic"))),
        n => Err(fail(format!(
            "{n} {role} image topics, which to use is not clear"
        ))),
    }
}

/// Chooses the depth topic (exactly one, or `--depth-topic`), the colour topic (at most
/// one, or `--color-topic`) and the depth camera's `CameraInfo`.
pub fn choose(s: &Survey, root: &Path, opts: &SequenceOptions) -> Result<Choice> {
    let depth = pick(
        s,
        root,
        opts.depth_topic.as_deref(),
        "depth",
        is_depth,
        true,
    )?
    .expect("a required topic");
    let color = pick(
        s,
        root,
        opts.color_topic.as_deref(),
        "color",
        is_color,
        false,
    )?;
    let chosen = |t: &TopicSurvey| Chosen {
        topic: t.channel.topic.clone(),
        stamps: t.stamps.clone(),
        compressed: t.kind == Kind::Compressed,
    };
    let mut notes = vec![format!(
        "depth from {} ({}, {} messages); {}",
        depth.channel.topic,
        depth.encoding,
        depth.count,
        match color {
            Some(c) => format!(
                "colour from {} ({}, {} messages)",
                c.channel.topic, c.encoding, c.count
            ),
            None => "no colour topic: the map is grey".into(),
        }
    )];
    let camera = camera_of(s, root, depth, &mut notes)?;
    Ok(Choice {
        depth: chosen(depth),
        color: color.map(chosen),
        depth_size: depth.size,
        camera,
        depth_scale: if depth.encoding == "16UC1" {
            1000.0
        } else {
            FLOAT_DEPTH_SCALE
        },
        notes,
    })
}

/// The depth camera's intrinsics and lens: the `camera_info` beside the depth topic, else
/// the only `CameraInfo` topic; its size must be the depth images'. A `plumb_bob` lens (the
/// Brown-Conrady model, [`Distortion`]) is removed from the frames as they are decoded;
/// another model is ignored, with a note.
fn camera_of(
    s: &Survey,
    root: &Path,
    depth: &TopicSurvey,
    notes: &mut Vec<String>,
) -> Result<Option<(Intrinsics, Option<Distortion>)>> {
    let sibling = match depth.channel.topic.rsplit_once('/') {
        Some((parent, _)) => format!("{parent}/camera_info"),
        None => "camera_info".into(),
    };
    let infos: Vec<&TopicSurvey> = s.topics.values().filter(|t| t.info.is_some()).collect();
    let Some(t) = s
        .topics
        .get(&sibling)
        .filter(|t| t.info.is_some())
        .or(if infos.len() == 1 {
            Some(infos[0])
        } else {
            None
        })
    else {
        return Ok(None);
    };
    let info = t.info.as_ref().expect("filtered on info");
    let (w, h) = depth.size;
    if (info.width, info.height) != (w, h) && (info.width, info.height) != (0, 0) {
        return Err(Error::format(
            root,
            format!(
                "the camera info on {} is for {}x{} images but the depth images of {} are \
                 {w}x{h}; pass --intrinsics fx,fy,cx,cy for them",
                t.channel.topic, info.width, info.height, depth.channel.topic
            ),
        ));
    }
    let lens = match info.distortion_model.as_str() {
        // No coefficients, or all zero, is a pinhole camera whatever the model says.
        _ if info.d.iter().all(|&d| d == 0.0) => None,
        "plumb_bob" | "" if info.d.len() == 5 => {
            let c = [info.d[0], info.d[1], info.d[2], info.d[3], info.d[4]];
            Distortion::from_coefficients(c).map_err(|why| {
                Error::format(
                    root,
                    format!("the camera info on {}: {why}", t.channel.topic),
                )
            })?
        }
        _ => {
            notes.push(format!(
                "the camera info on {} has distortion ({:?}, coefficients {:?}) of a model \
                 wgslam does not remove (it removes plumb_bob's five): it is ignored \
                 (pinhole projection); undistort the images before recording for the best \
                 maps",
                t.channel.topic, info.distortion_model, info.d
            ));
            None
        }
    };
    notes.push(format!("intrinsics from {}", t.channel.topic));
    let k = &info.k;
    let pinhole =
        Intrinsics::from_floats([k[0] as f32, k[4] as f32, k[2] as f32, k[5] as f32], (w, h));
    Ok(Some((pinhole, lens)))
}
