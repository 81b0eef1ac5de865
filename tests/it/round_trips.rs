//! How often one GPU stream waits for the device, and how much it reads back, on the plain
//! frames of a run (no keyframe, relocalisation or loop check), as `wgslam bench` counts
//! them (issue 48, item 4): the ICP system's read-back is the only wait per iteration; and
//! how several streams in one process share those waits (item 2).

use crate::common;

use common::harness::{gpu, gpu_backend};
use wgslam::gpu::context::{DeviceOptions, GpuSubmissions};
use wgslam::gpu::GpuContext;
use wgslam::slam::params::{Profile, ValidParams};
use wgslam::tools::{bench, run, streams};

/// Waits on a plain frame beyond one per ICP iteration: the health test's count of
/// candidates at the final pose (it decides whether the frame is fused), and on the frames
/// where the robust profile compacts the map (every `fusion.unstable_removal` interval: 2
/// of the bundled run's 22 plain frames) fusion's count of added surfels and the count of
/// surfels kept. Preprocess and predict are recorded into the first ICP iteration's
/// submission, the fern codes into preprocess's, and fusion's count is read after the next
/// frame's first ICP wait, so none of them waits: a wait added after preprocess, predict,
/// fusion or any ICP step fails [`PLAIN_WAITS_BEYOND_ICP_MEAN_MAX`] (measured: 1.18 mean,
/// 3 most; 2.09 mean while fusion waited for its count, before 2026-11-29).
const PLAIN_WAITS_BEYOND_ICP_MAX: u64 = 3;
/// The mean of the above: the candidate count on every frame and compaction's two on a
/// few make 1.18; one more wait on every frame (after fusion, say) makes 2.18, which fails.
const PLAIN_WAITS_BEYOND_ICP_MEAN_MAX: f64 = 1.5;
/// Submissions beyond one per ICP iteration on a plain frame: the candidate count, fusion
/// and compaction on its frames (measured: 2.09 mean, 3 most).
const PLAIN_SUBMISSIONS_BEYOND_ICP_MAX: u64 = 3;
/// Issue 48's bound on the bytes a plain frame reads back (the ICP systems, the two counts
/// and the fern codes: about 2.8 KB at 320x240 measured).
const PLAIN_READBACK_MAX_BYTES: u64 = 8 * 1024;

pub fn tests() -> Vec<common::harness::Test> {
    vec![
        gpu(
            "gpu_plain_frames_wait_only_for_icp_and_health",
            gpu_plain_frames_wait_only_for_icp_and_health,
        ),
        gpu(
            "gpu_streams_share_waits_and_match_one_stream",
            gpu_streams_share_waits_and_match_one_stream,
        ),
        gpu(
            "gpu_a_waiter_gathers_other_threads_not_its_own_streams",
            gpu_a_waiter_gathers_other_threads_not_its_own_streams,
        ),
        gpu(
            "gpu_combined_streams_submit_together_and_match_one_stream",
            gpu_combined_streams_submit_together_and_match_one_stream,
        ),
        gpu(
            "gpu_a_failed_scope_drops_its_held_work_and_spares_other_streams",
            gpu_a_failed_scope_drops_its_held_work_and_spares_other_streams,
        ),
    ]
}

/// `bench`'s first pass over the bundled frames with the default profile on the GPU.
fn gpu_plain_frames_wait_only_for_icp_and_health(ctx: GpuContext) {
    let seq = common::open_asset("icl_living_room_kt2");
    let mut backend = Some(gpu_backend(ctx));
    let r = bench::bench_frames(
        || Ok(backend.take().expect("one backend")),
        &seq,
        (1, seq.frames.len() - 1),
        &ValidParams::profile(Profile::Robust),
        run::Decode::BeforeEachFrame,
    )
    .unwrap();
    let t = r.round_trips.expect("the plain pass counts round trips");
    eprintln!("{t:?}");
    assert!(t.plain_frames >= 10, "{t:?}");
    assert!(t.icp_iterations_per_frame >= 1.0, "{t:?}");
    assert!(
        t.plain_waits_beyond_icp_max <= PLAIN_WAITS_BEYOND_ICP_MAX,
        "{t:?}"
    );
    assert!(
        t.plain_waits_beyond_icp_mean <= PLAIN_WAITS_BEYOND_ICP_MEAN_MAX,
        "{t:?}"
    );
    assert!(
        t.plain_submissions_beyond_icp_max <= PLAIN_SUBMISSIONS_BEYOND_ICP_MAX,
        "{t:?}"
    );
    assert!(
        t.plain_readback_bytes_max <= PLAIN_READBACK_MAX_BYTES,
        "{t:?}"
    );
}

