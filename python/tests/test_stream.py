"""Streaming (`wgslam.Slam`): frames fed one at a time give `wgslam run`'s trajectory bit
for bit; bad arrays are refused with a clear error; frames are tracked with the
interpreter's lock released."""

import os
import sys
import threading

import numpy as np
import pytest

import wgslam
from conftest import BUNDLED


def stream(seq, first, last, backend="cpu", params=None):
    """Feeds frames `first..=last` of `seq` through a `Slam` as `wgslam run` feeds them:
    each frame's number, stamp and ground truth (used for the first frame only)."""
    slam = wgslam.Slam.for_sequence(seq, params, backend)
    statuses = []
    for i in range(first, last + 1):
        depth, rgb = seq.frame(i)
        t = slam.track(depth, rgb, seq.timestamp(i), pose=seq.ground_truth(i), frame_id=i)
        statuses.append(t.status)
    return slam, statuses


def assert_same_trajectory(slam, result):
    stamps, poses = slam.trajectory()
    assert np.array_equal(stamps, result.stamps)
    # Bit for bit: the same pipeline steps on the same inputs.
    assert poses.tobytes() == result.poses.tobytes()


def test_streaming_equals_wgslam_run_bit_for_bit():
    seq = wgslam.open_sequence(BUNDLED)
    first = seq.default_first_frame()
    last = len(seq) - 1
    result = wgslam.run(BUNDLED, backend="cpu")
    slam, statuses = stream(seq, first, last)
    assert statuses[0] == "given" and set(statuses[1:]) <= {"tracked"}
    assert_same_trajectory(slam, result)
    m = slam.map()
    assert m["positions"].tobytes() == result.map["positions"].tobytes()


def test_streaming_equals_wgslam_run_on_7_scenes(shared_data):
    kitchen = shared_data / "7scenes_redkitchen"
    seq = wgslam.open_sequence(kitchen)
    result = wgslam.run(kitchen, frames="0..299", backend="cpu")
    slam, _ = stream(seq, 0, 299)
    assert_same_trajectory(slam, result)


def test_the_resolution_is_the_backends_default_unless_set():
    """Unset, the stream tracks at the resolution `wgslam run` chooses for its backend (every
    second pixel on the CPU); a parameter that sets it is kept."""
    seq = wgslam.open_sequence(BUNDLED)
    cpu = wgslam.Slam.for_sequence(seq, backend="cpu")
    assert (cpu.downsample, cpu.downsample_from) == (2, "cpu-default")
    full = wgslam.Slam.for_sequence(seq, {"downsample": 1}, backend="cpu")
    assert (full.downsample, full.downsample_from) == (1, "set")


def gpu_or_skip(seq):
    """A GPU stream over `seq`, or a skip when no adapter is here (a failure under
    WGSLAM_REQUIRE_GPU=1, as `.ci/run` sets it)."""
    try:
        return wgslam.Slam.for_sequence(seq, backend="gpu")
    except RuntimeError as e:
        if os.environ.get("WGSLAM_REQUIRE_GPU") == "1":
            pytest.fail(f"no GPU backend ({e}) and WGSLAM_REQUIRE_GPU=1")
        pytest.skip(f"no GPU backend here: {e}")


def test_a_gpu_stream_equals_wgslam_run_on_the_gpu():
    """The GPU's default resolution (every pixel) in a stream as in `wgslam run`: the same
    trajectory bit for bit (it was every second pixel, whatever the backend)."""
    seq = wgslam.open_sequence(BUNDLED)
    slam = gpu_or_skip(seq)
    assert (slam.downsample, slam.downsample_from) == (1, "gpu-default")
    first, last = seq.default_first_frame(), len(seq) - 1
    for i in range(first, last + 1):
        depth, rgb = seq.frame(i)
        slam.track(depth, rgb, seq.timestamp(i), pose=seq.ground_truth(i), frame_id=i)
    assert_same_trajectory(slam, wgslam.run(BUNDLED, backend="gpu"))


def test_gpu_streams_in_one_thread_share_one_device_and_each_equals_wgslam_run():
    """Two GPU trackers fed in turn from one thread, as a Python loop over several
    recordings does, track on the process's one shared device (none is opened for the
    second) and each gives `wgslam run`'s trajectory bit for bit."""
    seq = wgslam.open_sequence(BUNDLED)
    a = gpu_or_skip(seq)
    devices = wgslam._native.devices_opened()
    b = wgslam.Slam.for_sequence(seq, backend="gpu")
    assert wgslam._native.devices_opened() == devices
    first, last = seq.default_first_frame(), len(seq) - 1
    for i in range(first, last + 1):
        depth, rgb = seq.frame(i)
        for slam in (a, b):
            slam.track(depth, rgb, seq.timestamp(i), pose=seq.ground_truth(i), frame_id=i)
    result = wgslam.run(BUNDLED, backend="gpu")
    assert wgslam._native.devices_opened() == devices
    assert_same_trajectory(a, result)
    assert_same_trajectory(b, result)


