"""The Python module under hostile use: rendering in forked children, paths
as pathlib.Path, arguments of the wrong type or encoding, FIFOs, folders,
out of memory. Every error is one line naming the argument or the file."""
import errno
import json
import multiprocessing
import os
import pathlib
import queue as queue_module
import signal
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest

import geodrive
from conftest import REAL


def _torch():
    try:
        import torch
        return torch
    except ImportError:
        return None


KITTI_POSES = os.path.join(REAL, "kitti_odometry_00", "00.txt")

# ---- Fork safety (python/bindings.cc: ForkedChildRunsOpenMPSerially) ----

_SCENE = {}


def _make_scene(n=30000, T=6):
    rng = np.random.default_rng(11)
    pts = np.stack([rng.uniform(-8, 8, n), rng.uniform(-5, 5, n),
                    rng.uniform(3, 40, n)], 1).astype(np.float32)
    cols = rng.integers(0, 256, (n, 3)).astype(np.uint8)
    K = np.array([[80.0, 0, 63.5], [0, 80.0, 47.5], [0, 0, 1]])
    poses = np.repeat(np.eye(4)[None], T, 0)
    poses[:, 0, 3] = np.linspace(0, 1, T)
    poses[:, 2, 3] = -np.linspace(0, 2, T)
    return pts, cols, K, poses


def _render_two_frames(task):
    """In a pool worker: frames task, task + 1 with two threads (a parallel
    region of two threads: what hung in forked children)."""
    pts, cols, K, poses = _SCENE["scene"]
    r = geodrive.render(pts, cols, K, poses[task:task + 2], size=(96, 128),
                        threads=2)
    return task, r["rgb"], r["depth"], r["valid"]


def test_render_in_forked_pool_after_a_threaded_render():
    start = time.monotonic()
    _SCENE["scene"] = pts, cols, K, poses = _make_scene()
    ref = geodrive.render(pts, cols, K, poses, size=(96, 128), threads=2)
    with multiprocessing.get_context("fork").Pool(2) as pool:
        pending = pool.map_async(_render_two_frames, range(4))
        try:
            results = pending.get(timeout=20)   # a hang fails, then terminates
        except multiprocessing.TimeoutError:
            pytest.fail("rendering in forked workers did not finish in 20 s")
    assert sorted(r[0] for r in results) == [0, 1, 2, 3]
    for task, rgb, depth, valid in results:
        np.testing.assert_array_equal(rgb, ref["rgb"][task:task + 2])
        np.testing.assert_array_equal(depth, ref["depth"][task:task + 2])
        np.testing.assert_array_equal(valid, ref["valid"][task:task + 2])
    # The parent still renders on its threads, the same bytes.
    again = geodrive.render(pts, cols, K, poses, size=(96, 128), threads=2)
    np.testing.assert_array_equal(again["rgb"], ref["rgb"])
    assert time.monotonic() - start < 20


def _render_then_fork(queue, depth):
    """A forked child: renders, then forks a child that does the same."""
    signal.alarm(25)   # a hung child dies (SIGALRM's default action)
    queue.put((depth, _render_two_frames(0)[1]))
    if depth < 2:
        child = multiprocessing.get_context("fork").Process(
            target=_render_then_fork, args=(queue, depth + 1))
        child.start()
        child.join(25)


def test_nested_forks_render():
    """A forked child renders and forks again: every level renders."""
    _SCENE["scene"] = pts, cols, K, poses = _make_scene(n=5000)
    ref = geodrive.render(pts, cols, K, poses[:2], size=(96, 128), threads=2)
    ctx = multiprocessing.get_context("fork")
    queue = ctx.Queue()
    child = ctx.Process(target=_render_then_fork, args=(queue, 1))
    child.start()
    try:
        got = dict(queue.get(timeout=20) for _ in range(2))
    except queue_module.Empty:
        pytest.fail("a forked child did not render in 20 s")
    finally:
        child.join(10)
        if child.is_alive():
            child.terminate()
    assert sorted(got) == [1, 2]
    for rgb in got.values():
        np.testing.assert_array_equal(rgb, ref["rgb"])


