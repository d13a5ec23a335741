"""Type hints of geodrive (the pybind11 extension geodrive._core)."""
import os
from typing import Any, Dict, List, Optional, Sequence, Tuple, TypedDict

import numpy as np
import numpy.typing as npt

F32 = npt.NDArray[np.float32]
F64 = npt.NDArray[np.float64]
U8 = npt.NDArray[np.uint8]

class Clip:
    id: str
    scene_name: str
    num_frames: int
    timestamps_us: npt.NDArray[np.int64]
    image_paths: List[str]
    world_from_cam: F64  # (T, 4, 4)
    world_from_ego: F64  # (T, 4, 4)
    intrinsics: F64  # (T, 3, 3)
    image_size: Tuple[int, int]  # (width, height)
    def boxes(self, frame: int) -> List[Dict[str, Any]]: ...
    def lidar_sweeps(self) -> List[Dict[str, Any]]: ...
    def load_sweep(self, index: int) -> F32: ...  # (N, 5)

# Stub-only types (plain dicts at run time).
class _PairView(TypedDict):
    """One camera of a surround-view pair: read_pair(...)["views"][k]."""
    channel: str
    gt_video: str
    cond_video: str
    num_frames: int
    timestamps_us: npt.NDArray[np.int64]  # (T,)
    K: F64  # (3, 3) at the output size
    image_size: Tuple[int, int]  # (width, height)
    world_from_cam: F64  # (T, 4, 4), world = the reference camera at frame 0
    coverage: List[float]
    psnr_static: List[Optional[float]]
    supported_fraction: Optional[float]
    coverage_of_supported: Optional[float]
    points_built: int
    points_kept: int

class _PairSeam(TypedDict):
    camera_a: str
    camera_b: str
    overlap_pixels: int
    agreeing_fraction: float

class _Pair(TypedDict):
    """A manifest line's pair, checked (ReadPair); cameras, views and seams
    are empty for a single-camera pair."""
    dir: str
    gt_video: str
    cond_video: str
    num_frames: int
    cameras: List[str]
    views: List[_PairView]
    seams: List[_PairSeam]

class Dataset:
    clip_ids: List[str]
    has_lidar: bool
    def describe(self) -> str: ...
    def scenes(self) -> List[str]: ...
    def load_clip(self, clip_id: str) -> Clip: ...

class ConditionScene:
    points: F32  # (N, 3)
    colors: U8  # (N, 3)
    footprints: Optional[F32]  # (N,) capture footprints, or None
    footprint_axes: Optional[F32]  # (N, 6) surface axes per capture pixel, or None
    poses: F64  # (T, 4, 4) scene_from_cam
    K: F64  # (3, 3)
    image_size: Tuple[int, int]
    units: str
    description: str
    scale_report: str
    def K_at(self, width: int, height: int) -> F64: ...

def open_dataset(root: str | os.PathLike[str], version: str = "v1.0-mini",
                 frames: str = "all", channel: str = "CAM_FRONT",
                 clip_frames: int = 25, stride: int = 6) -> Dataset: ...
def scene_sources() -> List[str]: ...
def condition_scene(source: str, path: str | os.PathLike[str] = "",
                    clip: Optional[Clip] = None,
                    filter: str = "paper") -> ConditionScene: ...
def reconstruction_format(path: str | os.PathLike[str]) -> Optional[str]: ...
def render(points: F32, colors: U8, K: F64, cam_from_world: F64,
           size: Tuple[int, int] = (480, 720), mode: str = "zbuffer",
           radius: float = 0.0, near: float = 0.1, far: float = 100.0,
           threads: int = 0,
           out: Optional[Dict[str, np.ndarray]] = None,
           footprints: Optional[F32] = None,
           footprint_axes: Optional[F32] = None,
           max_magnification: float = 8.0) -> Dict[str, np.ndarray]: ...
def render_with_edits(points: F32, colors: U8, K: F64, cam_from_world: F64,
                      boxes: str | os.PathLike[str],
                      size: Tuple[int, int] = (480, 720),
                      mode: str = "3d", remove: Sequence[str] = (),
                      radius: float = 0.0,
                      frame0_image: Optional[U8] = None) -> Dict[str, Any]: ...
def edit_trajectory(world_from_cam: F64, times: Optional[F64] = None,
                    shift_left: float = 0.0, shift_right: float = 0.0,
                    shift_up: float = 0.0, yaw_deg: float = 0.0,
                    speed: float = 1.0, reverse: bool = False) -> F64: ...
def read_trajectory(path: str | os.PathLike[str]) -> Tuple[F64, F64]: ...
def psnr(a: U8, b: U8) -> float: ...
def ssim(a: U8, b: U8) -> float: ...
def ade_fde(pred: F64, gt: F64, align: str = "none") -> Dict[str, Any]: ...
def plan(clip: Clip,
         candidates: Sequence[str | os.PathLike[str] | F64 | Dict[str, Any]] = ...,
         shifts: Sequence[float] = ..., sample: int = 0,
         with_logged: bool = True) -> List[Dict[str, Any]]: ...
def read_manifest(path: str | os.PathLike[str]) -> List[Dict[str, Any]]: ...
def read_meta(pair_dir: str | os.PathLike[str]) -> Dict[str, Any]: ...
def read_pair(build_dir: str | os.PathLike[str],
              entry: Dict[str, Any]) -> _Pair: ...
def read_video(path: str | os.PathLike[str]) -> U8: ...
