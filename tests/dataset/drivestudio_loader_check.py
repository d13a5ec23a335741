#!/usr/bin/python3
"""Reads a `--export drivestudio` scene folder as drivestudio's nuScenes loader does
(ziyc/drivestudio@e59bda4, datasets/nuscenes/nuscenes_sourceloader.py,
datasets/base/pixel_source.py, datasets/driving_dataset.py; docs/reference/trainer-formats.md §4),
and checks what it gets.

  frames: len(listdir(lidar_pose)) (driving_dataset.py:58-63); no ego_pose/ folder
  per frame t and camera c: images/%03d_%d.jpg, sky_masks/%03d_%d.png,
    dynamic_masks/{all,human,vehicle}/%03d_%d.png (pixel_source.py:198-228), opened and
    converted to "L", > 0
  extrinsics/%03d_%d.txt np.loadtxt (4,4), re-based on inv(extrinsics/000_0.txt)
    (nuscenes_sourceloader.py:76-111); intrinsics/%d.txt 9 values, K scaled by
    load_size / (900, 1600) (:82-99)
  lidar/%03d.bin np.fromfile float32 reshape(-1, 4), transformed by lidar_pose/%03d.txt
    (:359-406)
  instances/instances_info.json: ids "0".."N-1", class_name one of the 18 keys of
    OBJECT_CLASS_NODE_MAPPING; frame_instances.json: a key per frame (:198-252)

Usage: drivestudio_loader_check.py SCENE_DIR CAMERAS EXPECTED_FRAMES
Prints one line; exit 0 when every check holds."""
import json
import os
import sys

import cv2
import numpy as np

CLASSES = {
    "vehicle.bus.bendy", "vehicle.bus.rigid", "vehicle.car", "vehicle.construction",
    "vehicle.emergency.ambulance", "vehicle.emergency.police", "vehicle.motorcycle",
    "vehicle.trailer", "vehicle.truck", "human.pedestrian.adult", "human.pedestrian.child",
    "human.pedestrian.construction_worker", "human.pedestrian.police_officer",
    "human.pedestrian.personal_mobility", "human.pedestrian.stroller",
    "human.pedestrian.wheelchair", "animal", "vehicle.bicycle"}
H, W = 900, 1600  # original_size of every nuScenes camera (dataset_meta.py:98-128)


def gray(path):
    img = cv2.imread(path, cv2.IMREAD_UNCHANGED)
    assert img is not None, path
    assert img.ndim == 2 and img.dtype == np.uint8, (path, img.shape, img.dtype)
    assert set(np.unique(img)) <= {0, 255}, (path, np.unique(img))
    return img > 0


def main():
    d, cams, expected = sys.argv[1], [int(c) for c in sys.argv[2].split(",")], int(sys.argv[3])
    assert not os.path.exists(f"{d}/ego_pose")
    t_count = len(os.listdir(f"{d}/lidar_pose"))
    assert t_count == expected, t_count
    front_start = np.loadtxt(f"{d}/extrinsics/000_0.txt")
    assert front_start.shape == (4, 4)
    sky = dyn = 0
    in_view = 0
    for c in cams:
        k = np.loadtxt(f"{d}/intrinsics/{c}.txt")
        assert k.shape == (9,) and np.all(k[4:] == 0), k
        fx, fy, cx, cy = k[:4]
        assert fx > 0 and fy > 0 and 0 < cx < W and 0 < cy < H
        for t in range(t_count):
            img = cv2.imread(f"{d}/images/{t:03d}_{c}.jpg")
            assert img is not None and img.shape == (H, W, 3), (t, None if img is None else img.shape)
            masks = {kind: gray(f"{d}/dynamic_masks/{kind}/{t:03d}_{c}.png")
                     for kind in ("all", "human", "vehicle")}
            assert np.array_equal(masks["all"], masks["human"] | masks["vehicle"])
            s = gray(f"{d}/sky_masks/{t:03d}_{c}.png")
            assert s.shape == (H, W)
            sky += s.mean()
            dyn += masks["all"].mean()
            c2w = np.linalg.inv(front_start) @ np.loadtxt(f"{d}/extrinsics/{t:03d}_{c}.txt")
            assert c2w.shape == (4, 4) and np.allclose(c2w[3], [0, 0, 0, 1])
            assert np.isclose(np.linalg.det(c2w[:3, :3]), 1, atol=1e-6)
            pts = np.fromfile(f"{d}/lidar/{t:03d}.bin", dtype=np.float32).reshape(-1, 4)
            assert len(pts) > 1000, len(pts)
            l2w = np.linalg.inv(front_start) @ np.loadtxt(f"{d}/lidar_pose/{t:03d}.txt")
            assert l2w.shape == (4, 4) and np.isclose(np.linalg.det(l2w[:3, :3]), 1, atol=1e-6)
            world = (l2w[:3, :3] @ pts[:, :3].T + l2w[:3, 3:4]).T
            cam = np.linalg.inv(c2w) @ np.vstack([world.T, np.ones(len(world))])
            front = cam[2] > 1
            u = fx * cam[0, front] / cam[2, front] + cx
            v = fy * cam[1, front] / cam[2, front] + cy
            inside = (u >= 0) & (u < W) & (v >= 0) & (v < H)
            in_view += int(inside.sum())
            # A LiDAR return in view is never under the sky mask.
            ui, vi = u[inside].astype(int), v[inside].astype(int)
            assert s[vi, ui].mean() < 0.01, s[vi, ui].mean()
    assert np.allclose(np.loadtxt(f"{d}/extrinsics/000_0.txt"), np.eye(4), atol=1e-9)
    info = json.load(open(f"{d}/instances/instances_info.json"))
    frames = json.load(open(f"{d}/instances/frame_instances.json"))
    assert sorted(info, key=int) == [str(i) for i in range(len(info))], list(info)[:5]
    assert sorted(frames, key=int) == [str(i) for i in range(t_count)]
    boxes = 0
    for k, v in info.items():
        assert v["class_name"] in CLASSES, v["class_name"]
        fa = v["frame_annotations"]
        assert len(fa["frame_idx"]) == len(fa["obj_to_world"]) == len(fa["box_size"])
        for f, o2w, size in zip(fa["frame_idx"], fa["obj_to_world"], fa["box_size"]):
            assert 0 <= f < t_count and int(k) in frames[str(f)]
            o2w = np.array(o2w).reshape(4, 4)
            assert np.isclose(np.linalg.det(o2w[:3, :3]), 1, atol=1e-6)
            assert len(size) == 3 and min(size) > 0
            boxes += 1
    for f, ids in frames.items():
        assert all(0 <= i < len(info) for i in ids), ids
    assert boxes == sum(len(ids) for ids in frames.values())
    n = t_count * len(cams)
    print(f"ok: {t_count} frames x {len(cams)} camera(s) at {W}x{H}, {len(info)} instances, "
          f"{boxes} boxes, sky {sky / n:.3f} and dynamic {dyn / n:.3f} of the pixels, "
          f"{in_view / n:.0f} LiDAR returns in view a frame")


if __name__ == "__main__":
    main()
