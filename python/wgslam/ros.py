"""ROS messages as the arrays :meth:`wgslam.Slam.track` takes, for a live loop over a ROS 2
subscription (docs/python.md). Pure numpy: no ROS import, so any object with a ROS
message's fields works (an ``rclpy`` message, a ``rosbags`` one, a test's stand-in).

- :func:`image_to_array`: a ``sensor_msgs/Image`` (``encoding``, ``width``, ``height``,
  ``step``, ``is_bigendian``, ``data``) as depth (``16UC1`` uint16, ``32FC1`` float32
  metres) or RGB uint8 (``rgb8``, ``bgr8``, ``rgba8``, ``bgra8``, ``mono8``).
- :func:`camera_info_intrinsics`: a ``sensor_msgs/CameraInfo``'s size and ``K`` as the
  ``(width, height, fx, fy, cx, cy)`` :class:`wgslam.Slam` takes.

Rows padded past ``width`` (``step`` larger than a row) are cut; a ``data`` whose size is
not ``height * step`` raises ``ValueError``. The same encodings as the command line's bag
readers (docs/datasets.md).
"""

from __future__ import annotations

from typing import Any, Tuple

import numpy as np

#: encoding -> (numpy dtype of one channel, channels)
_ENCODINGS = {
    "16UC1": (np.dtype("u2"), 1),
    "32FC1": (np.dtype("f4"), 1),
    "rgb8": (np.dtype("u1"), 3),
    "bgr8": (np.dtype("u1"), 3),
    "rgba8": (np.dtype("u1"), 4),
    "bgra8": (np.dtype("u1"), 4),
    "mono8": (np.dtype("u1"), 1),
}


def image_to_array(msg: Any) -> np.ndarray:
    """A ``sensor_msgs/Image`` as an array for :meth:`wgslam.Slam.track`.

    Depth: ``16UC1`` gives (H, W) uint16 raw units (millimetres: ``Slam(...,
    depth_scale=1000)``); ``32FC1`` gives (H, W) float32 metres with NaN and infinities
    (no reading) as 0. Colour: (H, W, 3) uint8 RGB (BGR swapped, alpha dropped, grey
    repeated). Other encodings raise ``ValueError``.
    """
    enc = str(msg.encoding)
    if enc not in _ENCODINGS:
        raise ValueError(f"image encoding {enc!r} is not read (one of {sorted(_ENCODINGS)})")
    dtype, channels = _ENCODINGS[enc]
    if getattr(msg, "is_bigendian", 0):
        dtype = dtype.newbyteorder(">")
    else:
        dtype = dtype.newbyteorder("<")
    h, w, step = int(msg.height), int(msg.width), int(msg.step)
    row = w * channels * dtype.itemsize
    data = np.frombuffer(bytes(msg.data), np.uint8)
    if step < row or data.size != h * step:
        raise ValueError(
            f"{enc} image {w}x{h}: data is {data.size} bytes, step {step}; want "
            f"height * step bytes with step >= {row}"
        )
    rows = data.reshape(h, step)[:, :row]
    px = np.ascontiguousarray(rows).view(dtype).reshape(h, w, channels)
    px = px.astype(dtype.newbyteorder("="), copy=False)
    if enc == "16UC1":
        return np.ascontiguousarray(px[:, :, 0], dtype=np.uint16)
    if enc == "32FC1":
        depth = np.array(px[:, :, 0], dtype=np.float32)  # a copy: frombuffer is read-only
        depth[~np.isfinite(depth)] = 0.0
        return depth
    if enc == "mono8":
        return np.repeat(px, 3, axis=2)
    rgb = px[:, :, [2, 1, 0]] if enc.startswith("bgr") else px[:, :, :3]
    return np.ascontiguousarray(rgb, dtype=np.uint8)


def camera_info_intrinsics(msg: Any) -> Tuple[int, int, float, float, float, float]:
    """``(width, height, fx, fy, cx, cy)`` of a ``sensor_msgs/CameraInfo`` (ROS 2's ``k``
    or ROS 1's ``K``, row-major 3x3). Distortion is not used (pinhole projection)."""
    k = getattr(msg, "k", None)
    if k is None:
        k = msg.K
    k = [float(v) for v in k]
    return int(msg.width), int(msg.height), k[0], k[4], k[2], k[5]
