#!/usr/bin/python3
"""Reads a `--export gen3c` clip folder as GEN3C's dynamic-video inference does
(nv-tlabs/GEN3C@db2ffe1, cosmos_predict1/diffusion/inference/data_loader_utils.py:137-164;
docs/reference/trainer-formats.md §1), and checks what it gets.

  rgb.mp4: cv2.VideoCapture, every frame, BGR -> RGB, /127.5 - 1 (:142-153)
  depth.npz['depth'] cast to float32 (:156); mask.npz['mask'] cast to float32 (:157)
  camera.npz['w2c'], ['intrinsics'] handed to torch unconverted (:160-162): float32
  frame count: (T - 1) % 120 == 0 (gen3c_dynamic.py:109-111); size 704x1280
  depth: NaN -> 100, clamped to [0, 100] (cache_3d.py:107-108); > 0 is unprojected

Usage: gen3c_loader_check.py CLIP_DIR EXPECTED_FRAMES
Prints one line; exit 0 when every check holds."""
import sys

import cv2
import numpy as np

H, W = 704, 1280


def main():
    clip, expected = sys.argv[1], int(sys.argv[2])
    cap = cv2.VideoCapture(f"{clip}/rgb.mp4")
    frames = []
    while True:
        ok, frame = cap.read()
        if not ok:
            break
        frames.append(cv2.cvtColor(frame, cv2.COLOR_BGR2RGB))
    rgb = np.stack(frames).astype(np.float32) / 127.5 - 1.0
    t = len(frames)
    assert t == expected and (t - 1) % 120 == 0, t
    assert rgb.shape == (t, H, W, 3), rgb.shape
    d = np.load(f"{clip}/depth.npz")
    m = np.load(f"{clip}/mask.npz")
    c = np.load(f"{clip}/camera.npz")
    assert list(d.files) == ["depth"] and list(m.files) == ["mask"], (d.files, m.files)
    assert sorted(c.files) == ["intrinsics", "w2c"], c.files
    depth, mask = d["depth"], m["mask"]
    assert depth.dtype == np.float32 and depth.shape == (t, H, W), (depth.dtype, depth.shape)
    assert mask.dtype == bool and mask.shape == (t, H, W), (mask.dtype, mask.shape)
    assert np.all(np.isfinite(depth)) and depth.min() >= 0 and depth.max() <= 100
    assert np.array_equal(mask, depth > 0)
    clamped = np.clip(np.nan_to_num(depth, nan=100.0), 0, 100)
    assert np.array_equal(clamped, depth), "the loader's clamp changes the depth"
    w2c, k = c["w2c"], c["intrinsics"]
    assert w2c.dtype == np.float32 and w2c.shape == (t, 4, 4), (w2c.dtype, w2c.shape)
    assert k.dtype == np.float32 and k.shape == (t, 3, 3), (k.dtype, k.shape)
    assert np.allclose(w2c[:, 3], [0, 0, 0, 1])
    rot = w2c[:, :3, :3]
    assert np.allclose(rot @ rot.transpose(0, 2, 1), np.eye(3), atol=1e-5)
    assert np.all(k[:, 2] == [0, 0, 1]) and np.all(k[:, 0, 1] == 0)
    # The loader's lift (forward_warp_utils_pytorch.py:428-455) then the projection back
    # returns the pixels: depth * inv(K) [x, y, 1], inv(w2c), then K (w2c X).
    ys, xs = np.nonzero(mask[t // 2])
    pick = np.arange(0, len(xs), max(1, len(xs) // 500))
    z = depth[t // 2][ys[pick], xs[pick]]
    pix = np.stack([xs[pick], ys[pick], np.ones(len(pick))]).astype(np.float32)
    cam = (np.linalg.inv(k[t // 2]) @ pix) * z
    world = np.linalg.inv(w2c[t // 2]) @ np.vstack([cam, np.ones(len(pick), np.float32)])
    back = k[t // 2] @ (w2c[t // 2] @ world)[:3]
    assert np.allclose(back[:2] / back[2], pix[:2], atol=1e-2)
    assert np.allclose(back[2], z, rtol=1e-4)
    print(f"ok: {t} frames {W}x{H}, depth coverage {mask.mean():.3f}, "
          f"depth {depth[mask].min():.2f}-{depth[mask].max():.2f} m")


if __name__ == "__main__":
    main()
