"""geodrive's array functions against NumPy / skimage references."""
import concurrent.futures
import os

import numpy as np
import pytest

import geodrive
from conftest import require


def make_scene(rng, n=4000, W=64, H=48):
    """Points whose projections in frame 0 lie 0.2+ px inside a pixel, with
    distinct depths; K for W x H; 3 poses (cam_from_world)."""
    K = np.array([[40.0, 0, 31.5], [0, 40.0, 23.5], [0, 0, 1]])
    u = rng.integers(0, W, n) + rng.uniform(-0.3, 0.3, n)
    v = rng.integers(0, H, n) + rng.uniform(-0.3, 0.3, n)
    z = rng.uniform(2.0, 50.0, n)
    x = (u - K[0, 2]) / K[0, 0] * z
    y = (v - K[1, 2]) / K[1, 1] * z
    pts = np.stack([x, y, z], 1).astype(np.float32)
    cols = rng.integers(0, 256, (n, 3)).astype(np.uint8)
    poses = np.repeat(np.eye(4)[None], 3, 0)
    poses[1, 0, 3] = 0.3   # camera 1 sees the points shifted
    poses[2, 2, 3] = -1.0
    return pts, cols, K, poses


def numpy_zbuffer(pts, cols, K, cam_from_world, H, W, near=0.1, far=100.0):
    """The paper's z-buffer with one pixel per point: pixel = floor(u + 0.5)
    (integer-index centres), nearest z wins, ties to the smaller index."""
    rgb = np.zeros((H, W, 3), np.uint8)
    depth = np.zeros((H, W), np.float32)
    p = pts.astype(np.float64) @ cam_from_world[:3, :3].T + cam_from_world[:3, 3]
    z = p[:, 2]
    ok = (z > near) & (z < far)
    u = np.floor(K[0, 0] * p[:, 0] / np.where(ok, z, 1) + K[0, 2] + 0.5)
    v = np.floor(K[1, 1] * p[:, 1] / np.where(ok, z, 1) + K[1, 2] + 0.5)
    ok &= (u >= 0) & (u < W) & (v >= 0) & (v < H)
    idx = np.nonzero(ok)[0]
    order = np.lexsort((idx, z[idx]))[::-1]   # far first, nearest written last
    for i in idx[order]:
        rgb[int(v[i]), int(u[i])] = cols[i]
        depth[int(v[i]), int(u[i])] = z[i]
    return rgb, depth


def test_render_matches_a_numpy_zbuffer_pixel_for_pixel():
    rng = np.random.default_rng(3)
    pts, cols, K, poses = make_scene(rng)
    r = geodrive.render(pts, cols, K, poses, size=(48, 64))
    assert r["rgb"].shape == (3, 48, 64, 3) and r["rgb"].dtype == np.uint8
    assert r["depth"].dtype == np.float32 and r["valid"].dtype == np.bool_
    for t in range(3):
        rgb, depth = numpy_zbuffer(pts, cols, K, poses[t], 48, 64)
        np.testing.assert_array_equal(r["rgb"][t], rgb)
        np.testing.assert_array_equal(r["valid"][t], depth > 0)
        np.testing.assert_allclose(r["depth"][t], depth, rtol=1e-5)


def test_ssim_and_psnr_match_skimage():
    skimage_metrics = require("skimage.metrics")
    rng = np.random.default_rng(4)
    a = rng.integers(0, 256, (48, 64, 3)).astype(np.uint8)
    b = np.clip(a.astype(int) + rng.integers(-20, 21, a.shape), 0, 255).astype(np.uint8)
    ref = skimage_metrics.structural_similarity(
        a, b, channel_axis=-1, gaussian_weights=True, sigma=1.5,
        use_sample_covariance=False, data_range=255)
    assert abs(geodrive.ssim(a, b) - ref) < 1e-9
    mse = np.mean((a.astype(float) - b) ** 2)
    assert abs(geodrive.psnr(a, b) - 10 * np.log10(255 ** 2 / mse)) < 1e-9


