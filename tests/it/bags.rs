//! Recordings as robots write them (`wgslam::dataset`'s bag readers): the bundled frames
//! written into an MCAP file by the `mcap` crate's own writer, with `sensor_msgs`
//! messages serialised here by hand in CDR (so the reader's decoding is checked against
//! bytes it did not write), track to exactly the folder's poses; two depth topics ask
//! which; a truncated or foreign file is a clear error. The ROS 1 `.bag` and ROS 2 `.db3`
//! forms are written by the Python `rosbags` package in `python/tests/test_bags.py`.

use crate::common;

use std::collections::BTreeMap;
use std::path::Path;

use common::cli::{ok, text, wgslam};
use common::harness::plain;
use wgslam::dataset::{self, Layout, RawFrame, SequenceOptions};
use wgslam::geometry::camera::Intrinsics;
use wgslam::slam::params::{Profile, SlamParams};

/// Bundled frames written into the recordings: 0 has no ground truth, so runs start at 1.
const FRAMES: std::ops::RangeInclusive<usize> = 0..=4;

/// A CDR (XCDR1, little-endian) message under construction.
struct Cdr(Vec<u8>);

impl Cdr {
    fn new() -> Cdr {
        Cdr(vec![0, 1, 0, 0])
    }
    fn align(&mut self, n: usize) {
        while (self.0.len() - 4) % n != 0 {
            self.0.push(0);
        }
    }
    fn u32(&mut self, v: u32) -> &mut Self {
        self.align(4);
        self.0.extend(v.to_le_bytes());
        self
    }
    fn f64(&mut self, v: f64) -> &mut Self {
        self.align(8);
        self.0.extend(v.to_le_bytes());
        self
    }
    fn string(&mut self, s: &str) -> &mut Self {
        self.u32(s.len() as u32 + 1);
        self.0.extend(s.as_bytes());
        self.0.push(0);
        self
    }
    fn bytes(&mut self, b: &[u8]) -> &mut Self {
        self.u32(b.len() as u32);
        self.0.extend(b);
        self
    }
    /// `std_msgs/Header` at `stamp` whole seconds.
    fn header(&mut self, stamp: u32) -> &mut Self {
        self.u32(stamp).u32(0).string("camera")
    }
}

/// `sensor_msgs/Image` in CDR.
fn image_msg(stamp: u32, (w, h): (u32, u32), encoding: &str, bpp: u32, data: &[u8]) -> Vec<u8> {
    let mut m = Cdr::new();
    m.header(stamp).u32(h).u32(w).string(encoding);
    m.0.push(0); // is_bigendian
    m.u32(w * bpp).bytes(data);
    m.0
}

/// `sensor_msgs/CompressedImage` in CDR holding `rgb` as a PNG.
fn png_msg(stamp: u32, (w, h): (u32, u32), rgb: Vec<u8>) -> Vec<u8> {
    let mut png = Vec::new();
    image::RgbImage::from_raw(w, h, rgb)
        .unwrap()
        .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .unwrap();
    let mut m = Cdr::new();
    m.header(stamp).string("png").bytes(&png);
    m.0
}

/// `sensor_msgs/CameraInfo` in CDR, every field; `lens`: the distortion model and its
/// coefficients.
fn camera_info_msg(k: &Intrinsics, (model, coefficients): (&str, &[f64])) -> Vec<u8> {
    let mut m = Cdr::new();
    m.header(0).u32(k.height).u32(k.width).string(model);
    m.u32(coefficients.len() as u32);
    for &d in coefficients {
        m.f64(d);
    }
    let kk = [
        k.fx as f64,
        0.0,
        k.cx as f64,
        0.0,
        k.fy as f64,
        k.cy as f64,
        0.0,
        0.0,
        1.0,
    ];
    let r = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
    for v in kk.iter().chain(&r) {
        m.f64(*v);
    }
    for i in 0..12 {
        m.f64(if i % 4 == 3 {
            0.0
        } else {
            kk.get(i - i / 4).copied().unwrap_or(0.0)
        });
    }
    m.u32(0).u32(0); // binning
    m.u32(0).u32(0).u32(0).u32(0); // roi
    m.0.push(0); // do_rectify
    m.0
}