# ---- Paths: str or os.PathLike (python/bindings.cc: PathArg) ----


def _write_npz(path, N=3, H=6, W=8):
    depth = np.full((N, H, W), 5.0, np.float32)
    K = np.array([[7.0, 0, 3.5], [0, 7.0, 2.5], [0, 0, 1]])
    c2w = np.repeat(np.eye(4)[None], N, 0)
    np.savez(path, depth=depth, intrinsics=K, cam_c2w=c2w, units="metres",
             images=np.full((N, H, W, 3), 200, np.uint8))


def test_pathlib_paths_are_accepted(pairs, real_scene, tmp_path):
    manifest = pathlib.Path(pairs)
    entries = geodrive.read_manifest(manifest)
    assert entries == geodrive.read_manifest(str(manifest))
    pair_dir = manifest.parent / entries[0]["pair_dir"]
    assert geodrive.read_meta(pair_dir) == geodrive.read_meta(str(pair_dir))
    assert geodrive.read_video(pair_dir / "gt.mp4").shape[0] == 25
    record = geodrive._read_pair(manifest.parent, entries[0])
    assert record["num_frames"] == 25
    poses, _ = geodrive.read_trajectory(pathlib.Path(KITTI_POSES))
    assert poses.shape == (4541, 4, 4)
    npz = tmp_path / "scene.npz"
    _write_npz(npz)
    assert geodrive.reconstruction_format(npz) == "npz"
    assert geodrive.reconstruction_format(os.fsencode(npz)) == "npz"   # bytes
    scene = geodrive.condition_scene("npz", path=npz, filter="released")
    assert scene.image_size == (8, 6)
    ds = geodrive.open_dataset(pathlib.Path(real_scene), "v1.0-mini-extract",
                               frames="keyframes")
    assert ds.clip_ids
    r = geodrive.render_with_edits(scene.points, scene.colors, scene.K_at(8, 6),
                                   np.repeat(np.eye(4)[None], 25, 0),
                                   pair_dir / "boxes.json", size=(6, 8))
    assert r["rgb"].shape == (25, 6, 8, 3)
    if _torch():
        from geodrive.torch import PairDataset
        assert len(PairDataset(manifest)) == len(entries)


# ---- Argument errors: one line naming the argument (geodrive/_args.py) ----


def _one_line_error(kind, call, *must_contain):
    with pytest.raises(kind) as e:
        call()
    msg = str(e.value)
    assert msg and "\n" not in msg and len(msg) < 300, msg
    for part in must_contain:
        assert part in msg, (part, msg)
    # The pybind11 dump is not chained onto it either.
    assert e.value.__cause__ is None and e.value.__suppress_context__ or \
        e.value.__context__ is None
    return msg


