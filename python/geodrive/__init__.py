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
import os as _os

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
_plan_json = _checked(_core.plan_json, _core, "plan")
read_pair = _checked(_core.read_pair, _core)
_read_pair = read_pair  # the name before read_pair was public

__all__ = [
    "Clip", "ConditionScene", "Dataset", "ade_fde", "condition_scene",
    "edit_trajectory", "open_dataset", "plan", "psnr", "read_manifest", "read_meta",
    "read_pair", "read_trajectory", "read_video", "reconstruction_format", "render", "render_with_edits",
    "scene_sources", "ssim",
]


def read_meta(pair_dir):
    """A pair's meta.json (validated by the toolkit's reader) as a dict;
    pair_dir: str or os.PathLike."""
    return _json.loads(_read_meta_json(pair_dir))


def plan(clip, candidates=(), shifts=(), sample=0, with_logged=True):
    """Scores candidate ego trajectories against a clip's geometry (the
    numbers of `geodrive plan`'s plan.json, docs/PLANNING.md) and returns one
    dict per candidate, in scoring order: the logged trajectory (with_logged),
    its lateral shifts by +-each of `shifts` (m), candidate files, waypoint
    arrays, then `sample` lattice candidates. Each dict has name, rank, cost,
    rejected, reject_reason, reject_detail, collision, drivable, kinematics
    and logged.

    candidates: paths (a .jsonl of waypoints or any trajectory file), (N, 4)
    float arrays of t, x, y, yaw in the ego frame of the clip's first frame
    (seconds, metres, radians), or dicts {"name": str, "waypoints": array}.
    """
    paths, names, arrays = [], [], []
    for i, c in enumerate(candidates):
        if isinstance(c, (str, bytes, _os.PathLike)):
            paths.append(c)
        elif isinstance(c, dict):
            names.append(str(c.get("name", "candidate-%d" % i)))
            arrays.append(c["waypoints"])
        else:
            names.append("candidate-%d" % i)
            arrays.append(c)
    text = _plan_json(clip, paths, names, arrays, [float(d) for d in shifts],
                      int(sample), bool(with_logged))
    return _json.loads(text)["candidates"]