/// Depth as `32FC1` metres (`raw / scale`, 0 = NaN) or `16UC1` raw units.
fn depth_bytes(f: &RawFrame, float_scale: Option<f32>) -> Vec<u8> {
    match float_scale {
        Some(scale) => f
            .depth
            .iter()
            .flat_map(|&d| {
                let m = if d == 0 { f32::NAN } else { d as f32 / scale };
                m.to_le_bytes()
            })
            .collect(),
        None => f.depth.iter().flat_map(|d| d.to_le_bytes()).collect(),
    }
}

/// What an MCAP fixture holds besides the frames.
#[derive(Default)]
struct McapOptions {
    /// Write depth a second time on another topic.
    second_depth: bool,
    /// Colour as a PNG `sensor_msgs/CompressedImage` instead of a raw `rgb8` `Image`.
    png_color: bool,
    /// The camera info's lens: `None` a pinhole `plumb_bob` (five zeros).
    lens: Option<(&'static str, &'static [f64])>,
    compression: Option<mcap::Compression>,
}

/// Writes `frames` (stamp = frame number) into `path` with the `mcap` crate's writer:
/// depth as `32FC1` on `/camera/depth/image_raw`, colour as `rgb8` on
/// `/camera/rgb/image_raw`, the intrinsics on `/camera/depth/camera_info`, and a topic
/// of another type that must be ignored.
fn write_mcap(path: &Path, seq: &dataset::Sequence, frames: &[usize], o: &McapOptions) {
    let file = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
    let mut w = mcap::WriteOptions::new()
        .compression(o.compression)
        .create(file)
        .unwrap();
    let none = BTreeMap::new();
    let mut channel = |ty: &str, topic: &str| {
        let schema = w.add_schema(ty, "ros2msg", b"").unwrap();
        w.add_channel(schema, topic, "cdr", &none).unwrap()
    };
    let depth = channel("sensor_msgs/msg/Image", "/camera/depth/image_raw");
    let color_type = if o.png_color {
        "sensor_msgs/msg/CompressedImage"
    } else {
        "sensor_msgs/msg/Image"
    };
    let color = channel(color_type, "/camera/rgb/image_raw");
    let info = channel("sensor_msgs/msg/CameraInfo", "/camera/depth/camera_info");
    let imu = channel("sensor_msgs/msg/Imu", "/imu");
    let depth2 = o
        .second_depth
        .then(|| channel("sensor_msgs/msg/Image", "/camera2/depth"));
    let mut seq_no = 0;
    let mut put = |w: &mut mcap::Writer<_>, channel_id, t: u64, data: &[u8]| {
        seq_no += 1;
        let header = mcap::records::MessageHeader {
            channel_id,
            sequence: seq_no,
            log_time: t,
            publish_time: t,
        };
        w.write_to_known_channel(&header, data).unwrap();
    };
    let lens = o.lens.unwrap_or(("plumb_bob", &[0.0; 5]));
    put(&mut w, info, 0, &camera_info_msg(&seq.intrinsics, lens));
    for &i in frames {
        let f = seq.load(i).unwrap();
        let size = (f.width, f.height);
        let stamp = seq.frames[i].timestamp as u32;
        let t = u64::from(stamp) * 1_000_000_000;
        let rgb: Vec<u8> = f.rgb.iter().flatten().copied().collect();
        let color_msg = if o.png_color {
            png_msg(stamp, size, rgb)
        } else {
            image_msg(stamp, size, "rgb8", 3, &rgb)
        };
        put(&mut w, color, t, &color_msg);
        let d = depth_bytes(&f, Some(seq.depth_scale));
        put(
            &mut w,
            depth,
            t + 1,
            &image_msg(stamp, size, "32FC1", 4, &d),
        );
        put(&mut w, imu, t + 2, b"not decoded");
        if let Some(d2) = depth2 {
            let d = depth_bytes(&f, None);
            put(&mut w, d2, t + 3, &image_msg(stamp, size, "16UC1", 2, &d));
        }
    }
    w.finish().unwrap();
}