def test_wrong_types_raise_type_error_naming_the_argument(real_scene, tmp_path):
    pts, cols, K, poses = _make_scene(n=100, T=2)
    npz = tmp_path / "scene.npz"
    _write_npz(npz)
    scene = geodrive.condition_scene("npz", path=str(npz), filter="released")
    ds = geodrive.open_dataset(real_scene, "v1.0-mini-extract", frames="keyframes")
    clip = ds.load_clip(ds.clip_ids[0])
    cases = [
        ("render()", "size", lambda: geodrive.render(pts, cols, K, poses, size="480x720")),
        ("render()", "points", lambda: geodrive.render("points", cols, K, poses)),
        ("render()", "threads", lambda: geodrive.render(pts, cols, K, poses, threads=2.5)),
        ("render()", "footprints", lambda: geodrive.render(pts, cols, K, poses, footprints={})),
        ("render()", "colour", lambda: geodrive.render(pts, cols, K, poses, colour=cols)),
        ("render()", "cam_from_world", lambda: geodrive.render(pts, cols, K)),
        ("edit_trajectory()", "speed", lambda: geodrive.edit_trajectory(poses, speed="fast")),
        ("open_dataset()", "root", lambda: geodrive.open_dataset(5)),
        ("open_dataset()", "clip_frames", lambda: geodrive.open_dataset(real_scene, clip_frames="25")),
        ("read_trajectory()", "path", lambda: geodrive.read_trajectory(None)),
        ("read_manifest()", "path", lambda: geodrive.read_manifest(["a.jsonl"])),
        ("read_meta()", "pair_dir", lambda: geodrive.read_meta(3)),
        ("read_video()", "path", lambda: geodrive.read_video(path=3.5)),
        ("condition_scene()", "clip", lambda: geodrive.condition_scene("lidar", clip="clip")),
        ("render_with_edits()", "remove", lambda: geodrive.render_with_edits(
            pts, cols, K, poses, "boxes.json", remove="car")),
        ("psnr()", "b", lambda: geodrive.psnr(np.zeros((2, 2, 3), np.uint8), b=object())),
        ("ade_fde()", "align", lambda: geodrive.ade_fde(poses, poses, align=None)),
        ("Dataset.load_clip()", "clip_id", lambda: ds.load_clip(7)),
        ("Clip.boxes()", "frame", lambda: clip.boxes("0")),
        ("ConditionScene.K_at()", "height", lambda: scene.K_at(8, [6])),
    ]
    for function, argument, call in cases:
        _one_line_error(TypeError, call, function, "'%s'" % argument)
    _one_line_error(TypeError, lambda: geodrive.read_video("x.mp4", 2),
                    "read_video() takes at most 1 arguments (2 given)")
    if _torch():
        from geodrive.torch import PairDataset
        _one_line_error(TypeError, lambda: PairDataset(12), "PairDataset()", "'manifest'")
        _one_line_error(TypeError, lambda: PairDataset("m.jsonl", size=5), "'size'")


# ---- Bad text, FIFOs, folders: ValueError naming the file or argument ----


def test_non_utf8_text_is_a_value_error_naming_it(tmp_path):
    traj = tmp_path / "traj.txt"
    traj.write_bytes(b"\xff\xfe 1 2 3 4 5 6 7\n")
    msg = _one_line_error(ValueError, lambda: geodrive.read_trajectory(traj), "traj.txt")
    assert "\\xff" in msg   # the bytes shown escaped, never an empty message
    manifest = tmp_path / "manifest.jsonl"
    manifest.write_bytes(b'{"clip_id": "\xff\xfe"}\n')
    _one_line_error(ValueError, lambda: geodrive.read_manifest(manifest), "manifest.jsonl")
    boxes = tmp_path / "boxes.json"
    boxes.write_bytes(b'{"format": "\xc3\x28"}')
    pts, cols, K, poses = _make_scene(n=10, T=1)
    _one_line_error(ValueError, lambda: geodrive.render_with_edits(
        pts, cols, K, poses, boxes, size=(96, 128)), "boxes.json")
    # Paths and text arguments that are not UTF-8 (undecodable file names
    # as os.listdir gives them) or hold a NUL byte.
    undecodable = os.fsdecode(bytes(tmp_path) + b"/\xff.txt")
    _one_line_error(ValueError, lambda: geodrive.read_trajectory(undecodable),
                    "read_trajectory()", "'path'", "UTF-8")
    _one_line_error(ValueError, lambda: geodrive.read_video(bytes(tmp_path) + b"/\xfe.mp4"),
                    "read_video()", "'path'", "UTF-8")
    _one_line_error(ValueError, lambda: geodrive.read_manifest(str(tmp_path) + "/a\0b"),
                    "read_manifest()", "'path'", "NUL")
    _one_line_error(ValueError, lambda: geodrive.condition_scene("\udcff"),
                    "condition_scene()", "'source'", "UTF-8")


def test_folders_are_value_errors(tmp_path):
    for call in (lambda: geodrive.read_manifest(tmp_path),
                 lambda: geodrive.read_trajectory(tmp_path),
                 lambda: geodrive.read_video(tmp_path)):
        _one_line_error(ValueError, call, str(tmp_path))


