"""geodrive on the real nuScenes extract: poses, intrinsics and LiDAR sweeps
against the raw tables and files (read here with json and NumPy)."""
import json
import os
import subprocess
import sys

import numpy as np

import geodrive
from conftest import GEODRIVE, REAL


def quat_to_matrix(q):
    w, x, y, z = q
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def pose(rec):
    m = np.eye(4)
    m[:3, :3] = quat_to_matrix(rec["rotation"])
    m[:3, 3] = rec["translation"]
    return m


def test_clip_poses_and_intrinsics_match_the_tables(real_scene):
    ds = geodrive.open_dataset(real_scene, "v1.0-mini-extract", frames="keyframes")
    assert ds.scenes() == ["scene-0916"]
    assert ds.has_lidar
    clip = ds.load_clip(ds.clip_ids[0])
    assert clip.num_frames == 25 and clip.image_size == (1600, 900)
    tables = os.path.join(real_scene, "v1.0-mini-extract")
    load = lambda t: {r["token"]: r for r in json.load(open(os.path.join(tables, t + ".json")))}
    sd = {r["filename"]: r for r in load("sample_data").values()}
    ego, calib = load("ego_pose"), load("calibrated_sensor")
    for t in (0, 12, 24):
        rel = os.path.relpath(clip.image_paths[t], real_scene)
        rec = sd[rel]
        expect = pose(ego[rec["ego_pose_token"]]) @ pose(calib[rec["calibrated_sensor_token"]])
        np.testing.assert_allclose(clip.world_from_cam[t], expect, atol=1e-9)
        np.testing.assert_allclose(
            clip.intrinsics[t], calib[rec["calibrated_sensor_token"]]["camera_intrinsic"],
            atol=1e-12)
        assert clip.timestamps_us[t] == rec["timestamp"]
    boxes = clip.boxes(0)
    assert boxes and {"instance_id", "category", "center", "size_wlh"} <= set(boxes[0])


def test_lidar_sweeps_are_the_files(real_scene):
    ds = geodrive.open_dataset(real_scene, "v1.0-mini-extract", frames="keyframes")
    clip = ds.load_clip(ds.clip_ids[0])
    sweeps = clip.lidar_sweeps()
    assert len(sweeps) == 41
    pts = clip.load_sweep(0)
    raw = np.fromfile(os.path.join(real_scene, sweeps[0]["path"]), np.float32).reshape(-1, 5)
    assert pts.shape == raw.shape and pts.dtype == np.float32
    np.testing.assert_array_equal(pts, raw)


def test_lidar_dense_scene_renders_what_the_builder_renders(real_scene, tmp_path):
    """condition_scene + render against `geodrive build-dataset` on the same
    clip (no dynamic editing, paper preset with the builder's default 1 px
    splat radius, 480x720): the same coverage in every frame."""
    clip_id = "scene-0916_0006_kf"
    ds = geodrive.open_dataset(real_scene, "v1.0-mini-extract", frames="keyframes")
    clip = ds.load_clip(clip_id)
    scene = geodrive.condition_scene("lidar-dense", clip=clip)
    assert scene.units == "metres" and scene.points.shape[1] == 3
    K = scene.K_at(720, 480)
    r = geodrive.render(scene.points, scene.colors, K, np.linalg.inv(scene.poses),
                        radius=1.0)
    subprocess.run([GEODRIVE, "build-dataset", "--dataroot", real_scene,
                    "--version", "v1.0-mini-extract", "--frames", "keyframes",
                    "--geometry", "lidar-dense", "--edit-mode", "none",
                    "--clips", clip_id, "--out", str(tmp_path / "out")],
                   check=True, capture_output=True)
    meta = geodrive.read_meta(str(tmp_path / "out" / "pairs" / clip_id))
    ours = r["valid"].reshape(len(r["valid"]), -1).mean(1)
    np.testing.assert_allclose(ours, meta["quality"]["coverage"], atol=1e-12)


