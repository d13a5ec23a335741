#!/usr/bin/python3
"""Recomputes nuScenes quantities from a dataset's JSON tables the way the official devkit does
(json + numpy only; no devkit install needed), for tests/dataset/synthetic_dataset_test.cc.

Usage: devkit_check.py DATAROOT VERSION SCENE_NAME SAMPLE_INDEX CHANNEL

Prints one JSON object:
  camera: the CHANNEL keyframe sample_data of the SAMPLE_INDEX-th sample of SCENE_NAME:
          token, timestamp, global_from_cam (4x4, devkit: transform_matrix(ego_pose) @
          transform_matrix(calibrated_sensor)), K
  boxes:  for every annotation of that sample: instance_token, category_name, and the 8 corners
          (devkit Box.corners() order) projected into that camera as in
          export_2d_annotations_as_json.get_2d_boxes (global -> ego -> sensor, view_points), with
          the camera-frame depth of each corner.
"""
import json
import os
import sys

import numpy as np


def quat_to_matrix(q):
    # pyquaternion Quaternion(w, x, y, z).rotation_matrix (normalised first).
    w, x, y, z = np.asarray(q, dtype=np.float64) / np.linalg.norm(q)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


def transform_matrix(translation, rotation, inverse=False):
    # nuscenes.utils.geometry_utils.transform_matrix
    tm = np.eye(4)
    r = quat_to_matrix(rotation)
    t = np.asarray(translation, dtype=np.float64)
    if inverse:
        tm[:3, :3] = r.T
        tm[:3, 3] = -r.T.dot(t)
    else:
        tm[:3, :3] = r
        tm[:3, 3] = t
    return tm


def box_corners(center, size, rotation):
    # nuscenes.utils.data_classes.Box.corners(wlh_factor=1)
    w, l, h = size
    x_corners = l / 2 * np.array([1, 1, 1, 1, -1, -1, -1, -1])
    y_corners = w / 2 * np.array([1, -1, -1, 1, 1, -1, -1, 1])
    z_corners = h / 2 * np.array([1, 1, -1, -1, 1, 1, -1, -1])
    corners = np.vstack((x_corners, y_corners, z_corners))
    corners = quat_to_matrix(rotation).dot(corners)
    return corners + np.asarray(center, dtype=np.float64).reshape(3, 1)


def view_points(points, view):
    # nuscenes.utils.geometry_utils.view_points(points, view, normalize=True)
    viewpad = np.eye(4)
    viewpad[:view.shape[0], :view.shape[1]] = view
    pts = np.concatenate((points, np.ones((1, points.shape[1]))))
    pts = viewpad.dot(pts)[:3, :]
    return pts / pts[2:3, :].repeat(3, 0).reshape(3, points.shape[1])


def main():
    root, version, scene_name, sample_index, channel = sys.argv[1:6]
    sample_index = int(sample_index)

    def table(name):
        with open(os.path.join(root, version, name + ".json")) as f:
            return json.load(f)

    scene = next(s for s in table("scene") if s["name"] == scene_name)
    samples = {s["token"]: s for s in table("sample")}
    tok = scene["first_sample_token"]
    for _ in range(sample_index):
        tok = samples[tok]["next"]
    sample = samples[tok]
    sensors = {s["token"]: s for s in table("sensor")}
    calibs = {c["token"]: c for c in table("calibrated_sensor")}
    poses = {p["token"]: p for p in table("ego_pose")}
    cam_sd = None
    for sd in table("sample_data"):
        if sd["sample_token"] != sample["token"] or not sd["is_key_frame"]:
            continue
        cs = calibs[sd["calibrated_sensor_token"]]
        if sensors[cs["sensor_token"]]["channel"] == channel:
            cam_sd = sd
    assert cam_sd is not None, "no keyframe for " + channel
    cs = calibs[cam_sd["calibrated_sensor_token"]]
    ep = poses[cam_sd["ego_pose_token"]]
    global_from_cam = transform_matrix(ep["translation"], ep["rotation"]).dot(
        transform_matrix(cs["translation"], cs["rotation"]))
    K = np.array(cs["camera_intrinsic"], dtype=np.float64)

    instances = {i["token"]: i for i in table("instance")}
    categories = {c["token"]: c["name"] for c in table("category")}
    boxes = []
    for ann in table("sample_annotation"):
        if ann["sample_token"] != sample["token"]:
            continue
        corners = box_corners(ann["translation"], ann["size"], ann["rotation"])
        # get_2d_boxes: box.translate(-ego t); box.rotate(ego q inverse); same for the sensor.
        c = corners - np.asarray(ep["translation"]).reshape(3, 1)
        c = quat_to_matrix(ep["rotation"]).T.dot(c)
        c = c - np.asarray(cs["translation"]).reshape(3, 1)
        c = quat_to_matrix(cs["rotation"]).T.dot(c)
        uv = view_points(c, K)
        boxes.append({
            "instance_token": ann["instance_token"],
            "category_name": categories[instances[ann["instance_token"]]["category_token"]],
            "translation": ann["translation"],
            "corners_uv": uv[:2].T.tolist(),
            "corners_depth": c[2].tolist(),
        })
    print(json.dumps({
        "camera": {
            "token": cam_sd["token"],
            "timestamp": cam_sd["timestamp"],
            "filename": cam_sd["filename"],
            "global_from_cam": global_from_cam.tolist(),
            "K": K.tolist(),
        },
        "sample_timestamp": sample["timestamp"],
        "boxes": boxes,
    }))


if __name__ == "__main__":
    main()