/// Streams tracked at once in one process by [`gpu_streams_share_waits_and_match_one_stream`]
/// (issue 48 item 2's check).
const STREAMS: usize = 4;
/// Issue 48 item 2's bound: with [`STREAMS`] streams in one process, device waits per
/// stream-frame are at most (ICP iterations per frame + this) / 2. One stream alone makes
/// about ICP + 2.09; the bound holds only when waits are shared between streams.
const STREAM_WAITS_BEYOND_ICP: f64 = 3.0;

/// The bundled frames as one GPU stream, then as [`STREAMS`] at once on contexts sharing
/// one device and queue: the streams share device waits (issue 48 item 2's bound), each
/// stream's map and accuracy equal the lone stream's bit for bit, and the lone stream
/// never has a wait served by another.
fn gpu_streams_share_waits_and_match_one_stream(ctx: GpuContext) {
    let seq = common::open_asset("icl_living_room_kt2");
    let r = streams::bench_streams(
        &ctx,
        &seq,
        (1, seq.frames.len() - 1),
        &ValidParams::profile(Profile::Robust),
        STREAMS,
    )
    .unwrap();
    let summary = format!("{}; {}", r.one.line(), r.many.line());
    eprintln!("{summary}");
    assert_eq!(r.one.shared_waits_per_stream_frame, 0.0, "{summary}");
    assert!(r.one.icp_iterations_per_frame >= 1.0, "{summary}");
    // The default, `--gpu-submissions own`: every submission goes to the device itself.
    assert_eq!(
        r.many.device_submissions_per_stream_frame, r.many.submissions_per_stream_frame,
        "{summary}"
    );
    let bound = (r.many.icp_iterations_per_frame + STREAM_WAITS_BEYOND_ICP) / 2.0;
    assert!(
        r.many.waits_per_stream_frame <= bound,
        "{STREAMS} streams waited {:.2} times per stream-frame, more than (ICP {:.2} + \
         {STREAM_WAITS_BEYOND_ICP}) / 2 = {bound:.2}; one stream alone waited {:.2}",
        r.many.waits_per_stream_frame,
        r.many.icp_iterations_per_frame,
        r.one.waits_per_stream_frame
    );
    assert_each_stream_equals_the_lone_one(&r);
}

/// Issue 48 item 2's second half, with `--gpu-submissions combined`: with [`STREAMS`]
/// streams, the `queue.submit` calls the device gets per stream-frame are at most this share
/// of the lone stream's (which equal its submissions). A stream's submission made while the
/// device has work in flight is held and given to the device with the others' in one call
/// (`shared_wait.rs`); measured 0.71-0.76 of the lone stream's (5.8-6.2 of 8.13) on the
/// 2-core machine, 2026-11-29 (0.67-0.70 when work was held while a thread was blocked in
/// the device too). How many are ready together depends on timing, so the bound leaves
/// margin: 0.85, at least 15 % saved, which streams submitting one by one never meet (their
/// share is 1).
const STREAM_DEVICE_SUBMISSIONS_SHARE_MAX: f64 = 0.85;

/// A device whose streams combine their submissions, with the environment's features and
/// limits.
fn combined_device(ctx: GpuContext) -> GpuContext {
    drop(ctx);
    GpuContext::with_options(DeviceOptions {
        submissions: GpuSubmissions::Combined,
        ..DeviceOptions::from_env().expect("the environment's device options")
    })
    .expect("a device with combined submissions")
}

/// [`gpu_streams_share_waits_and_match_one_stream`] with combined submissions: the device
/// gets fewer `queue.submit` calls than the streams make submissions, a lone stream's go one
/// by one, the waits still meet the bound, and every stream's map and accuracy equal the
/// lone stream's bit for bit.
fn gpu_combined_streams_submit_together_and_match_one_stream(ctx: GpuContext) {
    let seq = common::open_asset("icl_living_room_kt2");
    let frames = (1, seq.frames.len() - 1);
    let params = ValidParams::profile(Profile::Robust);
    let ctx = combined_device(ctx);
    let r = streams::bench_streams(&ctx, &seq, frames, &params, STREAMS).unwrap();
    let summary = format!("{}; {}", r.one.line(), r.many.line());
    eprintln!("combined: {summary}");
    assert_eq!(
        r.one.device_submissions_per_stream_frame, r.one.submissions_per_stream_frame,
        "a lone stream's submissions go to the device one by one: {summary}"
    );
    let most = STREAM_DEVICE_SUBMISSIONS_SHARE_MAX * r.one.device_submissions_per_stream_frame;
    assert!(
        r.many.device_submissions_per_stream_frame <= most,
        "{STREAMS} streams made {:.2} device submissions per stream-frame, more than \
         {STREAM_DEVICE_SUBMISSIONS_SHARE_MAX} x the lone stream's {:.2} = {most:.2}",
        r.many.device_submissions_per_stream_frame,
        r.one.device_submissions_per_stream_frame
    );
    let bound = (r.many.icp_iterations_per_frame + STREAM_WAITS_BEYOND_ICP) / 2.0;
    assert!(r.many.waits_per_stream_frame <= bound, "{summary}");
    assert_each_stream_equals_the_lone_one(&r);
}