def test_render_with_edits_is_what_the_builder_renders(real_scene, tmp_path):
    """render_with_edits (3D dynamic editing along the pair's boxes.json)
    against `geodrive build-dataset` with its default --edit-mode 3d: the same
    coverage in every frame; removing an instance drops its pixels."""
    clip_id = "scene-0916_0006_kf"
    subprocess.run([GEODRIVE, "build-dataset", "--dataroot", real_scene,
                    "--version", "v1.0-mini-extract", "--frames", "keyframes",
                    "--geometry", "lidar-dense", "--clips", clip_id,
                    "--out", str(tmp_path / "out")],
                   check=True, capture_output=True)
    pair = tmp_path / "out" / "pairs" / clip_id
    ds = geodrive.open_dataset(real_scene, "v1.0-mini-extract", frames="keyframes")
    scene = geodrive.condition_scene("lidar-dense", clip=ds.load_clip(clip_id))
    K = scene.K_at(720, 480)
    poses = np.linalg.inv(scene.poses)
    r = geodrive.render_with_edits(scene.points, scene.colors, K, poses,
                                   str(pair / "boxes.json"), radius=1.0)
    meta = geodrive.read_meta(str(pair))
    ours = r["valid"].reshape(len(r["valid"]), -1).mean(1)
    np.testing.assert_allclose(ours, meta["quality"]["coverage"], atol=1e-12)
    ids, counts = np.unique(r["instance"][0], return_counts=True)
    drawn = [(c, i) for i, c in zip(ids, counts) if i >= 0]
    assert drawn, "some object is drawn in frame 0"
    target = r["render_ids"][max(drawn)[1]]
    removed = geodrive.render_with_edits(scene.points, scene.colors, K, poses,
                                         str(pair / "boxes.json"), radius=1.0,
                                         remove=[target])
    kept = [removed["render_ids"][i] for i in np.unique(removed["instance"][0]) if i >= 0]
    assert target not in kept


def test_the_readme_example_runs(real_scene, tmp_path):
    """The README's Python example, as written, on the real scene."""
    readme = open("README.md").read()
    code = readme.split("```python\n", 1)[1].split("```", 1)[0]
    code = code.replace('"../shared/data/real', '"' + os.path.abspath(REAL))
    code = code.replace("/tmp/cond_left3m.png", str(tmp_path / "cond.png"))
    out = subprocess.run([sys.executable, "-c", code], check=True,
                         capture_output=True, text=True).stdout
    assert out.startswith("(25, 480, 720, 3) ")
    assert 0.4 < float(out.split()[-1]) < 0.7     # frame 0 seen from 3 m left
    assert os.path.getsize(tmp_path / "cond.png") > 10000


def test_read_trajectory_reads_the_real_kitti_poses():
    path = os.path.join(REAL, "kitti_odometry_00", "00.txt")
    poses, times = geodrive.read_trajectory(path)
    raw = np.loadtxt(path).reshape(-1, 3, 4)
    assert poses.shape == (4541, 4, 4) and times.shape == (4541,)
    np.testing.assert_allclose(poses[:, :3, 3], raw[:, :, 3], atol=1e-12)
    np.testing.assert_allclose(poses[:, :3, :3], raw[:, :, :3], atol=1e-6)
    np.testing.assert_allclose(times, np.loadtxt(os.path.join(REAL, "kitti_odometry_00", "times.txt")))


def test_a_numpy_written_reconstruction_is_a_scene(tmp_path):
    """The generic npz written by NumPy: recognised, read as a scene source,
    its points the unprojection of its depth (checked with NumPy)."""
    N, H, W = 3, 6, 8
    depth = np.fromfunction(lambda n, y, x: 5 + n + 0.1 * x, (N, H, W)).astype(np.float32)
    K = np.array([[7.0, 0, 3.5], [0, 7.0, 2.5], [0, 0, 1]])
    c2w = np.repeat(np.eye(4)[None], N, 0)
    c2w[:, 2, 3] = np.arange(N) * 0.5
    path = tmp_path / "scene.npz"
    np.savez(path, depth=depth, intrinsics=K, cam_c2w=c2w, units="metres",
             images=np.full((N, H, W, 3), 200, np.uint8))
    assert geodrive.reconstruction_format(str(path)) == "npz"
    assert geodrive.reconstruction_format(str(tmp_path)) == "npz"
    assert geodrive.reconstruction_format(REAL) is None
    scene = geodrive.condition_scene("npz", path=str(path), filter="released")
    assert scene.units == "metres" and scene.image_size == (W, H)
    v, u = np.mgrid[0:H, 0:W]
    z = depth[0]
    expect = np.stack([(u - 3.5) / 7 * z, (v - 2.5) / 7 * z, z], -1).reshape(-1, 3)
    np.testing.assert_allclose(scene.points, expect, rtol=1e-6)
    np.testing.assert_allclose(scene.poses[:, 2, 3], [0, 0.5, 1.0])
    assert (scene.colors == 200).all()
    assert "npz" in geodrive.scene_sources()


