"""ROS 1 and ROS 2 (SQLite) bags of the bundled frames, written by the ``rosbags`` package
(not by wgslam), for ``test_bags.py``: wgslam's readers and message decoding are checked
against bytes another tool wrote.

Frames are read from the bundled PNGs by the small decoder here (zlib and the five PNG
row filters; the bundled files are 8-bit RGB and 16-bit grey, not interlaced), so writing
the bags needs only numpy and rosbags.
"""

import struct
import zlib
from pathlib import Path

import numpy as np
from rosbags.typesys import Stores, get_typestore

ICL_K = (481.20, -480.0, 319.5, 239.5)
DEPTH_TOPIC = "/camera/depth/image"
COLOR_TOPIC = "/camera/rgb/image_color"
INFO_TOPIC = "/camera/depth/camera_info"


def read_png(path: Path) -> np.ndarray:
    """A non-interlaced 8-bit RGB or 16-bit grey PNG as an array (rows, cols[, 3])."""
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n", path
    pos, idat, head = 8, b"", None
    while pos < len(data):
        (n,) = struct.unpack(">I", data[pos : pos + 4])
        kind = data[pos + 4 : pos + 8]
        body = data[pos + 8 : pos + 8 + n]
        if kind == b"IHDR":
            head = struct.unpack(">IIBBBBB", body)
        elif kind == b"IDAT":
            idat += body
        pos += 12 + n
    w, h, depth, colour, _, _, interlace = head
    assert interlace == 0 and (depth, colour) in [(8, 2), (16, 0), (8, 6)], (path, head)
    channels = {2: 3, 0: 1, 6: 4}[colour]
    bpp = channels * depth // 8
    raw = zlib.decompress(idat)
    stride = w * bpp
    out = np.zeros((h, stride), np.uint8)
    prev = np.zeros(stride, np.int32)
    for y in range(h):
        f = raw[y * (stride + 1)]
        line = np.frombuffer(raw, np.uint8, stride, y * (stride + 1) + 1).astype(np.int32)
        cur = np.zeros(stride, np.int32)
        if f in (0, 2):
            cur = (line + (prev if f == 2 else 0)) & 0xFF
        else:
            for x in range(stride):
                a = cur[x - bpp] if x >= bpp else 0
                b = prev[x]
                c = prev[x - bpp] if x >= bpp else 0
                if f == 1:
                    p = a
                elif f == 3:
                    p = (a + b) // 2
                else:
                    pa, pb, pc = abs(b - c), abs(a - c), abs(a + b - 2 * c)
                    p = a if pa <= pb and pa <= pc else (b if pb <= pc else c)
                cur[x] = (line[x] + p) & 0xFF
        out[y] = cur
        prev = cur
    if depth == 16:
        return out.view(">u2").reshape(h, w).astype(np.uint16)
    return out.reshape(h, w, channels)[:, :, :3]


def bundled_frames(root: Path, count: int):
    """(stamp, depth uint16 (h, w), rgb uint8 (h, w, 3)) of the first ``count`` frames of
    the bundled ICL-NUIM folder (``associations.txt``: stamp, depth file, stamp, rgb file)."""
    frames = []
    for line in (root / "associations.txt").read_text().splitlines()[:count]:
        stamp, depth, _, rgb = line.split()
        frames.append((int(stamp), read_png(root / depth), read_png(root / rgb)))
    return frames


def _messages(store, ros1: bool, frames):
    """(topic, msgtype, stamp ns, message) of the bag, in recording order: the camera info,
    then each frame's colour (bgr8, to test the channel swap) and depth (16UC1 raw units)."""
    t = store.types
    Header, Time = t["std_msgs/msg/Header"], t["builtin_interfaces/msg/Time"]
    Image, Info = t["sensor_msgs/msg/Image"], t["sensor_msgs/msg/CameraInfo"]
    RoI = t["sensor_msgs/msg/RegionOfInterest"]

    def header(sec):
        stamp = Time(sec=sec, nanosec=0)
        if ros1:
            return Header(seq=0, stamp=stamp, frame_id="camera")
        return Header(stamp=stamp, frame_id="camera")

    fx, fy, cx, cy = ICL_K
    k = np.array([fx, 0, cx, 0, fy, cy, 0, 0, 1], np.float64)
    r = np.eye(3).ravel()
    p = np.array([fx, 0, cx, 0, 0, fy, cy, 0, 0, 0, 1, 0], np.float64)
    h, w = frames[0][1].shape
    names = ("D", "K", "R", "P") if ros1 else ("d", "k", "r", "p")
    mats = dict(zip(names, (np.zeros(5), k, r, p)))
    roi = RoI(x_offset=0, y_offset=0, height=0, width=0, do_rectify=False)
    info = Info(header=header(0), height=h, width=w, distortion_model="plumb_bob",
                binning_x=0, binning_y=0, roi=roi, **mats)
    yield INFO_TOPIC, Info.__msgtype__, 0, info
    for stamp, depth, rgb in frames:
        ns = stamp * 1_000_000_000
        bgr = np.ascontiguousarray(rgb[:, :, ::-1]).ravel()
        yield COLOR_TOPIC, Image.__msgtype__, ns, Image(
            header=header(stamp), height=h, width=w, encoding="bgr8", is_bigendian=0,
            step=3 * w, data=bgr)
        yield DEPTH_TOPIC, Image.__msgtype__, ns + 1, Image(
            header=header(stamp), height=h, width=w, encoding="16UC1", is_bigendian=0,
            step=2 * w, data=depth.astype("<u2").view(np.uint8).ravel())


def write_ros1(path: Path, frames, lz4: bool = True):
    """A ROS 1 ``.bag`` (lz4 chunks unless ``lz4`` is false)."""
    from rosbags.rosbag1 import Writer

    store = get_typestore(Stores.ROS1_NOETIC)
    writer = Writer(path)
    if lz4:
        writer.set_compression(Writer.CompressionFormat.LZ4)
    with writer:
        conns = {}
        for topic, msgtype, ns, msg in _messages(store, True, frames):
            if topic not in conns:
                conns[topic] = writer.add_connection(topic, msgtype, typestore=store)
            writer.write(conns[topic], ns, store.serialize_ros1(msg, msgtype))


def write_ros2_sqlite(path: Path, frames):
    """A ROS 2 bag folder with ``metadata.yaml`` and one ``.db3`` file."""
    from rosbags.rosbag2 import StoragePlugin, Writer

    store = get_typestore(Stores.ROS2_HUMBLE)
    with Writer(path, version=8, storage_plugin=StoragePlugin.SQLITE3) as writer:
        conns = {}
        for topic, msgtype, ns, msg in _messages(store, False, frames):
            if topic not in conns:
                conns[topic] = writer.add_connection(topic, msgtype, typestore=store)
            writer.write(conns[topic], ns, store.serialize_cdr(msg, msgtype))


if __name__ == "__main__":
    import sys

    root, out, count = Path(sys.argv[1]), Path(sys.argv[2]), int(sys.argv[3])
    frames = bundled_frames(root, count)
    write_ros1(out / "frames.bag", frames)
    write_ros2_sqlite(out / "ros2", frames)
