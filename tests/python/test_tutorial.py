"""docs/tutorial.md, run as written (ctest python/tutorial).

The tutorial's fenced code blocks run in order, as a newcomer would type them:

- ```sh blocks are the set-up (install the Debian packages, configure and
  build): they are NOT run here -- ctest runs inside the build they describe;
- ```bash blocks run with `bash -euo pipefail` from the repository root;
- ```python blocks run with /usr/bin/python3 (PYTHONPATH from ctest: the
  module of this build);
- ```text blocks are expected outputs, read by no one but the reader.

In the code, `./build/apps/geodrive` becomes $GEODRIVE_BINARY (this build's
binary), the tutorial's working folder /tmp/geodrive_tutorial becomes
pytest's tmp_path, and ../shared/data/real the real-data folder of the other
tests. The checks below assert what the tutorial promises: pair counts, exit
codes, the figures it prints, and the shape of the PyTorch batch. Every
check must meet its block, so a step cannot silently leave the tutorial.
"""
import json
import os
import re
import subprocess

import pytest

from conftest import GEODRIVE, REAL

TUTORIAL = "docs/tutorial.md"
WORKDIR = "/tmp/geodrive_tutorial"
BLOCK = re.compile(r"^```(\w*)\n(.*?)^```[ \t]*$", re.M | re.S)


def blocks():
    """(language, code) of every fenced block of the tutorial, in order."""
    with open(TUTORIAL, encoding="utf-8") as f:
        return BLOCK.findall(f.read())


def manifest(path):
    with open(path, encoding="utf-8") as f:
        return [json.loads(line) for line in f if line.strip()]


def frame0_means(out):
    """(coverage, PSNR) of the builder's 'frame 0 of N pairs built' line."""
    m = re.search(r"frame 0 of (\d+) pairs built \(means\): coverage ([0-9.]+), "
                  r"static-region PSNR ([0-9.]+) dB", out)
    assert m, out
    return int(m.group(1)), float(m.group(2)), float(m.group(3))


# What each run block must give, matched by a piece of its code (first match
# wins). Each check gets (stdout + stderr, working folder).
def check_synth(out, w):
    assert os.path.isfile(os.path.join(w, "synth", "v1.0-mini", "sample_data.json"))
    clips = sorted(os.listdir(os.path.join(w, "synth", "monst3r")))
    assert len(clips) == 9 and clips[0] == "scene-0001_0000", clips
    assert "9 MonST3R clips" in out, out


def check_synth_info(out, w):
    assert "scenes 1, samples 40" in out and "LIDAR_TOP" in out, out
    assert "(36 clips from 1 scenes" in out, out


def check_synth_build(out, w):
    n, coverage, psnr = frame0_means(out)
    assert n == 9 and "failed 0 of 9 clips" in out, out
    assert abs(coverage - 0.897) < 0.01 and abs(psnr - 30.7) < 0.5, out
    pairs = manifest(os.path.join(w, "synth_pairs", "manifest.jsonl"))
    assert len(pairs) == 9 and {p["geometry_source"] for p in pairs} == {"monst3r"}
    assert os.path.getsize(os.path.join(w, "synth_pairs", "failures.jsonl")) == 0


def check_real_info(out, w):
    assert "attribute visibility log map" in out, out
    assert "(3 clips from 1 scenes" in out, out


def check_real_lidar(out, w):
    assert "optional tables missing" in out, out
    n, coverage, psnr = frame0_means(out)
    assert n == 3 and abs(coverage - 0.150) < 0.01 and abs(psnr - 23.3) < 0.5, out
    ids = [p["clip_id"] for p in manifest(os.path.join(w, "real_lidar", "manifest.jsonl"))]
    assert ids == ["scene-0916_0000_kf", "scene-0916_0006_kf", "scene-0916_0012_kf"], ids