/// With combined submissions, a stream whose error scope catches an error (here a copy
/// past a buffer's end) drops the work it held in that scope: another stream's wait, which
/// makes every held submission, stays free of it, and the failing stream's own wait for the
/// dropped work ends at once. Held, the invalid command buffer would fail the other
/// stream's `queue.submit`, in that stream's error scope.
fn gpu_a_failed_scope_drops_its_held_work_and_spares_other_streams(ctx: GpuContext) {
    let a = combined_device(ctx);
    let b = a.share();
    let buffer = |size: u64| {
        a.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("copy test"),
            size,
            usage: wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        })
    };
    let (small, large) = (buffer(256), buffer(4096));
    let copy = |c: &GpuContext, bytes: u64| -> wgslam::Result<()> {
        let mut enc = c.encoder("copy");
        enc.copy_buffer_to_buffer(&large, 0, &small, 0, bytes);
        c.submit(enc);
        Ok(())
    };
    // B's work is made at once (the only stream so far) and keeps the device busy as far
    // as the host knows; A's next, a valid copy, is held.
    b.scoped("b's copy", || copy(&b, 256)).unwrap();
    a.scoped("a's valid copy", || copy(&a, 256)).unwrap();
    let failed = a.scoped("a's copy past the end", || copy(&a, 4096));
    assert!(
        failed.is_err(),
        "a copy past a buffer's end was not refused"
    );
    // B's wait makes A's held valid copy, not the invalid one.
    b.scoped("b's wait", || b.wait_idle())
        .expect("another stream's invalid work reached this stream's submission");
    a.wait_idle()
        .expect("waiting for dropped work ends at once, without an error");
    assert_eq!(
        a.stats().device_submissions + b.stats().device_submissions,
        2
    );
}

/// Every stream's map size and accuracy equal the lone stream's bit for bit.
fn assert_each_stream_equals_the_lone_one(r: &streams::StreamsResult) {
    assert!(
        r.identical_to_one,
        "a stream's map size or accuracy differs from the lone stream's: {:?}",
        r.many
            .each
            .iter()
            .map(|e| (e.map_points, e.ate_rmse_aligned_m))
            .collect::<Vec<_>>()
    );
}

/// Round trips of [`gpu_a_waiter_gathers_other_threads_not_its_own_streams`]'s first part.
const ONE_THREAD_ROUND_TRIPS: usize = 20;

/// A thread about to wait for the device gathers the *other threads* that drive streams on
/// its queue, never its own streams: one thread driving two contexts (Python looping over
/// two trackers) never waits the gathering time out, while a second thread that has work
/// in flight and does not come to wait makes the waiter wait it out once.
fn gpu_a_waiter_gathers_other_threads_not_its_own_streams(ctx: GpuContext) {
    let round_trip = |c: &GpuContext| {
        let enc = c.encoder("round trip");
        c.submit(enc);
    };
    let other = ctx.share();
    for _ in 0..ONE_THREAD_ROUND_TRIPS {
        round_trip(&ctx);
        round_trip(&other);
        ctx.wait_idle().unwrap();
        other.wait_idle().unwrap();
    }
    assert_eq!(
        ctx.gathers_timed_out(),
        0,
        "one thread gathered for its own streams"
    );

    // A thread that submits and then stays away from the device: the waiter gathers it.
    let (submitted_tx, submitted_rx) = std::sync::mpsc::channel();
    let (done_tx, done_rx) = std::sync::mpsc::channel::<()>();
    let away = ctx.share();
    std::thread::scope(|scope| {
        scope.spawn(move || {
            round_trip(&away);
            submitted_tx.send(()).unwrap();
            done_rx.recv().unwrap();
        });
        submitted_rx.recv().unwrap();
        round_trip(&ctx);
        ctx.wait_idle().unwrap();
        done_tx.send(()).unwrap();
    });
    assert_eq!(
        ctx.gathers_timed_out(),
        1,
        "the waiter did not gather the other thread"
    );
}
