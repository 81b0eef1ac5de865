"""wgslam: dense RGB-D SLAM (point-based fusion, point-to-plane ICP) on the GPU through wgpu.

Frames in as numpy arrays, results out as numpy arrays (docs/python.md):

- :func:`run` runs the whole pipeline over a dataset, as ``wgslam run`` does, and returns a
  :class:`RunResult` (trajectory, map, metrics, per-frame records; ``write`` for the usual
  output files).
- :class:`Slam` tracks a live stream one frame at a time (:meth:`Slam.track`), with the map
  at any time (:meth:`Slam.map`).
- :func:`open_sequence` reads a dataset's frames as arrays (to replay them through
  :class:`Slam`, or to look at them); a ROS bag or MCAP recording is a dataset too.
- :mod:`wgslam.ros` turns live ROS messages (``sensor_msgs/Image``, ``CameraInfo``) into
  the arrays :meth:`Slam.track` takes.

Poses are 4x4 float64 camera-to-world matrices (metres), row-major. Frames are processed
with the interpreter's lock released, so other Python threads run meanwhile. Failures of a
run raise :class:`Error` with the command line's message; arrays of the wrong dtype or shape
raise ``TypeError`` / ``ValueError`` before any work.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from typing import Any, Callable, Dict, List, Optional, Sequence as _Seq, Tuple, Union

import numpy as np

from . import _native
from ._native import Error, Sequence

__all__ = ["run", "RunResult", "Slam", "Track", "open_sequence", "Sequence", "Error"]

#: Raw depth units per metre a :class:`Slam` given float32 metres uses inside (when no
#: ``depth_scale`` is given): 0.2 mm steps, up to 13.1 m (TUM's and ICL-NUIM's scale).
METRES_DEPTH_SCALE = 5000.0

PathLike = Union[str, "os.PathLike[str]"]


def _params_json(params: Optional[Dict[str, Any]]) -> str:
    """The ``params`` dict (a parameter file's keys and sections) as JSON for the extension."""
    if params is None:
        return "{}"
    if not isinstance(params, dict):
        raise TypeError(
            f"params must be a dict of parameter-file keys (docs/params-file.md), "
            f"not {type(params).__name__}"
        )
    return json.dumps(params)


def _frames_range(frames: Union[None, str, Tuple[int, int], range]) -> Optional[str]:
    """``frames`` as the command line's inclusive ``"A..B"``."""
    if frames is None or isinstance(frames, str):
        return frames
    if isinstance(frames, range):
        if frames.step != 1 or len(frames) == 0:
            raise ValueError(f"frames {frames!r}: want a non-empty range with step 1")
        return f"{frames.start}..{frames.stop - 1}"
    if isinstance(frames, tuple) and len(frames) == 2:
        return f"{int(frames[0])}..{int(frames[1])}"
    raise TypeError(f"frames {frames!r}: want \"A..B\", (first, last) inclusive, or a range")


def _path(p: Optional[PathLike]) -> Optional[str]:
    return None if p is None else os.fspath(p)


class RunResult:
    """A finished run (:func:`run`): what ``wgslam run`` writes, as arrays and dicts."""

    def __init__(self, native: Any) -> None:
        self._native = native
        self.stamps: np.ndarray
        """Stamps of ``trajectory.tum``'s poses, ``(N,)`` float64 seconds (or frame numbers)."""
        self.poses: np.ndarray
        """``trajectory.tum``'s poses, ``(N, 4, 4)`` float64 camera to world; after loop
        closure when it ran. Lost and empty frames have no pose."""
        self.stamps, self.poses = native.trajectory()
        self.metrics: Dict[str, Any] = json.loads(native.metrics_json())
        """``metrics.json``: timings, map size, tracking counts, ATE/RPE against ground truth."""
        self._frames: Optional[List[Dict[str, Any]]] = None
        self._map: Optional[Dict[str, np.ndarray]] = None

    @property
    def trajectory(self) -> Tuple[np.ndarray, np.ndarray]:
        """``(stamps, poses)``: see :attr:`stamps` and :attr:`poses`."""
        return self.stamps, self.poses

    @property
    def odometry(self) -> Tuple[np.ndarray, np.ndarray]:
        """``trajectory_odometry.tum``: the poses as tracked, before any loop closure."""
        return self._native.odometry()

    @property
    def map(self) -> Dict[str, np.ndarray]:
        """The map, one row per surfel: ``positions`` (N, 3) float32 metres and ``normals``
        (N, 3) float32, world frame; ``colors`` (N, 3) uint8 RGB; ``weights`` (N,) float32;
        ``radii`` (N,) float32 metres; ``last_frames`` (N,) uint32."""
        if self._map is None:
            self._map = self._native.map()
        return self._map

    @property
    def frames(self) -> List[Dict[str, Any]]:
        """``frames.json``: one record per frame (index, stamp, times, the pipeline's report)."""
        if self._frames is None:
            self._frames = json.loads(self._native.frames_json())
        return self._frames

    def write(self, out_dir: PathLike) -> None:
        """Writes the files ``wgslam run --out OUT_DIR`` writes (trajectory.tum,
        trajectory_odometry.tum, map.ply, metrics.json, frames.json and the pictures), as a
        set: each complete or not written."""
        self._native.write(os.fspath(out_dir))


def run(
    dataset: Optional[PathLike] = None,
    frames: Union[None, str, Tuple[int, int], range] = None,
    backend: str = "auto",
    params: Optional[Dict[str, Any]] = None,
    *,
    poses: str = "track",
    progress: Optional[Callable[[int, int], Any]] = None,
) -> RunResult:
    """Runs dense SLAM over a dataset, as ``wgslam run DATASET`` does (no files written).

    ``dataset``: the sequence's folder (any layout the command line reads; ``None``: the
    bundled frames). ``frames``: ``"A..B"``, ``(A, B)`` (inclusive) or a ``range``, by
    position (default: from the first frame with ground truth to the last). ``backend``:
    ``"auto"``, ``"cpu"`` or ``"gpu"``. ``params``: a parameter file's keys and sections
    as a dict (``{"profile": "robust", "icp": {"dist_m": 0.08}}``; docs/params-file.md).
    ``poses``: ``"track"`` or ``"gt"`` (fuse at ground truth). ``progress``: called as
    ``progress(done, total)`` after each frame; an exception it raises (or Ctrl-C) stops
    the run and is raised here.
    """
    native = _native.run(
        _path(dataset), _frames_range(frames), backend, poses, _params_json(params), progress
    )
    return RunResult(native)


def open_sequence(dataset: Optional[PathLike] = None, params: Optional[Dict[str, Any]] = None) -> Sequence:
    """Opens a dataset as ``wgslam run`` does (the dataset keys of ``params`` apply:
    ``camera``, ``intrinsics``, ``depth-scale``, ``gt``, ``max-time-diff``); its frames come
    out as arrays (:meth:`Sequence.frame`)."""
    return _native.open_sequence(_path(dataset), _params_json(params))


#: Track statuses whose frame has a pose the run stands by (fused, in the trajectory).
TRACKED_STATUSES = ("given", "tracked", "relocalised")


@dataclass
class Track:
    """What :meth:`Slam.track` made of a frame."""

    pose: np.ndarray
    """Camera to world, (4, 4) float64: the frame's pose, or for a lost or empty frame the
    last tracked one."""
    status: str
    """``"tracked"`` (ICP from the last pose), ``"given"`` (the first frame, or a given
    pose), ``"relocalised"``, ``"lost"`` (not fused) or ``"empty"`` (no depth)."""
    detail: str
    """The pipeline's words: how ICP ended, why tracking was lost."""
    report_json: str = field(repr=False)

    @property
    def tracked(self) -> bool:
        """Whether the frame has a pose the run stands by (fused, in the trajectory)."""
        return self.status in TRACKED_STATUSES

    @property
    def report(self) -> Dict[str, Any]:
        """The pipeline's full report of the frame (as in ``frames.json``)."""
        return json.loads(self.report_json)


def _shape_error(what: str, arr: np.ndarray, want: Tuple[int, ...], layout: str) -> ValueError:
    got = tuple(arr.shape)
    hint = ""
    if len(got) >= 2 and got[:2] == (want[1], want[0]) and got[2:] == want[2:]:
        hint = " (a transposed image? numpy images are (height, width))"
    elif what == "color" and got[:2] == want[:2] and len(got) == 3 and got[2] == 4:
        hint = " (RGBA? give RGB: color[..., :3])"
    return ValueError(f"{what} has shape {got}, expected {want} {layout}{hint}")


class Slam:
    """A streaming tracker for live sensors: one frame at a time, the map at any time.

    ``intrinsics``: the depth camera's ``(width, height, fx, fy, cx, cy)`` in pixels (or a
    dict with those keys). ``params``: a parameter file's keys and sections as a dict
    (docs/params-file.md; robust profile by default). ``backend``: ``"auto"``, ``"cpu"``
    or ``"gpu"``. ``depth_scale``: raw depth units per metre of uint16 depth (1000 for
    millimetres; ``1 / depth_sensor.get_depth_scale()`` with pyrealsense2); without it,
    only float32 metres are taken (held inside at :data:`METRES_DEPTH_SCALE`). ``poses``:
    ``"track"``, or ``"gt"`` to fuse at the pose given to every :meth:`track`.

    Colour and depth must be registered (the same pixels). Fed a sequence's frames with
    their frame numbers and the first frame's ground truth (``for_sequence`` and
    ``track(..., pose=gt, frame_id=i)``), it gives ``wgslam run``'s trajectory bit for bit.
    """

    def __init__(
        self,
        intrinsics: Union[_Seq[float], Dict[str, float]],
        params: Optional[Dict[str, Any]] = None,
        backend: str = "auto",
        *,
        depth_scale: Optional[float] = None,
        poses: str = "track",
    ) -> None:
        if isinstance(intrinsics, dict):
            intrinsics = tuple(intrinsics[k] for k in ("width", "height", "fx", "fy", "cx", "cy"))
        if len(intrinsics) != 6:
            raise ValueError(
                f"intrinsics {intrinsics!r}: want (width, height, fx, fy, cx, cy)"
            )
        w, h, fx, fy, cx, cy = intrinsics
        self.width, self.height = int(w), int(h)
        self._raw_scale_given = depth_scale is not None
        scale = float(depth_scale) if depth_scale is not None else METRES_DEPTH_SCALE
        self._native = _native.Slam(
            (self.width, self.height, float(fx), float(fy), float(cx), float(cy)),
            scale,
            backend,
            poses,
            _params_json(params),
        )

    @classmethod
    def for_sequence(
        cls,
        sequence: Sequence,
        params: Optional[Dict[str, Any]] = None,
        backend: str = "auto",
        *,
        poses: str = "track",
    ) -> "Slam":
        """A tracker with a sequence's camera and depth scale (:func:`open_sequence`)."""
        return cls(
            sequence.intrinsics(),
            params,
            backend,
            depth_scale=sequence.depth_scale(),
            poses=poses,
        )

    def _check_depth(self, depth: Any) -> np.ndarray:
        if not isinstance(depth, np.ndarray):
            raise TypeError(f"depth must be a numpy array, not {type(depth).__name__}")
        if depth.dtype not in (np.uint16, np.float32):
            raise TypeError(
                f"depth has dtype {depth.dtype}: want uint16 raw units (with depth_scale) or "
                f"float32 metres (depth.astype(np.float32))"
            )
        if depth.dtype == np.uint16 and not self._raw_scale_given:
            raise ValueError(
                "uint16 depth needs its scale: construct Slam(..., depth_scale=UNITS_PER_METRE) "
                "(1000 for millimetres), or give float32 metres"
            )
        want = (self.height, self.width)
        if depth.shape != want:
            raise _shape_error("depth", depth, want, "(height, width)")
        return depth

    def _check_color(self, color: Any) -> Optional[np.ndarray]:
        if color is None:
            return None
        if not isinstance(color, np.ndarray):
            raise TypeError(f"color must be a numpy array, not {type(color).__name__}")
        if color.dtype != np.uint8:
            raise TypeError(f"color has dtype {color.dtype}: want uint8 RGB")
        want = (self.height, self.width, 3)
        if color.shape != want:
            raise _shape_error("color", color, want, "(height, width, RGB)")
        return color

    def track(
        self,
        depth: np.ndarray,
        color: Optional[np.ndarray] = None,
        timestamp: Optional[float] = None,
        *,
        pose: Optional[np.ndarray] = None,
        frame_id: Optional[int] = None,
    ) -> Track:
        """Tracks and fuses one frame; returns its pose and status as they happen.

        ``depth``: (H, W) uint16 raw units (the constructor's ``depth_scale``) or float32
        metres; 0 (or NaN) is no reading. ``color``: (H, W, 3) uint8 RGB, or ``None`` (black;
        relocalisation's keyframe codes read colour, so give it when you have it).
        ``timestamp``: seconds, for the trajectory (default: the frame number). ``pose``:
        a known camera-to-world (4, 4): the first frame's places the map (default: the
        identity); with ``poses="gt"`` every frame needs one. ``frame_id``: the frame's
        number, stored in the map and read by the surfel removal's schedule (default: the
        last one plus one, from 0); each must be greater than the last (:class:`Error`).
        """
        depth = self._check_depth(depth)
        color = self._check_color(color)
        if pose is not None:
            pose = np.asarray(pose, dtype=np.float64)
        raw, metres = (depth, None) if depth.dtype == np.uint16 else (None, depth)
        pose_out, status, detail, report = self._native.track(
            raw, metres, color, None if timestamp is None else float(timestamp), pose,
            None if frame_id is None else int(frame_id),
        )
        return Track(pose_out, status, detail, report)

    @property
    def downsample(self) -> int:
        """The input's downsampling: 1 tracks every pixel, 2 every second pixel in each
        direction. Unless ``params`` set it, the backend's default, as ``wgslam run``
        chooses it (every pixel on the GPU, every second pixel on the CPU)."""
        return self._native.downsample

    @property
    def downsample_from(self) -> str:
        """Where :attr:`downsample` came from, as ``metrics.json``'s ``downsample_from``:
        ``"set"`` (``params``), ``"gpu-default"`` or ``"cpu-default"``."""
        return self._native.downsample_from

    def map(self) -> Dict[str, np.ndarray]:
        """The map now (a copy from the backend), as :attr:`RunResult.map`."""
        return self._native.map()

    def trajectory(self) -> Tuple[np.ndarray, np.ndarray]:
        """``(stamps (N,), poses (N, 4, 4))`` of the tracked frames so far, camera to world,
        after loop closure when it runs (as ``trajectory.tum``)."""
        return self._native.trajectory()
