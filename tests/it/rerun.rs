//! `wgslam run --rerun FILE.rrd` (cargo feature `rerun`; the `#[cfg(feature = "rerun")]` on
//! its `mod` in main.rs keeps this file out of a default `cargo test`): the recording is
//! written whole, and the rerun crate's own decoder reads back every entity with the rows a
//! short run logs.

use crate::common;

use std::collections::BTreeMap;
use std::io::BufReader;
use std::path::Path;

use common::cli::{ok, text, wgslam};
use common::harness::plain;
use rerun::external::arrow::array::{Array, AsArray};
use rerun::external::re_log_encoding::DecoderApp;
use rerun::log::{Chunk, LogMsg};

/// The run's frames: five bundled frames, a map every second frame.
const FRAMES: &str = "1..5";
const FRAME_COUNT: usize = 5;
const MAP_EVERY: usize = 2;

/// Smallest plausible recording of five frames, bytes: each frame logs a 640x480 RGB image
/// (900 KiB) and its u16 depth (600 KiB) and the file is LZ4-compressed; a tenth of the
/// raw bytes is far below what real images compress to, and far above an empty recording.
const MIN_RECORDING_BYTES: u64 = FRAME_COUNT as u64 * 150 * 1024;

/// What one entity holds in a recording: static rows, and per-frame rows as (frame
/// timeline value, points: positions of a point cloud, points over all strips of a line
/// strip, 0 otherwise) in file order.
#[derive(Debug, Default)]
struct EntityRows {
    static_rows: usize,
    frames: Vec<i64>,
    instances: Vec<usize>,
}

/// Decodes `path` with the rerun crate's decoder; rows per entity path.
fn read_recording(path: &Path) -> BTreeMap<String, EntityRows> {
    let file = std::fs::File::open(path).expect("open the recording");
    let decoder = DecoderApp::decode_eager(BufReader::new(file)).expect("an .rrd stream");
    let mut entities: BTreeMap<String, EntityRows> = BTreeMap::new();
    for msg in decoder {
        let LogMsg::ArrowMsg(_, arrow) = msg.expect("a message that decodes") else {
            continue;
        };
        let chunk = Chunk::from_arrow_msg(&arrow).expect("a chunk");
        let rows = entities.entry(chunk.entity_path().to_string()).or_default();
        if chunk.is_static() {
            rows.static_rows += chunk.num_rows();
            continue;
        }
        let frame = chunk
            .timelines()
            .get(&"frame".into())
            .unwrap_or_else(|| panic!("{} logged off the frame timeline", chunk.entity_path()));
        assert!(
            chunk.timelines().contains_key(&"stamp".into()),
            "{} has no stamp timeline",
            chunk.entity_path()
        );
        rows.frames.extend_from_slice(frame.times_raw());
        // Points per row: a point cloud's positions, or the points over all of a line
        // strip's strips (images and poses count nothing).
        let points = [
            rerun::Points3D::descriptor_positions(),
            rerun::LineStrips3D::descriptor_strips(),
        ]
        .into_iter()
        .find_map(|d| chunk.components().get_array(d.component));
        rows.instances
            .extend((0..chunk.num_rows()).map(|r| match points {
                None => 0,
                Some(list) => {
                    let row = list.value(r);
                    match row.as_list_opt::<i32>() {
                        // `values()` is the whole child array of a sliced list: count
                        // by offsets.
                        Some(strips) => (0..strips.len())
                            .map(|i| strips.value_length(i) as usize)
                            .sum(),
                        None => row.len(),
                    }
                }
            }));
    }
    entities
}

