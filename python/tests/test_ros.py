"""The ROS frame-conversion helpers (:mod:`wgslam.ros`) on stand-in messages: each
encoding, padded rows, byte order, and a wrong size refused."""

from types import SimpleNamespace

import numpy as np
import pytest

from wgslam.ros import camera_info_intrinsics, image_to_array


def image(encoding, pixels, step_pad=0, big_endian=False):
    """A stand-in ``sensor_msgs/Image`` holding ``pixels`` (H, W[, C])."""
    h, w = pixels.shape[:2]
    rows = pixels.reshape(h, -1)
    if big_endian:
        rows = rows.astype(rows.dtype.newbyteorder(">"))
    raw = rows.view(np.uint8).reshape(h, -1)
    raw = np.concatenate([raw, np.zeros((h, step_pad), np.uint8)], axis=1)
    return SimpleNamespace(encoding=encoding, width=w, height=h, step=raw.shape[1],
                           is_bigendian=int(big_endian), data=raw.tobytes())


def test_depth_encodings():
    mm = np.arange(12, dtype=np.uint16).reshape(3, 4) * 1000
    out = image_to_array(image("16UC1", mm, step_pad=4))
    assert out.dtype == np.uint16 and np.array_equal(out, mm)
    assert np.array_equal(image_to_array(image("16UC1", mm, big_endian=True)), mm)
    m = mm.astype(np.float32) / 1000
    m[0, 1] = np.nan
    out = image_to_array(image("32FC1", m))
    assert out.dtype == np.float32 and out[0, 1] == 0 and out[2, 3] == m[2, 3]


def test_colour_encodings():
    rgb = np.arange(2 * 3 * 3, dtype=np.uint8).reshape(2, 3, 3)
    assert np.array_equal(image_to_array(image("rgb8", rgb, step_pad=3)), rgb)
    assert np.array_equal(image_to_array(image("bgr8", rgb[:, :, ::-1].copy())), rgb)
    rgba = np.concatenate([rgb, np.full((2, 3, 1), 255, np.uint8)], axis=2)
    assert np.array_equal(image_to_array(image("rgba8", rgba)), rgb)
    bgra = np.concatenate([rgb[:, :, ::-1], np.full((2, 3, 1), 255, np.uint8)], axis=2)
    assert np.array_equal(image_to_array(image("bgra8", bgra)), rgb)
    grey = rgb[:, :, 0].copy()
    out = image_to_array(image("mono8", grey))
    assert out.shape == (2, 3, 3) and np.array_equal(out[:, :, 2], grey)


def test_bad_messages_are_refused():
    msg = image("16UC1", np.zeros((2, 2), np.uint16))
    msg.data = msg.data[:-1]
    with pytest.raises(ValueError, match="height \\* step"):
        image_to_array(msg)
    with pytest.raises(ValueError, match="not read"):
        image_to_array(image("yuv422", np.zeros((2, 2), np.uint16)))


def test_camera_info():
    k = [525.0, 0, 319.5, 0, 526.0, 239.5, 0, 0, 1]
    ros2 = SimpleNamespace(width=640, height=480, k=k)
    assert camera_info_intrinsics(ros2) == (640, 480, 525.0, 526.0, 319.5, 239.5)
    ros1 = SimpleNamespace(width=640, height=480, K=k)
    assert camera_info_intrinsics(ros1) == (640, 480, 525.0, 526.0, 319.5, 239.5)
