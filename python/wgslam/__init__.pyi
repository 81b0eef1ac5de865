"""Type stubs of the package ``wgslam`` (python/wgslam/__init__.py holds the docstrings)."""

from os import PathLike
from typing import Any, Callable, Dict, List, Optional, Sequence as _Seq, Tuple, Union

import numpy as np
import numpy.typing as npt

from ._native import Error as Error, Sequence as Sequence

METRES_DEPTH_SCALE: float
TRACKED_STATUSES: Tuple[str, ...]
_Path = Union[str, PathLike[str]]
_Frames = Union[None, str, Tuple[int, int], range]
_Params = Optional[Dict[str, Any]]

class RunResult:
    stamps: npt.NDArray[np.float64]
    poses: npt.NDArray[np.float64]
    metrics: Dict[str, Any]
    @property
    def trajectory(self) -> Tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]: ...
    @property
    def odometry(self) -> Tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]: ...
    @property
    def map(self) -> Dict[str, np.ndarray]: ...
    @property
    def frames(self) -> List[Dict[str, Any]]: ...
    def write(self, out_dir: _Path) -> None: ...

def run(
    dataset: Optional[_Path] = None,
    frames: _Frames = None,
    backend: str = "auto",
    params: _Params = None,
    *,
    poses: str = "track",
    progress: Optional[Callable[[int, int], Any]] = None,
) -> RunResult: ...
def open_sequence(dataset: Optional[_Path] = None, params: _Params = None) -> Sequence: ...

class Track:
    pose: npt.NDArray[np.float64]
    status: str
    detail: str
    report_json: str
    @property
    def tracked(self) -> bool: ...
    @property
    def report(self) -> Dict[str, Any]: ...

class Slam:
    width: int
    height: int
    def __init__(
        self,
        intrinsics: Union[_Seq[float], Dict[str, float]],
        params: _Params = None,
        backend: str = "auto",
        *,
        depth_scale: Optional[float] = None,
        poses: str = "track",
    ) -> None: ...
    @classmethod
    def for_sequence(
        cls, sequence: Sequence, params: _Params = None, backend: str = "auto", *, poses: str = "track"
    ) -> Slam: ...
    def track(
        self,
        depth: Union[npt.NDArray[np.uint16], npt.NDArray[np.float32]],
        color: Optional[npt.NDArray[np.uint8]] = None,
        timestamp: Optional[float] = None,
        *,
        pose: Optional[npt.NDArray[np.float64]] = None,
        frame_id: Optional[int] = None,
    ) -> Track: ...
    @property
    def downsample(self) -> int: ...
    @property
    def downsample_from(self) -> str: ...
    def map(self) -> Dict[str, np.ndarray]: ...
    def trajectory(self) -> Tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]: ...