fn run_writes_a_recording_the_decoder_reads() {
    let out = common::temp_dir("rerun-run");
    let rrd = out.join("run.rrd");
    let every = MAP_EVERY.to_string();
    let o = ok(wgslam(&[
        "run",
        "--backend",
        "cpu",
        "--frames",
        FRAMES,
        "--rerun",
        rrd.to_str().unwrap(),
        "--rerun-map-every",
        &every,
        "--out",
        out.to_str().unwrap(),
    ]));
    assert!(
        text(&o).contains("run.rrd"),
        "path not reported: {}",
        text(&o)
    );
    let bytes = std::fs::metadata(&rrd).expect("recording written").len();
    assert!(
        bytes >= MIN_RECORDING_BYTES,
        "recording of {bytes} bytes, expected at least {MIN_RECORDING_BYTES}"
    );
    let leftovers: Vec<_> = std::fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.contains(".tmp-"))
        .collect();
    assert!(leftovers.is_empty(), "temp files left: {leftovers:?}");

    let entities = read_recording(&rrd);
    let shown: Vec<_> = entities.keys().collect();
    eprintln!("entities: {shown:?}");
    let get = |e: &str| {
        entities
            .get(&format!("/{e}"))
            .or_else(|| entities.get(e))
            .unwrap_or_else(|| panic!("entity {e} missing; found {shown:?}"))
    };
    let every_frame: Vec<i64> = (1..=FRAME_COUNT as i64).collect();
    for e in [
        "world/camera",
        "world/camera/image/rgb",
        "world/camera/image/depth",
        "world/trajectory/estimate",
    ] {
        let rows = get(e);
        let mut frames = rows.frames.clone();
        frames.sort();
        assert_eq!(frames, every_frame, "{e}: rows per frame");
    }
    for e in ["world/camera/image", "world/trajectory/ground_truth"] {
        assert_eq!(get(e).static_rows, 1, "{e}: one static row");
    }
    // The estimated path grows by one point a frame.
    let strip = get("world/trajectory/estimate");
    let mut growth: Vec<(i64, usize)> = strip
        .frames
        .iter()
        .copied()
        .zip(strip.instances.iter().copied())
        .collect();
    growth.sort();
    let expected: Vec<(i64, usize)> = (1..=FRAME_COUNT).map(|n| (n as i64, n)).collect();
    assert_eq!(growth, expected, "(frame, points of the estimated path)");
    // The map after frames 2 and 4 (every 2nd), and the final map at frame 5.
    let map = get("world/map");
    let mut map_frames = map.frames.clone();
    map_frames.sort();
    assert_eq!(map_frames, vec![2, 4, 5], "map rows");
    // The final map has every surfel (fewer than the 100k cap here) as a point.
    let metrics = common::read_json(out.join("metrics.json"));
    let surfels = metrics["map_points"].as_u64().unwrap() as usize;
    assert!(surfels > 0 && surfels <= 100_000, "{surfels} surfels");
    let last = map
        .frames
        .iter()
        .zip(&map.instances)
        .filter(|(f, _)| **f == 5)
        .map(|(_, n)| *n)
        .collect::<Vec<_>>();
    assert_eq!(last, vec![surfels], "final map points vs metrics.json");
}

/// A run that fails after the recording started leaves neither the recording nor its temp
/// file; a bad `--rerun-map-every` is refused before anything runs.
fn failed_run_leaves_no_recording() {
    let out = common::temp_dir("rerun-fail");
    let rrd = out.join("run.rrd");
    // --out names a file, so writing the outputs fails after the frames ran.
    let not_a_dir = out.join("file");
    std::fs::write(&not_a_dir, b"x").unwrap();
    let run_one_frame = |more: &[&str]| {
        let rrd = rrd.to_str().unwrap();
        let mut args = vec![
            "run",
            "--backend",
            "cpu",
            "--frames",
            "1..2",
            "--rerun",
            rrd,
        ];
        args.extend_from_slice(more);
        wgslam(&args)
    };
    let o = run_one_frame(&["--out", not_a_dir.to_str().unwrap()]);
    assert!(!o.status.success(), "{}", text(&o));
    let names: Vec<_> = std::fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert_eq!(names, vec!["file".to_string()], "left behind: {names:?}");

    let o = run_one_frame(&["--rerun-map-every", "0", "--out", out.to_str().unwrap()]);
    assert!(!o.status.success(), "--rerun-map-every 0 accepted");
    assert!(text(&o).contains("--rerun-map-every"), "{}", text(&o));
    assert!(!rrd.exists());
}

pub fn tests() -> Vec<common::harness::Test> {
    vec![
        plain(
            "run_writes_a_recording_the_decoder_reads",
            run_writes_a_recording_the_decoder_reads,
        ),
        plain(
            "failed_run_leaves_no_recording",
            failed_run_leaves_no_recording,
        ),
    ]
}