def check_real_dense(out, w):
    n, coverage, psnr = frame0_means(out)
    assert n == 3 and abs(coverage - 0.738) < 0.01 and abs(psnr - 36.7) < 0.5, out
    assert "1.000 of it completed" in out, out
    pair = os.path.join(w, "real_dense", "pairs", "scene-0916_0006_kf")
    for name in ("gt.mp4", "cond.mp4", "first_frame.png", "boxes.json", "meta.json",
                 "preview.png", "completion.png"):
        assert os.path.isfile(os.path.join(pair, name)), name


def check_pair_listing(out, w):
    for name in ("gt.mp4", "cond.mp4", "meta.json", "preview.png"):
        assert name in out, out


def check_meta(out, w):
    assert "scene-0916_0006_kf geometry lidar-dense preset footprint 25 frames 0.5 s apart" in out, out
    assert "poses in metres" in out and "frame 0: coverage 0.731" in out, out


def check_batch(out, w):
    assert "3 pairs, 2 batches of 2" in out, out
    assert "gt (2, 49, 3, 480, 720) torch.float32" in out, out
    assert "cond (2, 49, 3, 480, 720) torch.float32" in out, out
    assert "['scene-0916_0000_kf', 'scene-0916_0006_kf']" in out, out


CHECKS = [
    ("geodrive synth", check_synth),
    ("nuscenes-info --dataroot /tmp/geodrive_tutorial/synth", check_synth_info),
    ("--out /tmp/geodrive_tutorial/synth_pairs", check_synth_build),
    ("nuscenes-info --dataroot ../shared", check_real_info),
    ("--out /tmp/geodrive_tutorial/real_lidar", check_real_lidar),
    ("--out /tmp/geodrive_tutorial/real_dense", check_real_dense),
    ("ls /tmp/geodrive_tutorial/real_dense/pairs/", check_pair_listing),
    ("read_meta", check_meta),
    ("PairDataset", check_batch),
]


def test_the_setup_blocks_are_the_ones_not_run():
    setup = [code for lang, code in blocks() if lang == "sh"]
    assert setup, "the set-up is fenced as ```sh"
    text = "\n".join(setup)
    assert "GEODRIVE_WITH_TORCH=1 bash scripts/install_deps.sh" in text
    assert "-DGEODRIVE_WITH_PYTHON=ON" in text
    for lang, code in blocks():
        assert lang in ("sh", "bash", "python", "text"), "unknown block ```" + lang
    # The targets the set-up builds exist (the build itself is not run here).
    defined = ""
    for folder in ("apps", "python"):
        with open(os.path.join(folder, "CMakeLists.txt"), encoding="utf-8") as f:
            defined += f.read()
    targets = re.findall(r"--target ([\w ]+)", text)
    assert targets, text
    for name in " ".join(targets).split():
        assert re.search(r"(add_executable|pybind11_add_module)\(%s " % name, defined), name


def test_the_tutorial_runs_as_written(real_scene, tmp_path):
    work = str(tmp_path / "geodrive_tutorial")
    binary = os.path.abspath(GEODRIVE)
    real = os.path.abspath(REAL)
    used = set()
    ran = 0
    for lang, code in blocks():
        if lang not in ("bash", "python"):
            continue
        original = code
        code = (code.replace("./build/apps/geodrive", binary)
                    .replace(WORKDIR, work)
                    .replace("../shared/data/real", real))
        if lang == "bash":
            cmd = ["bash", "-euo", "pipefail", "-c", code]
        else:
            cmd = ["/usr/bin/python3", "-c", code]
        r = subprocess.run(cmd, capture_output=True, text=True, timeout=900)
        out = r.stdout + r.stderr
        assert r.returncode == 0, "tutorial block failed (exit %d):\n%s\n--- output:\n%s" % (
            r.returncode, original, out)
        ran += 1
        for i, (key, check) in enumerate(CHECKS):
            if key in original:
                check(out, work)
                used.add(i)
                break
    unused = [CHECKS[i][0] for i in range(len(CHECKS)) if i not in used]
    assert not unused, "tutorial steps no longer in docs/tutorial.md: %s" % unused
    assert ran >= len(CHECKS)