def test_fifos_are_value_errors_and_never_block(tmp_path):
    """Each reader on a FIFO with no writer: ValueError naming it, at once
    (in a child process, so a reader that blocks fails the test by its
    timeout instead of hanging it)."""
    code = textwrap.dedent("""
        import os, sys, numpy as np, geodrive
        d = sys.argv[1]
        for name in ("t.txt", "m.jsonl", "v.mp4", "b.json", "m3r/pred_traj.txt"):
            os.makedirs(os.path.dirname(os.path.join(d, name)), exist_ok=True)
            os.mkfifo(os.path.join(d, name))
        K = np.array([[80.0, 0, 63.5], [0, 80.0, 47.5], [0, 0, 1]])
        calls = [
            ("t.txt", lambda: geodrive.read_trajectory(os.path.join(d, "t.txt"))),
            ("m.jsonl", lambda: geodrive.read_manifest(os.path.join(d, "m.jsonl"))),
            ("v.mp4", lambda: geodrive.read_video(os.path.join(d, "v.mp4"))),
            ("b.json", lambda: geodrive.render_with_edits(
                np.zeros((1, 3), np.float32), np.zeros((1, 3), np.uint8), K,
                np.eye(4), os.path.join(d, "b.json"), size=(96, 128))),
            ("pred_traj.txt", lambda: geodrive.condition_scene(
                "monst3r", os.path.join(d, "m3r"))),
        ]
        for name, call in calls:
            try:
                call()
                print("no error", name)
            except ValueError as e:
                assert name in str(e) and "\\n" not in str(e), str(e)
                print("ok", name)
    """)
    out = subprocess.run([sys.executable, "-c", code, str(tmp_path)],
                         capture_output=True, text=True, timeout=20)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split("\n")[:-1] == ["ok " + n for n in (
        "t.txt", "m.jsonl", "v.mp4", "b.json", "pred_traj.txt")], out.stdout


# ---- Out of memory, file-system errors (python/bindings.cc: TranslateException) ----


def test_out_of_memory_is_one_memory_error():
    """Under an address-space limit a render whose C++ copy of the cloud
    cannot be allocated: MemoryError with the documented line."""
    code = textwrap.dedent("""
        import resource, numpy as np, geodrive
        n = 40_000_000   # 600 MB of points: reserved, never touched
        pts, cols = np.zeros((n, 3), np.float32), np.zeros((n, 3), np.uint8)
        size = [int(l.split()[1]) * 1024 for l in open("/proc/self/status")
                if l.startswith("VmSize")][0]
        resource.setrlimit(resource.RLIMIT_AS, (size + (200 << 20), resource.RLIM_INFINITY))
        K = np.array([[80.0, 0, 63.5], [0, 80.0, 47.5], [0, 0, 1]])
        try:
            geodrive.render(pts, cols, K, np.eye(4), size=(96, 128), threads=1)
        except MemoryError as e:
            print(e)
    """)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True,
                         text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    assert out.stdout == (
        "out of memory (the call needs more memory than this process may use: "
        "try a smaller size, fewer frames or fewer threads)\n")


def test_file_system_errors_name_the_path(tmp_path):
    long_path = str(tmp_path / ("x" * 5000))
    for call in (lambda: geodrive.read_video(long_path),
                 lambda: geodrive.condition_scene("monst3r", long_path),
                 lambda: geodrive.read_trajectory(long_path)):
        with pytest.raises((OSError, ValueError)) as e:
            call()
        assert "\n" not in str(e.value)
        if isinstance(e.value, OSError):   # std::filesystem errors
            assert e.value.errno == errno.ENAMETOOLONG
            assert e.value.filename == long_path
        else:
            assert long_path in str(e.value)


