#!/usr/bin/python3
"""Reads a `build-dataset --export geodrive-upstream` output exactly as GeoDrive's released trainer
does (wangyida/GeoDrive train/train.py, MyWebDataset; docs/reference/geodrive_upstream.md §3), line
by line, and checks what it gets.

  meta.jsonl lines {gt_frames: paths relative to --video_data_root (the nuScenes root),
                    render_frames: paths relative to --condition_data_root, scene_idx}
  frames: cv2.imread (BGR) -> RGB, float, /255*2-1 ([-1, 1])
  25 frames: the 4k+1 trim keeps 25, then pad to 49 by repeating the last frame
  resize: plain, aspect-distorting resize to 480x720 (video_reshape_mode="resize")

Usage: upstream_loader_check.py CONDITION_ROOT VIDEO_ROOT EXPECTED_SAMPLES
Prints one line per sample; exit 0 when every check holds."""
import json
import os
import sys

import cv2
import numpy as np


def load_frames(root, rel_paths):
    frames = []
    for rel in rel_paths:
        path = os.path.join(root, rel)
        img = cv2.imread(path)  # BGR uint8, as the trainer
        assert img is not None, f"cv2 cannot read {path}"
        frames.append(cv2.cvtColor(img, cv2.COLOR_BGR2RGB))
    return np.stack(frames)


def to_model_input(frames, height=480, width=720, target=49):
    n = len(frames)
    keep = (n - 1) // 4 * 4 + 1  # 4k+1 trim
    frames = frames[:keep]
    if keep < target:  # pad by repeating the last frame
        frames = np.concatenate([frames, np.repeat(frames[-1:], target - keep, axis=0)])
    resized = np.stack([cv2.resize(f, (width, height), interpolation=cv2.INTER_LINEAR)
                        for f in frames])
    return resized.astype(np.float32) / 255.0 * 2.0 - 1.0


def psnr(a, b):
    mse = np.mean((a.astype(np.float64) - b.astype(np.float64)) ** 2)
    return 100.0 if mse == 0 else 10 * np.log10(255.0 ** 2 / mse)


def main():
    cond_root, video_root, expected = sys.argv[1], sys.argv[2], int(sys.argv[3])
    entries = [json.loads(l) for l in open(os.path.join(cond_root, "meta.jsonl")) if l.strip()]
    assert len(entries) == expected, f"{len(entries)} samples, expected {expected}"
    idx = [e["scene_idx"] for e in entries]
    assert idx == sorted(idx) and len(set(idx)) == len(idx), f"scene_idx not sorted/unique: {idx}"
    for e in entries:
        assert isinstance(e["scene_idx"], int)
        assert len(e["gt_frames"]) == 25 and len(e["render_frames"]) == 25
        sample = "sample_%06d" % e["scene_idx"]
        assert all(r == f"{sample}/render_{i}.png" for i, r in enumerate(e["render_frames"]))
        gt = load_frames(video_root, e["gt_frames"])
        cond = load_frames(cond_root, e["render_frames"])
        assert cond.shape == (25, 576, 1024, 3), cond.shape  # upstream: 288x512 x2
        # Frame-0 policy: the condition's frame 0 is the real image.
        p0 = psnr(cv2.resize(gt[0], (1024, 576), interpolation=cv2.INTER_AREA), cond[0])
        assert p0 > 40, f"{sample}: condition frame 0 is not the real image (PSNR {p0:.1f})"
        covered = float(np.mean(cond[1:].max(axis=3) > 0))
        assert covered > 0.2, f"{sample}: renders are empty ({covered:.3f} covered)"
        x_gt, x_cond = to_model_input(gt), to_model_input(cond)
        assert x_gt.shape == (49, 480, 720, 3) and x_cond.shape == (49, 480, 720, 3)
        assert x_gt.min() >= -1 and x_gt.max() <= 1 and x_cond.min() >= -1
        assert np.array_equal(x_cond[24], x_cond[48]), "padding must repeat the last frame"
        print(f"{sample} (scene_idx {e['scene_idx']}): gt {gt.shape} cond {cond.shape} -> "
              f"model input {x_cond.shape}, frame-0 PSNR vs real {p0:.1f} dB, "
              f"covered {covered:.3f}")
    print(f"read {len(entries)} sample(s) as train.py does")


if __name__ == "__main__":
    main()
