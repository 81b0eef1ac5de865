"""Type stubs of the extension module ``wgslam._native`` (python/src). Use the package
``wgslam``; its functions check arrays and give the documented API over these."""

from os import PathLike
from typing import Any, Callable, Dict, List, Optional, Tuple

import numpy as np
import numpy.typing as npt

class Error(RuntimeError):
    """A run failed: the message is the command line's (what ``wgslam`` prints after ``error: ``)."""

class Run:
    def trajectory(self) -> Tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]: ...
    def odometry(self) -> Tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]: ...
    def map(self) -> Dict[str, np.ndarray]: ...
    def metrics_json(self) -> str: ...
    def frames_json(self) -> str: ...
    def write(self, out_dir: str) -> None: ...

class Sequence:
    """An opened dataset (``wgslam.open_sequence``): camera, depth scale, stamps, ground
    truth, and its frames as arrays."""
    def __len__(self) -> int: ...
    def intrinsics(self) -> Tuple[int, int, float, float, float, float]:
        """The depth images' camera: ``(width, height, fx, fy, cx, cy)``, pixels."""
    def depth_scale(self) -> float:
        """Raw depth units per metre."""
    def default_first_frame(self) -> int:
        """The first frame ``wgslam run`` runs without ``--frames`` (the first with ground truth)."""
    def timestamp(self, i: int) -> float:
        """Frame ``i``'s stamp (seconds, or the frame number where the layout has no clock)."""
    def ground_truth(self, i: int) -> Optional[npt.NDArray[np.float64]]:
        """Frame ``i``'s ground-truth camera-to-world pose, (4, 4) float64, or ``None``."""
    def frame(self, i: int) -> Tuple[npt.NDArray[np.uint16], npt.NDArray[np.uint8]]:
        """Frame ``i``'s images as a run decodes them: depth (H, W) uint16 raw units, RGB
        (H, W, 3) uint8."""

class Slam:
    def __init__(
        self,
        intrinsics: Tuple[int, int, float, float, float, float],
        depth_scale: float,
        backend: str,
        poses: str,
        params_json: str,
    ) -> None: ...
    def track(
        self,
        depth_raw: Optional[npt.NDArray[np.uint16]],
        depth_m: Optional[npt.NDArray[np.float32]],
        color: Optional[npt.NDArray[np.uint8]],
        timestamp: Optional[float],
        pose: Optional[npt.NDArray[np.float64]],
        frame_id: Optional[int],
    ) -> Tuple[npt.NDArray[np.float64], str, str, str]: ...
    @property
    def downsample(self) -> int: ...
    @property
    def downsample_from(self) -> str: ...
    def map(self) -> Dict[str, np.ndarray]: ...
    def trajectory(self) -> Tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]: ...

def run(
    dataset: Optional[str],
    frames: Optional[str],
    backend: str,
    poses: str,
    params_json: str,
    progress: Optional[Callable[[int, int], Any]] = None,
) -> Run: ...
def open_sequence(dataset: Optional[str], params_json: str) -> Sequence: ...
def main(args: List[str]) -> int: ...
def devices_opened() -> int: ...