fn bundled() -> dataset::Sequence {
    common::open_asset("icl_living_room_kt2")
}

fn with_gt() -> SequenceOptions {
    SequenceOptions {
        gt_path: Some(common::bundled_icl().join("livingRoom2.gt.freiburg")),
        ..SequenceOptions::default()
    }
}

/// The MCAP form of the bundled frames (zstd chunks) opens with the folder's intrinsics,
/// depth scale, stamps, pixels and ground truth, and tracks to the same poses to the last
/// bit on the CPU backend: `32FC1` metres of depth quantised at 5000 per metre convert
/// back exactly.
fn mcap_tracks_to_the_folders_poses() {
    let d = common::temp_dir("bags-mcap");
    let folder = bundled();
    let frames: Vec<usize> = FRAMES.collect();
    let path = d.join("frames.mcap");
    let o = McapOptions {
        compression: Some(mcap::Compression::Zstd),
        ..McapOptions::default()
    };
    write_mcap(&path, &folder, &frames, &o);
    let bag = dataset::open(&path, &with_gt()).unwrap();
    assert_eq!(bag.layout, Layout::Mcap);
    assert_eq!(bag.intrinsics, folder.intrinsics);
    assert_eq!(bag.depth_scale, folder.depth_scale);
    assert_eq!(bag.len(), frames.len());
    assert!(
        bag.notes
            .iter()
            .any(|n| n.contains("/camera/depth/image_raw") && n.contains("/camera/rgb/image_raw")),
        "{:?}",
        bag.notes
    );
    for i in [0, frames.len() - 1, 1] {
        assert_eq!(bag.load(i).unwrap(), folder.load(i).unwrap(), "frame {i}");
        assert_eq!(bag.frames[i].timestamp, folder.frames[i].timestamp);
        assert_eq!(
            bag.frames[i].gt_cam_to_world,
            folder.frames[i].gt_cam_to_world
        );
    }
    let (first, last) = (1, *FRAMES.end());
    let params = || SlamParams::profile(Profile::Robust);
    let on_folder = common::run_cpu(&folder, first, last, params()).unwrap();
    let on_bag = common::run_cpu(&bag, first, last, params()).unwrap();
    assert_eq!(on_bag.trajectory(), on_folder.trajectory(), "same poses");
}

