"""PyTorch access to pairs built by ``geodrive build-dataset``.

``PairDataset(manifest)`` yields ``{"gt": (T, 3, H, W), "cond": (T, 3, H, W),
"meta": dict}``: float32 tensors in [-1, 1], the layout GeoDrive's trainer
feeds CogVideoX, and the pair's manifest line (flat: clip_id, pair_dir, scene,
num_frames, geometry_source, pose_units, mean_coverage, options_hash, so the
default collate batches it; the whole meta.json: ``geodrive.read_meta``); ``frames=49`` pads 25 frames to 49 by repeating the last one
(upstream's loader). Videos are decoded by the toolkit's own FFmpeg reader
(geodrive.read_video); each DataLoader worker process opens its own files, so
``num_workers > 0`` is safe.

A surround-view pair (``build-dataset --cameras``; its manifest line has
``cameras``) yields ``{"gt": (V, T, 3, H, W), "cond": (V, T, 3, H, W),
"cameras": [V names], "meta": dict}``: view k is camera ``cameras[k]``, in
the order of meta.json's ``views`` (the reference camera first), or of
``PairDataset(..., cameras=[...])``, which selects views. Frames are checked
against meta.json per video: a view video with another frame count or size
is a ValueError naming the file.

A manifest mixing single-camera and surround-view pairs (or rigs of other
cameras) yields items of different shapes and keys, which the default
collate cannot batch together: batch one kind at a time (a sampler grouping
by ``dataset.entries[i].get("cameras")``, or ``batch_size=1``). For
surround-view pairs of different rigs, ``cameras=`` gives every item the
same views; a pair without one of them (a single-camera pair included) is
refused when the dataset is made, naming the pair.
"""
import concurrent.futures
import os

import numpy as np
import torch

from . import read_manifest, read_pair, read_video
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
      cameras: surround-view pairs only: the views to read, in this order
        (None = every view of each pair, as meta.json lists them). A pair
        without one of them, or a single-camera pair, is a ValueError here.

    Items: single-camera pair ``{"gt", "cond": (T, 3, H, W), "meta"}``;
    surround-view pair ``{"gt", "cond": (V, T, 3, H, W), "cameras", "meta"}``
    (the default collate batches items of one kind and one camera list; it
    turns ``cameras`` into V tuples of the batch's names).
    """

    def __init__(self, manifest, frames=None, size=None, cameras=None):
        _check("PairDataset()", "manifest", "os.PathLike", manifest)
        _check("PairDataset()", "frames", "Optional[int]", frames)
        _check("PairDataset()", "size", "Optional[Tuple[int, int]]", size)
        _check("PairDataset()", "cameras", "Optional[List[str]]", cameras)
        manifest = os.fsdecode(manifest)
        self.root = os.path.dirname(os.path.abspath(manifest))
        self.entries = read_manifest(manifest)
        self.frames = frames
        self.size = size
        self.cameras = None
        if cameras is not None:
            self.cameras = [os.fsdecode(c) for c in cameras]
            if not self.cameras:
                raise ValueError("PairDataset(): cameras is empty (None reads "
                                 "every view)")
            for c in self.cameras:
                if self.cameras.count(c) > 1:
                    raise ValueError("PairDataset(): camera %s is listed "
                                     "twice in cameras" % c)
            for e in self.entries:
                have = e.get("cameras")
                if not have:
                    raise ValueError(
                        "%s: pair %s is a single-camera pair; cameras= "
                        "selects views of surround-view pairs (build-dataset "
                        "--cameras)" % (manifest, e["clip_id"]))
                missing = [c for c in self.cameras if c not in have]
                if missing:
                    raise ValueError(
                        "%s: pair %s has no camera %s (its cameras: %s)" % (
                            manifest, e["clip_id"], ", ".join(missing),
                            ", ".join(have)))

    def __len__(self):
        return len(self.entries)

    def __getitem__(self, i):
        e = self.entries[i]
        # The C++ reader's checks (pair_dir inside the build, meta.json's
        # clip id, the listed videos present).
        pair = read_pair(self.root, e)
        if pair["cameras"] != e.get("cameras", []):
            raise ValueError(
                "%s/meta.json: views [%s] differ from the manifest line's "
                "cameras [%s]" % (pair["dir"], ", ".join(pair["cameras"]),
                                  ", ".join(e.get("cameras", []))))
        if pair["cameras"]:
            return self._surround_view(pair, e)
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

    def _surround_view(self, pair, e):
        """(V, T, 3, H, W) gt and cond of the selected views."""
        views = pair["views"]
        if self.cameras is not None:
            views = [views[pair["cameras"].index(c)] for c in self.cameras]
        paths = [v["gt_video"] for v in views] + [v["cond_video"] for v in views]
        videos = list(_pool().map(read_video, paths))
        for path, video, view in zip(paths, videos, views + views):
            width, height = view["image_size"]
            if video.shape[0] != pair["num_frames"]:
                raise ValueError(
                    "%s: %s video has %d frames, meta.json lists %d" % (
                        path, view["channel"], video.shape[0],
                        pair["num_frames"]))
            if video.shape[1:3] != (height, width):
                raise ValueError(
                    "%s: %s video is %dx%d (HxW), meta.json's intrinsics "
                    "%dx%d" % (path, view["channel"], video.shape[1],
                               video.shape[2], height, width))
        n = len(views)
        return {
            "gt": torch.stack([_to_tensor(v, self.size, self.frames)
                               for v in videos[:n]]),
            "cond": torch.stack([_to_tensor(v, self.size, self.frames)
                                 for v in videos[n:]]),
            "cameras": [v["channel"] for v in views],
            "meta": dict(e),
        }
