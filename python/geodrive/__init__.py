"""geodrive: the GeoDrive toolkit's core in Python, over NumPy arrays.

Poses are (T, 4, 4) float64 matrices (world_from_cam unless named otherwise),
cameras (3, 3) K in integer-index pixels (OpenCV), images (H, W, 3) uint8 RGB.
Bad input raises ValueError with the command-line tool's one-line message.
``geodrive.torch.PairDataset`` reads built pairs for PyTorch.
"""
import json as _json

from ._core import (  # noqa: F401
    Clip,
    ConditionScene,
    Dataset,
    ade_fde,
    condition_scene,
    edit_trajectory,
    open_dataset,
    psnr,
    read_manifest,
    read_trajectory,
    read_video,
    reconstruction_format,
    render,
    render_with_edits,
    scene_sources,
    ssim,
)
from ._core import read_meta_json as _read_meta_json

__all__ = [
    "Clip", "ConditionScene", "Dataset", "ade_fde", "condition_scene",
    "edit_trajectory", "open_dataset", "psnr", "read_manifest", "read_meta",
    "read_trajectory", "read_video", "reconstruction_format", "render", "render_with_edits",
    "scene_sources", "ssim",
]


def read_meta(pair_dir):
    """A pair's meta.json (validated by the toolkit's reader) as a dict."""
    return _json.loads(_read_meta_json(pair_dir))
