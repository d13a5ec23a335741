#!/usr/bin/python3
"""Reads a `--export rds-hq` root as Cosmos-Drive-Dreams' condition renderer does
(nv-tlabs/Cosmos-Drive-Dreams@f745347, cosmos-drive-dreams-toolkits/render_from_rds_hq.py;
docs/reference/trainer-formats.md §3), and checks what it gets.

  tars: one webdataset sample each (utils/wds_utils.py:15-21); members grouped as
    webdataset.tariterators does: key = the basename up to its first dot, the rest the
    lower-cased extension (base_plus_ext, group_by_keys(lcase=True)); decoded by extension
    (.npy/.npz with numpy.load, no pickles; .json with json.loads)
  clips: the stems of ROOT/pose/*.tar (:501-505), or a -cj JSON list (:506-509)
  poses: the keys containing 'pose.<cam>.npy', stacked in sorted order (:84-89), indexed by
    frame (:357); render frames range(0, N, 30 // 30) in chunks of 121 (:91-92, 206-208)
  intrinsics: pinhole_intrinsic.<cam>.npy -> [fx, fy, cx, cy, w, h], rescaled to 1280x720
    (:110-118, utils/camera/pinhole.py:58-71)
  LiDAR: per render frame, frames +-2 * 3 rounded to multiples of 3, clamped to the largest
    key; each '%06d.lidar_raw.npz' ['xyz'] (N,3) and ['lidar_to_world'], returns under 3 m
    dropped (:314-342); the object JSON of each of those keys and of the frame (:344-345)
  objects: object_to_world 4x4, object_lwh, object_is_moving, object_type (utils/bbox_utils.py)
  HD map: 3d_<type>/<clip>.tar, one '<type>.json' member (utils/minimap_utils.py:100-104)

Usage: rds_hq_loader_check.py ROOT CLIP EXPECTED_FRAMES [CONFIG]
CONFIG: rds_hq (default: config/dataset_rds_hq.json's one camera) or rds_hq_mv (its six cameras,
config/dataset_rds_hq_mv.json:2): the renderer's loop over settings['CAMERAS'] (:79-118), each
camera's poses and intrinsics checked, the LiDAR projected into each.
Prints one line; exit 0 when every check holds."""
import io
import json
import os
import re
import sys
import tarfile

import numpy as np

CAM = "camera_front_wide_120fov"
CAMERAS = {"rds_hq": [CAM],
           "rds_hq_mv": [CAM, "camera_cross_left_120fov", "camera_cross_right_120fov",
                         "camera_rear_left_70fov", "camera_rear_right_70fov",
                         "camera_rear_tele_30fov"]}
MINIMAP_TYPES = ["lanelines", "road_boundaries", "crosswalks", "road_markings",
                 "wait_lines", "poles", "traffic_signs", "traffic_lights"]
TYPES = {"Car", "Truck", "Pedestrian", "Cyclist"}
CHUNK = 121
BASE_PLUS_EXT = re.compile(r"^((?:.*/|)[^.]+)[.]([^/]*)$")  # webdataset.tariterators


def decode(ext, data):
    if ext.endswith(".npy"):
        return np.load(io.BytesIO(data))  # allow_pickle=False by default
    if ext.endswith(".npz"):
        return dict(np.load(io.BytesIO(data)))
    if ext.endswith(".json"):
        return json.loads(data)
    return data


def get_sample(path, clip):
    """The first (only) sample of a tar, as WebDataset(url).decode() gives it."""
    with tarfile.open(path) as tar:
        members = [m for m in tar.getmembers() if m.isfile()]
        assert members, path
        sample = {}
        for m in members:
            assert re.fullmatch(re.escape(clip) + r"\.[^/]+", m.name), (path, m.name)
            prefix, ext = BASE_PLUS_EXT.match(m.name).groups()
            assert prefix == clip, (path, m.name, prefix)  # one sample per tar
            ext = ext.lower()
            assert ext not in sample, (path, ext)
            sample[ext] = decode(ext, tar.extractfile(m).read())
    sample["__key__"] = clip
    return sample


