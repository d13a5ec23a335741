"""geodrive: the GeoDrive toolkit's core in Python, over NumPy arrays.

Poses are (T, 4, 4) float64 matrices (world_from_cam unless named otherwise),
cameras (3, 3) K in integer-index pixels (OpenCV), images (H, W, 3) uint8 RGB.
Paths are str or os.PathLike (pathlib.Path). Errors are one line: bad input
raises ValueError with the command-line tool's message, an argument of the
wrong type TypeError naming it (geodrive/_args.py), out of memory MemoryError,
a file-system failure OSError naming the path. Rendering works in forked
children (multiprocessing), there on one thread per process.
``geodrive.torch.PairDataset`` reads built pairs for PyTorch.
"""
import json as _json

from . import _core
from ._args import check_methods as _check_methods
from ._args import checked as _checked
from ._core import Clip, ConditionScene, Dataset  # noqa: F401

for _cls in (Clip, ConditionScene, Dataset):
    _check_methods(_cls, _core)

ade_fde = _checked(_core.ade_fde, _core)
condition_scene = _checked(_core.condition_scene, _core)
edit_trajectory = _checked(_core.edit_trajectory, _core)
open_dataset = _checked(_core.open_dataset, _core)
psnr = _checked(_core.psnr, _core)
read_manifest = _checked(_core.read_manifest, _core)
read_trajectory = _checked(_core.read_trajectory, _core)
read_video = _checked(_core.read_video, _core)
reconstruction_format = _checked(_core.reconstruction_format, _core)
render = _checked(_core.render, _core)
render_with_edits = _checked(_core.render_with_edits, _core)
scene_sources = _checked(_core.scene_sources, _core)
ssim = _checked(_core.ssim, _core)
_read_meta_json = _checked(_core.read_meta_json, _core, "read_meta")
read_pair = _checked(_core.read_pair, _core)
_read_pair = read_pair  # the name before read_pair was public

__all__ = [
    "Clip", "ConditionScene", "Dataset", "ade_fde", "condition_scene",
    "edit_trajectory", "open_dataset", "psnr", "read_manifest", "read_meta",
    "read_pair", "read_trajectory", "read_video", "reconstruction_format", "render", "render_with_edits",
    "scene_sources", "ssim",
]


def read_meta(pair_dir):
    """A pair's meta.json (validated by the toolkit's reader) as a dict;
    pair_dir: str or os.PathLike."""
    return _json.loads(_read_meta_json(pair_dir))