/// A lens of a model wgslam does not remove (`rational_polynomial`'s eight coefficients).
const OTHER_LENS: (&str, &[f64]) = (
    "rational_polynomial",
    &[0.1, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
);
/// A `plumb_bob` lens, removed as the frames are decoded.
const PLUMB_BOB_LENS: [f64; 5] = [0.1, -0.05, 0.001, 0.0, 0.0];

/// `wgslam run INPUT --backend cpu --frames 1..2 --out OUT [--gt GT]`, which must succeed;
/// what it printed.
fn run_frames_1_to_2(input: &Path, out: &Path, gt: Option<&Path>) -> String {
    let mut args: Vec<&std::ffi::OsStr> = ["run"].map(std::ffi::OsStr::new).to_vec();
    args.push(input.as_os_str());
    args.extend(["--backend", "cpu", "--frames", "1..2", "--out"].map(std::ffi::OsStr::new));
    args.push(out.as_os_str());
    if let Some(gt) = gt {
        args.extend([std::ffi::OsStr::new("--gt"), gt.as_os_str()]);
    }
    let o = ok(wgslam(&args));
    text(&o)
}

/// The runs written into `a` and `b` have the same `trajectory.tum`, byte for byte.
fn assert_same_trajectory(a: &Path, b: &Path) {
    let traj = |dir: &Path| std::fs::read(dir.join("trajectory.tum")).unwrap();
    assert_eq!(traj(a), traj(b), "{} and {}", a.display(), b.display());
}

/// `wgslam run` reads an `.mcap` as it reads a folder: the same trajectory.tum, byte for
/// byte, and the topics named; a lens of another model than `plumb_bob` is named as
/// ignored.
fn run_on_an_mcap_writes_the_folders_trajectory() {
    let d = common::temp_dir("bags-run");
    let path = d.join("frames.mcap");
    let o = McapOptions {
        lens: Some(OTHER_LENS),
        ..McapOptions::default()
    };
    write_mcap(&path, &bundled(), &[0, 1, 2], &o);
    let gt = common::bundled_icl().join("livingRoom2.gt.freiburg");
    let said = run_frames_1_to_2(&path, &d.join("bag"), Some(&gt));
    assert!(said.contains("/camera/depth/image_raw"), "{said}");
    assert!(said.contains("ignored"), "{said}");
    run_frames_1_to_2(&common::bundled_icl(), &d.join("folder"), None);
    assert_same_trajectory(&d.join("bag"), &d.join("folder"));
}

/// A `plumb_bob` lens in the camera info is removed as the frames are decoded, as the same
/// lens in a folder's `camera.json` is: the same trajectory.tum, byte for byte.
fn a_plumb_bob_lens_is_removed_as_camera_json_s() {
    let d = common::temp_dir("bags-lens");
    let path = d.join("frames.mcap");
    let o = McapOptions {
        lens: Some(("plumb_bob", &PLUMB_BOB_LENS)),
        ..McapOptions::default()
    };
    write_mcap(&path, &bundled(), &[0, 1, 2], &o);
    let folder = d.join("folder");
    std::fs::create_dir_all(&folder).unwrap();
    let src = common::bundled_icl();
    for f in ["associations.txt", "livingRoom2.gt.freiburg"] {
        std::fs::copy(src.join(f), folder.join(f)).unwrap();
    }
    for sub in ["depth", "rgb"] {
        std::fs::create_dir_all(folder.join(sub)).unwrap();
        for i in 0..3 {
            let name = format!("{i}.png");
            std::fs::copy(src.join(sub).join(&name), folder.join(sub).join(&name)).unwrap();
        }
    }
    let k = bundled().intrinsics;
    let [k1, k2, p1, p2, k3] = PLUMB_BOB_LENS;
    std::fs::write(
        folder.join("camera.json"),
        format!(
            r#"{{"width": {}, "height": {}, "fx": {}, "fy": {}, "cx": {}, "cy": {}, "distortion": [{k1}, {k2}, {p1}, {p2}, {k3}]}}"#,
            k.width, k.height, k.fx, k.fy, k.cx, k.cy
        ),
    )
    .unwrap();
    std::fs::write(
        folder.join("associations.txt"),
        "0 depth/0.png 0 rgb/0.png\n1 depth/1.png 1 rgb/1.png\n2 depth/2.png 2 rgb/2.png\n",
    )
    .unwrap();
    let gt = src.join("livingRoom2.gt.freiburg");
    let said = run_frames_1_to_2(&path, &d.join("bag-out"), Some(&gt));
    assert!(
        said.contains("lens distortion k1 0.1") && said.contains("camera info"),
        "{said}"
    );
    let said = run_frames_1_to_2(&folder, &d.join("folder-out"), Some(&gt));
    assert!(
        said.contains("lens distortion k1 0.1") && said.contains("camera.json"),
        "{said}"
    );
    assert_same_trajectory(&d.join("bag-out"), &d.join("folder-out"));
}

/// Two depth topics: the error lists the image topics with type, encoding and count and
/// names the flag; the flag chooses. (Colour here is PNG `CompressedImage`s, lz4 chunks.)
fn two_depth_topics_ask_which() {
    let d = common::temp_dir("bags-two-depth");
    let path = d.join("two.mcap");
    let o = McapOptions {
        second_depth: true,
        png_color: true,
        compression: Some(mcap::Compression::Lz4),
        ..McapOptions::default()
    };
    write_mcap(&path, &bundled(), &[0, 1], &o);
    let e = dataset::open(&path, &SequenceOptions::default())
        .unwrap_err()
        .to_string();
    for want in [
        "2 depth image topics",
        "/camera/depth/image_raw (sensor_msgs/msg/Image, 32FC1, 2 messages)",
        "/camera2/depth (sensor_msgs/msg/Image, 16UC1, 2 messages)",
        "--depth-topic",
    ] {
        assert!(e.contains(want), "{want:?} not in {e}");
    }
    let chosen = SequenceOptions {
        depth_topic: Some("/camera2/depth".into()),
        ..SequenceOptions::default()
    };
    let seq = dataset::open(&path, &chosen).unwrap();
    assert_eq!(seq.depth_scale, 1000.0, "16UC1 is millimetres");
    let (got, want) = (seq.load(1).unwrap(), bundled().load(1).unwrap());
    assert_eq!(got.depth, want.depth, "16UC1 as written");
    assert_eq!(got.rgb, want.rgb, "PNG colour is lossless");
    let e = dataset::open(
        &path,
        &SequenceOptions {
            depth_topic: Some("/imu".into()),
            ..SequenceOptions::default()
        },
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("/imu is not a depth image topic"), "{e}");
}

/// A recording cut short, with a byte run overwritten, or of another format, is an error
/// that names it; never a panic.
fn truncated_corrupt_and_foreign_recordings_are_refused() {
    let d = common::temp_dir("bags-bad");
    let path = d.join("good.mcap");
    write_mcap(&path, &bundled(), &[0, 1], &McapOptions::default());
    let bytes = std::fs::read(&path).unwrap();
    let cases: Vec<(&str, Vec<u8>)> = vec![
        ("cut.mcap", bytes[..bytes.len() / 2].to_vec()),
        ("empty.mcap", Vec::new()),
        (
            "foreign.mcap",
            b"ply\nformat ascii 1.0\nend_header\n".to_vec(),
        ),
        ("garbled.mcap", {
            let mut b = bytes.clone();
            let n = b.len();
            b[n / 3..n / 3 + 64].fill(0xA5);
            b
        }),
        ("foreign.bag", b"#ROSBAG V2.0\nnot really".to_vec()),
        ("foreign.db3", b"SQLite format 3\0 but not".to_vec()),
    ];
    for (name, b) in cases {
        let p = d.join(name);
        std::fs::write(&p, b).unwrap();
        let opened = dataset::open(&p, &SequenceOptions::default());
        let e = match opened {
            Err(e) => e.to_string(),
            // A corruption inside a message's pixels shows when the frame is decoded.
            Ok(seq) => match (0..seq.len()).map(|i| seq.load(i)).find(|r| r.is_err()) {
                Some(Err(e)) => e.to_string(),
                _ => panic!("{name} read without an error"),
            },
        };
        assert!(e.contains(name), "{name}: {e}");
    }
    let ros2 = d.join("ros2_bag");
    std::fs::create_dir(&ros2).unwrap();
    std::fs::write(
        ros2.join("metadata.yaml"),
        "rosbag2_bagfile_information: {}\n",
    )
    .unwrap();
    let e = dataset::open(&ros2, &SequenceOptions::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("without a .mcap or .db3"), "{e}");
    std::fs::copy(&path, ros2.join("ros2_bag_0.mcap")).unwrap();
    let seq = dataset::open(&ros2, &SequenceOptions::default()).unwrap();
    assert_eq!((seq.layout, seq.len()), (Layout::Ros2Bag, 2));
}

pub fn tests() -> Vec<common::harness::Test> {
    vec![
        plain(
            "mcap_tracks_to_the_folders_poses",
            mcap_tracks_to_the_folders_poses,
        ),
        plain(
            "run_on_an_mcap_writes_the_folders_trajectory",
            run_on_an_mcap_writes_the_folders_trajectory,
        ),
        plain(
            "a_plumb_bob_lens_is_removed_as_camera_json_s",
            a_plumb_bob_lens_is_removed_as_camera_json_s,
        ),
        plain("two_depth_topics_ask_which", two_depth_topics_ask_which),
        plain(
            "truncated_corrupt_and_foreign_recordings_are_refused",
            truncated_corrupt_and_foreign_recordings_are_refused,
        ),
    ]
}
