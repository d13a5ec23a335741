"""PyTorch access to pairs built by ``geodrive build-dataset``.

``PairDataset(manifest)`` yields ``{"gt": (T, 3, H, W), "cond": (T, 3, H, W),
"meta": dict}``: float32 tensors in [-1, 1], the layout GeoDrive's trainer
feeds CogVideoX, and the pair's manifest line (flat: clip_id, pair_dir, scene,
num_frames, geometry_source, pose_units, mean_coverage, options_hash, so the
default collate batches it; the whole meta.json: ``geodrive.read_meta``); ``frames=49`` pads 25 frames to 49 by repeating the last one
(upstream's loader). Videos are decoded by the toolkit's own FFmpeg reader
(geodrive.read_video); each DataLoader worker process opens its own files, so
``num_workers > 0`` is safe.
"""
import concurrent.futures
import os

import numpy as np
import torch

from . import _read_pair as read_pair
from . import read_manifest, read_video
from ._args import check as _check

__all__ = ["PairDataset"]

_pools = {}


def _pool():
    """A 2-thread pool per process (DataLoader workers are forked: a pool
    made before the fork has no threads in the child)."""
    pid = os.getpid()
    if pid not in _pools:
        _pools.clear()
        _pools[pid] = concurrent.futures.ThreadPoolExecutor(2)
    return _pools[pid]


def _to_tensor(frames, size, frames_out):
    """(T, H, W, 3) uint8 -> (T', 3, H', W') float32 in [-1, 1]."""
    x = torch.from_numpy(np.ascontiguousarray(frames)).permute(0, 3, 1, 2)
    x = x.float().div_(127.5).sub_(1.0)
    if size is not None and tuple(x.shape[-2:]) != tuple(size):
        x = torch.nn.functional.interpolate(
            x, size=tuple(size), mode="bilinear", align_corners=False)
    if frames_out is not None:
        if frames_out < 1:
            raise ValueError("frames must be >= 1")
        if x.shape[0] >= frames_out:
            x = x[:frames_out]
        else:  # repeat the last frame (GeoDrive's 25 -> 49 padding)
            pad = x[-1:].expand(frames_out - x.shape[0], -1, -1, -1)
            x = torch.cat([x, pad], 0)
    return x.contiguous()


class PairDataset(torch.utils.data.Dataset):
    """The pairs listed in a build's manifest.jsonl.

    Args:
      manifest: path (str or os.PathLike) of OUT/manifest.jsonl (pair folders
        are next to it).
      frames: frames per item (None = as built; 49 pads 25 -> 49).
      size: (H, W) to resize to (None = as built).
    """

    def __init__(self, manifest, frames=None, size=None):
        _check("PairDataset()", "manifest", "os.PathLike", manifest)
        _check("PairDataset()", "frames", "Optional[int]", frames)
        _check("PairDataset()", "size", "Optional[Tuple[int, int]]", size)
        manifest = os.fsdecode(manifest)
        self.root = os.path.dirname(os.path.abspath(manifest))
        self.entries = read_manifest(manifest)
        self.frames = frames
        self.size = size

    def __len__(self):
        return len(self.entries)

    def __getitem__(self, i):
        e = self.entries[i]
        # The C++ reader's checks (pair_dir inside the build, meta.json's
        # clip id, the listed videos present).
        pair = read_pair(self.root, e)
        # The two videos decode at once (read_video releases the GIL); each
        # decode is single-threaded, so the frames are the same everywhere.
        gt, cond = _pool().map(read_video, [
            os.path.join(pair["dir"], "gt.mp4"),
            os.path.join(pair["dir"], "cond.mp4")])
        for name, video in (("gt", gt), ("cond", cond)):
            if video.shape[0] != pair["num_frames"]:
                raise ValueError(
                    "%s: %s video has %d frames, meta.json lists %d" % (
                        pair["dir"], name, video.shape[0], pair["num_frames"]))
        return {
            "gt": _to_tensor(gt, self.size, self.frames),
            "cond": _to_tensor(cond, self.size, self.frames),
            "meta": dict(e),
        }