def test_colours_and_images_are_uint8_never_coerced():
    """Float colours in [0, 1] used to render black, float and uint16 images
    gave PSNR 62 dB for a 29 dB pair: every non-uint8 colour or image is a
    ValueError naming the argument and the conversion to make."""
    pts = np.array([[0, 0, 5.0]], np.float32)
    K = np.array([[100.0, 0, 50], [0, 100.0, 50], [0, 0, 1]])
    poses = np.eye(4)[None]
    bad = [np.ones((1, 3)), np.ones((1, 3), np.float32), np.full((1, 3), 200, np.uint16),
           np.full((1, 3), 200, np.int64), np.full((1, 3), True)]
    for colors in bad:
        with pytest.raises(ValueError, match=r"^colors: dtype \w+, expected uint8"):
            geodrive.render(pts, colors, K, poses, size=(100, 100))
    ok = geodrive.render(pts, np.full((1, 3), 200, np.uint8), K, poses, size=(100, 100))
    assert ok["rgb"][0, 50, 50].tolist() == [200, 200, 200]
    a = np.random.default_rng(0).integers(0, 256, (16, 16, 3)).astype(np.uint8)
    b = np.clip(a.astype(int) + 8, 0, 255).astype(np.uint8)
    for dtype in (np.float32, np.float64, np.uint16):
        with pytest.raises(ValueError, match=r"^a: dtype"):
            geodrive.psnr(a.astype(dtype), b)
        with pytest.raises(ValueError, match=r"^b: dtype"):
            geodrive.ssim(a, b.astype(dtype))
    # The uint8 figure is the reference formula's.
    mse = ((a.astype(float) - b.astype(float)) ** 2).mean()
    assert abs(geodrive.psnr(a, b) - 10 * np.log10(255 ** 2 / mse)) < 1e-9


def test_pair_dataset_reads_through_the_cpp_checks(pairs, tmp_path):
    """PairDataset goes through ReadPair's checks and the frame counts of
    meta.json: a short gt.mp4, a pair_dir that climbs out or is absolute, a
    clip id that is not a folder name, a pair whose meta.json names another
    clip and a missing video are each one ValueError naming the problem."""
    torch = _torch()
    if torch is None:
        pytest.skip("torch missing")
    import shutil
    from geodrive.torch import PairDataset
    src = os.path.dirname(pairs)
    lines = [json.loads(l) for l in open(pairs)]
    assert len(lines) >= 2

    def build(name, edit_line=None, edit_tree=None):
        root = tmp_path / name
        shutil.copytree(src, root, symlinks=True)
        first = dict(lines[0])
        if edit_line:
            edit_line(first)
        with open(root / "manifest.jsonl", "w") as f:
            f.write(json.dumps(first) + "\n")
        if edit_tree:
            edit_tree(root / lines[0]["pair_dir"], root)
        return PairDataset(root / "manifest.jsonl")

    ok = build("ok")
    item = ok[0]
    assert item["gt"].shape[0] == lines[0]["num_frames"]

    def short_gt(pair, root):  # a 10-frame gt.mp4 beside a 25-frame cond.mp4
        frames = geodrive.read_video(str(pair / "gt.mp4"))[:10]
        cv2 = pytest.importorskip("cv2")
        w = cv2.VideoWriter(str(pair / "gt_short.mp4"), cv2.VideoWriter_fourcc(*"mp4v"),
                            10, (frames.shape[2], frames.shape[1]))
        for f in frames:
            w.write(cv2.cvtColor(f, cv2.COLOR_RGB2BGR))
        w.release()
        os.replace(pair / "gt_short.mp4", pair / "gt.mp4")

    # Each case fails when the dataset opens (manifest lines are checked as
    # they are read) or when the item is read: either is the same ValueError.
    cases = [
        (lambda: build("short", edit_tree=short_gt)[0],
         r"gt video has 10 frames, meta.json lists"),
        (lambda: build("climb", edit_line=lambda e: e.update(
            pair_dir="../" + os.path.basename(src)))[0], r"climbs out"),
        (lambda: build("absolute", edit_line=lambda e: e.update(
            pair_dir=os.path.abspath(src)))[0], r"is absolute"),
        (lambda: build("badid", edit_line=lambda e: e.update(clip_id="../x"))[0],
         r"not a plain folder name"),
        (lambda: build("otherclip", edit_line=lambda e: e.update(
            clip_id=lines[1]["clip_id"]))[0], r"differs from the manifest"),
        (lambda: build("novideo", edit_tree=lambda pair, root: os.remove(
            pair / "cond.mp4"))[0], r"cond.mp4: missing"),
    ]
    for read, message in cases:
        with pytest.raises(ValueError, match=message):
            read()