def test_trajectory_edits_and_ade_fde_against_numpy():
    poses = np.repeat(np.eye(4)[None], 5, 0)
    poses[:, 2, 3] = np.arange(5.0)          # forward 1 m a frame
    left = geodrive.edit_trajectory(poses, shift_left=3.0)
    np.testing.assert_allclose(left[:, :3, 3], poses[:, :3, 3] - [3, 0, 0])
    rev = geodrive.edit_trajectory(poses, reverse=True)
    np.testing.assert_allclose(rev[:, 2, 3], np.arange(5.0)[::-1])
    e = geodrive.ade_fde(left, poses)
    assert abs(e["ade"] - 3) < 1e-12 and abs(e["fde"] - 3) < 1e-12
    e = geodrive.ade_fde(left, poses, align="se3")
    assert e["ade"] < 1e-9


def test_bad_input_raises_value_error_with_the_cli_message(tmp_path):
    rng = np.random.default_rng(5)
    pts, cols, K, poses = make_scene(rng, n=10)
    with pytest.raises(ValueError, match=r"colors: shape \(9, 3\), expected \(10, 3\)"):
        geodrive.render(pts, cols[:9], K, poses)
    with pytest.raises(ValueError, match="expected"):
        geodrive.render(pts, cols, np.eye(4), poses)
    with pytest.raises(ValueError, match="missing.mp4"):
        geodrive.read_video(str(tmp_path / "missing.mp4"))
    with pytest.raises(ValueError, match="unknown scene source 'nope'"):
        geodrive.condition_scene("nope", path="x")
    bad = tmp_path / "bad.npz"
    bad.write_bytes(b"PK\x03\x04 not a zip")
    with pytest.raises(ValueError, match="bad.npz"):
        geodrive.condition_scene("npz", path=str(bad))


def rss_mb():
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2 ** 20


def test_no_leak_over_1000_calls():
    rng = np.random.default_rng(6)
    pts, cols, K, poses = make_scene(rng, n=2000)
    for _ in range(50):   # warm up allocator pools
        geodrive.render(pts, cols, K, poses, size=(48, 64))
    before = rss_mb()
    for _ in range(1000):
        r = geodrive.render(pts, cols, K, poses, size=(48, 64))
        geodrive.ssim(r["rgb"][0], r["rgb"][1])
        try:
            geodrive.render(pts, cols[:1], K, poses)
        except ValueError:
            pass
    grown = rss_mb() - before
    # 1000 calls return 1000 x 37 KB of arrays: a leak of them would be 37 MB.
    assert grown < 8, "RSS grew by %.1f MB" % grown


def test_threads_render_the_same_as_one():
    rng = np.random.default_rng(7)
    pts, cols, K, poses = make_scene(rng, n=20000)
    ref = geodrive.render(pts, cols, K, poses, size=(48, 64))["rgb"]
    with concurrent.futures.ThreadPoolExecutor(4) as ex:
        outs = list(ex.map(lambda _: geodrive.render(
            pts, cols, K, poses, size=(48, 64))["rgb"], range(16)))
    for o in outs:
        np.testing.assert_array_equal(o, ref)


def test_render_into_a_previous_result():
    rng = np.random.default_rng(8)
    pts, cols, K, poses = make_scene(rng)
    first = geodrive.render(pts, cols, K, poses, size=(48, 64))
    expect = {k: v.copy() for k, v in first.items()}
    pts2, cols2, _, _ = make_scene(rng)
    geodrive.render(pts2, cols2, K, poses, size=(48, 64), out=first)  # dirty them
    again = geodrive.render(pts, cols, K, poses, size=(48, 64), out=first)
    for k in ("rgb", "depth", "valid"):
        assert again[k] is first[k]
        np.testing.assert_array_equal(again[k], expect[k])
    assert set(np.unique(again["valid"].view(np.uint8))) <= {0, 1}
    with pytest.raises(ValueError, match="do not match this render"):
        geodrive.render(pts, cols, K, poses[:2], size=(48, 64), out=first)
