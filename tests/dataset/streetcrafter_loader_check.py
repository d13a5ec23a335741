#!/usr/bin/python3
"""Reads a `build-dataset --export streetcrafter` output as StreetCrafter's video trainer does
(zju3dv/street_crafter@8f365f6, video_diffusion/vwm/data/subsets/waymo.py and common.py;
docs/reference/trainer-formats.md §2), and its LiDAR depth as the 3DGS stage does
(street_gaussian/datasets/waymo_readers.py:126-134), and checks what it gets.

  meta_info_{train,val}.json: JSON lists of {frames, guidances, guidances_mask}, paths relative
    to the data root (waymo.py:17-22,49-56; common.py:25-26); a missing file raises
  __getitem__: frames[i], guidances[i] for i < 25 (waymo.py:97-112)
  each image: PIL open, convert("RGB"), crop to the target aspect (wider: centre columns;
    taller: the bottom rows), LANCZOS resize to the target, ToTensor()*2-1 (waymo.py:58-77)
  guidances_mask[i]: read as the PandaSet loader reads it (pandaset.py:110-115): 0 or 1
  depth npz: mask -> bool (H, W), value float32, depth[mask] = value

Usage: streetcrafter_loader_check.py DATA_ROOT EXPECTED_SAMPLES
Prints one line per sample; exit 0 when every check holds."""
import json
import os
import sys

import numpy as np
from PIL import Image

NUM_FRAMES = 25
TARGET_H, TARGET_W = 320, 576  # configs/condition/waymo_low_res.yaml


def load_image(path):
    """The loader's image path (waymo.py:58-77), returning the array it hands the model and
    whether its crop and resize were the identity."""
    img = Image.open(path).convert("RGB")
    w, h = img.size
    identity = (w, h) == (TARGET_W, TARGET_H)
    if w / h > TARGET_W / TARGET_H:  # wider: centre crop of the width
        new_w = int(h * TARGET_W / TARGET_H)
        left = (w - new_w) // 2
        img = img.crop((left, 0, left + new_w, h))
    elif w / h < TARGET_W / TARGET_H:  # taller: keep the bottom rows
        new_h = int(w * TARGET_H / TARGET_W)
        img = img.crop((0, h - new_h, w, h))
    img = img.resize((TARGET_W, TARGET_H), Image.LANCZOS)
    arr = np.asarray(img, dtype=np.float32) / 255.0 * 2.0 - 1.0
    return arr, identity


def check_depth(root, guidance_rel):
    """The npz beside a guidance: lidar/depth/<frame>_0.npz."""
    clip_dir = guidance_rel.split("/lidar/")[0]
    name = os.path.basename(guidance_rel).replace(".png", ".npz")
    path = os.path.join(root, clip_dir, "lidar", "depth", name)
    d = np.load(path)  # no allow_pickle, as the reader
    assert sorted(d.files) == ["mask", "value"], d.files
    mask = d["mask"].astype(bool)
    value = d["value"].astype(np.float32)
    assert d["mask"].dtype == bool and mask.shape == (TARGET_H, TARGET_W), (d["mask"].dtype, mask.shape)
    assert d["value"].dtype == np.float32 and value.ndim == 1, (d["value"].dtype, value.shape)
    assert len(value) == mask.sum(), (len(value), mask.sum())
    assert value.min() >= 0.1 and value.max() <= 100.0, (value.min(), value.max())
    depth = np.zeros(mask.shape, np.float32)
    depth[mask] = value
    return depth


def main():
    root, expected = sys.argv[1], int(sys.argv[2])
    samples = 0
    for split in ("train", "val"):
        path = os.path.join(root, f"meta_info_{split}.json")
        with open(path) as f:
            items = json.load(f)
        assert isinstance(items, list), path
        for item in items:
            for key in ("frames", "guidances", "guidances_mask"):
                assert len(item[key]) == NUM_FRAMES, (key, len(item[key]))
            frames, guidances = [], []
            for i in range(NUM_FRAMES):
                frame, same_f = load_image(os.path.join(root, item["frames"][i]))
                guidance, same_g = load_image(os.path.join(root, item["guidances"][i]))
                assert same_f and same_g, "crop/resize is not the identity"
                # The mask as the PandaSet loader takes it (pandaset.py:110-115): the image
                # path above, then channel 0 of ToTensor(), in [0, 1].
                mask, same_m = load_image(os.path.join(root, item["guidances_mask"][i]))
                assert same_m, "crop/resize of the mask is not the identity"
                mask = (mask[..., 0] + 1.0) / 2.0
                assert set(np.unique(mask)) <= {0.0, 1.0}, np.unique(mask)
                # Black (-1 in the model's range) wherever nothing was drawn.
                assert np.all(guidance[mask == 0] == -1.0)
                depth = check_depth(root, item["guidances"][i])
                # Every drawn pixel of the guidance has a depth, and only those.
                assert np.array_equal(depth > 0, mask > 0)
                frames.append(frame)
                guidances.append(guidance)
            frames = np.stack(frames)
            assert frames.shape == (NUM_FRAMES, TARGET_H, TARGET_W, 3)
            assert -1.0 <= frames.min() and frames.max() <= 1.0
            print(f"{split}: {item['frames'][0].split('/')[0]}: 25 frames and guidances "
                  f"{TARGET_W}x{TARGET_H}, guidance coverage {np.mean(np.stack(guidances) > -1):.3f}")
            samples += 1
    assert samples == expected, (samples, expected)
    print(f"ok: {samples} samples read as the trainer reads them")


if __name__ == "__main__":
    main()