def main():
    root, clip, expected = sys.argv[1], sys.argv[2], int(sys.argv[3])
    config = sys.argv[4] if len(sys.argv) > 4 else "rds_hq"
    assert "." not in clip
    stems = [f[:-4] for f in os.listdir(f"{root}/pose") if f.endswith(".tar")]
    assert clip in stems, stems
    for split in ("train", "val"):
        lst = json.load(open(f"{root}/clips_{split}.json"))
        assert isinstance(lst, list) and all(isinstance(c, str) for c in lst), lst
    listed = json.load(open(f"{root}/clips_train.json")) + json.load(open(f"{root}/clips_val.json"))
    assert sorted(listed) == sorted(stems), (listed, stems)

    pose_data = get_sample(f"{root}/pose/{clip}.tar", clip)
    intr = get_sample(f"{root}/pinhole_intrinsic/{clip}.tar", clip)
    cameras = CAMERAS[config]
    # Every member is some camera's pose or intrinsics: none the renderer would skip.
    names = "|".join(cameras)
    for key in pose_data:
        assert key == "__key__" or re.fullmatch(r"\d{6}\.pose\.(" + names + r")\.npy", key), key
    assert sorted(k for k in intr if k != "__key__") == sorted(
        f"pinhole_intrinsic.{c}.npy" for c in cameras), sorted(intr)
    poses_of, k_of = {}, {}
    for cam_name in cameras:
        pose_keys = sorted(k for k in pose_data if f"pose.{cam_name}.npy" in k)
        assert [int(k.split(".")[0]) for k in pose_keys] == list(range(len(pose_keys))), pose_keys[:3]
        poses = np.stack([pose_data[k] for k in pose_keys])
        n = len(poses)
        assert n == expected and n >= CHUNK, (cam_name, n)
        assert poses.dtype == np.float64 and poses.shape == (n, 4, 4), (poses.dtype, poses.shape)
        assert np.allclose(poses[:, 3], [0, 0, 0, 1])
        rot = poses[:, :3, :3]
        assert np.allclose(rot @ rot.transpose(0, 2, 1), np.eye(3), atol=1e-9)
        assert np.allclose(np.linalg.det(rot), 1, atol=1e-9)
        k = intr[f"pinhole_intrinsic.{cam_name}.npy"]
        assert k.shape == (6,) and k.dtype == np.float64, (k.shape, k.dtype)
        fx, fy, cx, cy, w, h = k
        assert (int(w), int(h)) == (w, h) == (1280, 720), (w, h)
        assert fx > 0 and fy > 0 and 0 < cx < w and 0 < cy < h
        poses_of[cam_name], k_of[cam_name] = poses, k
    poses, n = poses_of[CAM], len(poses_of[CAM])
    fx, fy, cx, cy, w, h = k_of[CAM]
    render_frame_ids = list(range(0, n, 30 // 30))
    chunks = len(render_frame_ids) // CHUNK
    assert chunks >= 1

    lidar = get_sample(f"{root}/lidar_raw/{clip}.tar", clip)
    lidar_ids = [int(key.split(".")[0]) for key in lidar
                 if key.endswith(".lidar_raw.npz") and key.split(".")[0].isdigit()]
    valid = [x for x in lidar_ids if x <= render_frame_ids[-1]]
    max_lidar = max(valid)
    assert max_lidar == (n - 1) // 3 * 3, (max_lidar, n)
    assert set(range(0, max_lidar + 1, 3)) <= set(lidar_ids)
    objects = get_sample(f"{root}/all_object_info/{clip}.tar", clip)
    points_in_view = 0
    for frame_idx in render_frame_ids:  # the renderer's accumulation, keys only
        acc = [min(max(0, frame_idx + i * 3), len(render_frame_ids) - 1) for i in range(-2, 3)]
        low = [min(max_lidar, int(round(a / 3)) * 3) for a in acc]
        for lo in low:
            assert f"{lo:06d}.lidar_raw.npz" in lidar, lo
            assert f"{lo:06d}.all_object_info.json" in objects, lo
        assert f"{frame_idx:06d}.all_object_info.json" in objects, frame_idx
    for key, npz in lidar.items():
        if key == "__key__":
            continue
        assert sorted(npz) == ["lidar_to_world", "xyz"], sorted(npz)
        xyz = npz["xyz"].astype(np.float32).reshape(-1, 3)
        assert npz["xyz"].dtype == np.float32 and npz["xyz"].ndim == 2, npz["xyz"].shape
        l2w = npz["lidar_to_world"]
        assert l2w.dtype == np.float64 and l2w.shape == (4, 4)
        assert np.allclose(l2w[3], [0, 0, 0, 1])
        near = np.linalg.norm(xyz, axis=1) < 3.0
        assert near.mean() < 0.5, near.mean()  # a sensor-centred frame
    mid = render_frame_ids[len(render_frame_ids) // 2] // 3 * 3
    npz = lidar[f"{mid:06d}.lidar_raw.npz"]
    pts = npz["xyz"].astype(np.float32).reshape(-1, 3)
    pts = pts[np.linalg.norm(pts, axis=1) >= 3.0]
    world = (npz["lidar_to_world"] @ np.concatenate([pts, np.ones([len(pts), 1])], axis=1).T).T[:, :3]
    in_view = {}
    for cam_name in cameras:
        fx, fy, cx, cy, w, h = k_of[cam_name]
        cam = (np.linalg.inv(poses_of[cam_name][mid])
               @ np.concatenate([world, np.ones([len(world), 1])], axis=1).T)[:3]
        front = cam[2] > 0.5
        u = fx * cam[0, front] / cam[2, front] + cx
        v = fy * cam[1, front] / cam[2, front] + cy
        in_view[cam_name] = int(((u >= 0) & (u < w) & (v >= 0) & (v < h)).sum())
    points_in_view = in_view[CAM]
    assert points_in_view > 1000, in_view
    assert min(in_view.values()) > 100, in_view

    boxes = moving = 0
    for key, frame in objects.items():
        if key == "__key__":
            continue
        assert re.fullmatch(r"\d{6}\.all_object_info\.json", key), key
        for track, o in frame.items():
            assert sorted(o) == ["object_is_moving", "object_lwh", "object_to_world", "object_type"], o
            m = np.array(o["object_to_world"])
            assert m.shape == (4, 4) and np.allclose(m[3], [0, 0, 0, 1])
            assert np.allclose(np.linalg.det(m[:3, :3]), 1, atol=1e-6)
            lwh = np.array(o["object_lwh"])
            assert lwh.shape == (3,) and np.all(lwh > 0), lwh
            assert isinstance(o["object_is_moving"], bool)
            assert o["object_type"] in TYPES, o["object_type"]
            boxes += 1
            moving += o["object_is_moving"]
    assert len(objects) - 1 == n, len(objects)

    for t in MINIMAP_TYPES:
        sample = get_sample(f"{root}/3d_{t}/{clip}.tar", clip)
        names = [k for k in sample if k.endswith(".json")]
        assert names == [f"{t}.json"], names
        assert sample[names[0]] == {"labels": []}
    print(f"ok: {config}: {len(cameras)} camera(s) x {n} poses ({chunks} chunk of {CHUNK}), "
          f"{len(lidar_ids)} LiDAR keys to {max_lidar}, returns in view at frame {mid}: "
          f"{', '.join(f'{c} {m}' for c, m in in_view.items())}; {boxes} boxes "
          f"({moving} moving), {len(MINIMAP_TYPES)} empty HD-map tars")


if __name__ == "__main__":
    main()