def test_footprint_render_is_the_builders_footprint_preset(real_scene, tmp_path):
    """render(..., footprints=scene.footprints) against `build-dataset
    --preset footprint --edit-mode none` on the same clip: the same coverage
    in every frame (the approached scene stays closed)."""
    clip_id = "scene-0916_0006_kf"
    subprocess.run([GEODRIVE, "build-dataset", "--dataroot", real_scene,
                    "--version", "v1.0-mini-extract", "--frames", "keyframes",
                    "--geometry", "lidar-dense", "--preset", "footprint",
                    "--edit-mode", "none", "--clips", clip_id,
                    "--out", str(tmp_path / "out")],
                   check=True, capture_output=True)
    ds = geodrive.open_dataset(real_scene, "v1.0-mini-extract", frames="keyframes")
    scene = geodrive.condition_scene("lidar-dense", clip=ds.load_clip(clip_id))
    assert scene.footprints is not None and scene.footprints.shape == (len(scene.points),)
    assert scene.footprint_axes.shape == (len(scene.points), 6)
    r = geodrive.render(scene.points, scene.colors, scene.K_at(720, 480),
                        np.linalg.inv(scene.poses), footprints=scene.footprints,
                        footprint_axes=scene.footprint_axes)
    meta = geodrive.read_meta(str(tmp_path / "out" / "pairs" / clip_id))
    ours = r["valid"].reshape(len(r["valid"]), -1).mean(1)
    np.testing.assert_allclose(ours, meta["quality"]["coverage"], atol=1e-12)
    assert ours[5] > 0.7      # one-pixel points: 0.496 at this frame


def test_waymo_segments_open_like_nuscenes(tmp_path):
    """A synthetic Waymo segment (geodrive synth --format waymo) opens through
    the same call: clips of the FRONT camera, its poses and intrinsics, the
    laser_labels as boxes and the TOP range image as one sweep per frame."""
    seg = tmp_path / "waymo"
    subprocess.run([GEODRIVE, "synth", "--format", "waymo", "--out", str(seg),
                    "--scenes", "1", "--duration", "2.6", "--size", "64x96",
                    "--lidar-columns", "720"], check=True, capture_output=True)
    ds = geodrive.open_dataset(str(seg))
    assert ds.describe().startswith("waymo")
    assert ds.has_lidar
    assert len(ds.clip_ids) == 1
    clip = ds.load_clip(ds.clip_ids[0])
    assert clip.num_frames == 25 and clip.image_size == (96, 64)
    # Frames 0.1 s apart (10 Hz), each camera at its own capture time.
    dt = np.diff(np.array(clip.timestamps_us))
    assert np.all(dt == 100000)
    # The FRONT camera looks along the vehicle's +x: its optical axis (the
    # third column of world_from_cam) is the ego's forward direction.
    w = np.array(clip.world_from_cam[0])
    assert abs(np.linalg.det(w[:3, :3]) - 1) < 1e-9
    assert w[2, 2] < 0.1  # horizontal, not looking up or down
    assert clip.boxes(0) and clip.boxes(0)[0]["category"] == "vehicle.car"
    assert clip.load_sweep(0).shape[0] > 1000
    assert geodrive.open_dataset(str(seg), dataset="waymo").clip_ids == ds.clip_ids
    try:
        geodrive.open_dataset(str(seg), dataset="nuscenes")
        raise AssertionError("a Waymo folder opened as nuScenes")
    except ValueError as e:
        assert "v1.0-mini" in str(e) or str(seg) in str(e)