def test_float_metres_track_like_raw_depth():
    """float32 metres are turned into the raw units the scale gives: the same frames as
    raw depth / scale give the same poses."""
    seq = wgslam.open_sequence(BUNDLED)
    raw = wgslam.Slam.for_sequence(seq, backend="cpu")
    metres = wgslam.Slam(seq.intrinsics(), backend="cpu", depth_scale=seq.depth_scale())
    for i in range(1, 5):
        depth, rgb = seq.frame(i)
        gt = seq.ground_truth(i)
        a = raw.track(depth, rgb, pose=gt)
        b = metres.track((depth / np.float32(seq.depth_scale())).astype(np.float32), rgb, pose=gt)
        assert a.status == b.status and np.array_equal(a.pose, b.pose), i


@pytest.fixture
def slam_and_frame():
    seq = wgslam.open_sequence(BUNDLED)
    depth, rgb = seq.frame(1)
    return wgslam.Slam.for_sequence(seq, backend="cpu"), depth, rgb


@pytest.mark.parametrize(
    "bad, error, words",
    [
        (lambda d, c: (d.astype(np.float64), c), TypeError, "dtype float64"),
        (lambda d, c: (d.T.copy(), c), ValueError, "transposed"),
        (lambda d, c: (d[:240], c), ValueError, "expected (480, 640)"),
        (lambda d, c: (d, c[:, :320]), ValueError, "expected (480, 640, 3)"),
        (lambda d, c: (d, np.concatenate([c, c[..., :1]], axis=2)), ValueError, "RGBA"),
        (lambda d, c: (d, c.astype(np.float32)), TypeError, "want uint8"),
        (lambda d, c: (d.tolist(), c), TypeError, "numpy array"),
    ],
)
def test_bad_arrays_raise_before_any_work(slam_and_frame, bad, error, words):
    slam, depth, rgb = slam_and_frame
    d, c = bad(depth, rgb)
    with pytest.raises(error) as e:
        slam.track(d, c)
    assert words in str(e.value)
    # Nothing was tracked: the next good frame is the first.
    assert slam.track(depth, rgb).status == "given"


def test_uint16_depth_needs_its_scale_and_a_pose_is_4x4(slam_and_frame):
    slam, depth, rgb = slam_and_frame
    unscaled = wgslam.Slam((640, 480, 481.2, -480.0, 319.5, 239.5), backend="cpu")
    with pytest.raises(ValueError, match="depth_scale"):
        unscaled.track(depth, rgb)
    with pytest.raises(ValueError, match=r"\(4, 4\)"):
        slam.track(depth, rgb, pose=np.eye(3))


@pytest.mark.parametrize(
    "kwargs, words",
    [
        ({"pose": np.full((4, 4), np.nan)}, "pose holds NaN"),
        ({"pose": np.diag([2.0, 2.0, 2.0, 1.0])}, "not a rotation"),
        ({"pose": np.ones((4, 4))}, "last row"),
        ({"timestamp": float("nan")}, "timestamp NaN must be a finite number"),
    ],
)
def test_bad_poses_and_stamps_raise_before_any_work(slam_and_frame, kwargs, words):
    # Issue 46: a NaN pose made every surfel NaN, a NaN stamp was kept, a scaled pose
    # was taken silently; each is refused as a pose file would be.
    slam, depth, rgb = slam_and_frame
    with pytest.raises(ValueError) as e:
        slam.track(depth, rgb, **kwargs)
    assert words in str(e.value)
    assert slam.track(depth, rgb).status == "given"


def test_frame_numbers_go_forward(slam_and_frame):
    """A frame number not after the last one is refused before any work (an earlier one
    panicked in loop closure's pose graph once it became a node); numbers left out go on
    from the last."""
    slam, depth, rgb = slam_and_frame
    assert slam.track(depth, rgb, frame_id=100).status == "given"
    for earlier in (100, 5):
        with pytest.raises(wgslam.Error) as e:
            slam.track(depth, rgb, frame_id=earlier)
        assert f"frame {earlier} is not after the last frame, 100" in str(e.value)
    assert slam.track(depth, rgb).status == "tracked"
    assert slam.track(depth, rgb, frame_id=200).status == "tracked"


def test_frames_are_tracked_with_the_lock_released():
    """A Python thread runs while a run processes frames. The progress callback (run with
    the lock held) hands each frame's number to a thread; with a switch interval longer
    than the run, that thread can only take the lock when the run releases it, so it has
    handled frame k by the callback of frame k + 1 only if frames are processed without
    the lock."""
    handed, handled, wake = [0], [0], threading.Event()
    stop = False

    def helper():
        while not stop:
            wake.wait()
            wake.clear()
            handled[0] = handed[0]

    seen = []

    def progress(done, total):
        if done > 1:
            seen.append(handled[0] == done - 1)
        handed[0] = done
        wake.set()

    thread = threading.Thread(target=helper, daemon=True)
    old = sys.getswitchinterval()
    sys.setswitchinterval(100.0)
    try:
        thread.start()
        wgslam.run(BUNDLED, frames="1..8", backend="cpu", progress=progress)
    finally:
        sys.setswitchinterval(old)
        stop = True
        wake.set()
    assert len(seen) == 7 and all(seen), seen
