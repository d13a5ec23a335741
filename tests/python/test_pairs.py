"""Pairs built by the toolkit, read through geodrive and geodrive.torch."""
import os
import subprocess
import sys

import numpy as np
import pytest

import geodrive
from conftest import require


def test_read_video_matches_opencv(pairs):
    cv2 = require("cv2")
    entry = geodrive.read_manifest(pairs)[0]
    path = os.path.join(os.path.dirname(pairs), entry["pair_dir"], "gt.mp4")
    ours = geodrive.read_video(path)
    cap = cv2.VideoCapture(path)
    theirs = []
    while True:
        ok, f = cap.read()
        if not ok:
            break
        theirs.append(cv2.cvtColor(f, cv2.COLOR_BGR2RGB))
    assert ours.shape == (len(theirs),) + theirs[0].shape
    # Both decode the same H.264 stream with FFmpeg; colour conversion may
    # round differently by one level.
    assert geodrive.psnr(ours[0], theirs[0]) > 40


def test_pair_dataset_layout_and_padding(pairs):
    torch = require("torch")
    from geodrive.torch import PairDataset
    ds = PairDataset(pairs)
    item = ds[0]
    assert item["gt"].shape == item["cond"].shape
    T, C, H, W = item["gt"].shape
    assert (T, C) == (25, 3) and item["gt"].dtype == torch.float32
    assert -1.0 <= float(item["gt"].min()) and float(item["gt"].max()) <= 1.0
    assert item["meta"]["clip_id"] == geodrive.read_manifest(pairs)[0]["clip_id"]
    padded = PairDataset(pairs, frames=49, size=(240, 360))[0]
    assert padded["cond"].shape == (49, 3, 240, 360)
    assert torch.equal(padded["cond"][25], padded["cond"][24])
    assert torch.equal(padded["cond"][48], padded["cond"][24])


def test_dataloader_with_workers(pairs):
    torch = require("torch")
    from geodrive.torch import PairDataset
    loader = torch.utils.data.DataLoader(PairDataset(pairs), batch_size=1,
                                         num_workers=2)
    batch = next(iter(loader))
    assert batch["gt"].shape[:2] == (1, 25)
    ref = PairDataset(pairs)[0]["gt"]
    assert torch.equal(batch["gt"][0], ref)


def test_example_script_prints_one_batch(pairs):
    example = os.path.join(os.path.dirname(__file__), "..", "..", "examples",
                           "pair_dataloader.py")
    out = subprocess.run([sys.executable, example, pairs], check=True,
                         capture_output=True, text=True).stdout
    assert "gt torch.Size([2, 49, 3, 480, 720])" in out or "gt torch.Size([1, 49, 3, 480, 720])" in out
