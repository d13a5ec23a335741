"""Shared fixtures of the Python module's tests (run by ctest; see
tests/python/CMakeLists.txt): the module from the build tree, the real
nuScenes extract, a small built pair set (geodrive synth + build-dataset,
the demo's pipeline at a smaller size) and a small surround-view pair."""
import importlib
import os
import subprocess

import pytest

GEODRIVE = os.environ.get("GEODRIVE_BINARY", "build/apps/geodrive")
REAL = os.environ.get("GEODRIVE_REAL_DATA", "../shared/data/real")


@pytest.fixture(scope="session")
def real_scene():
    root = os.path.join(REAL, "nuscenes_scene0916")
    if not os.path.isdir(root):
        pytest.fail("real data missing: " + root)
    return root


@pytest.fixture(scope="session")
def pairs(tmp_path_factory):
    """manifest.jsonl of pairs built from a 1-scene synthetic world."""
    d = tmp_path_factory.mktemp("pairs")
    synth, out = d / "synth", d / "out"
    subprocess.run([GEODRIVE, "synth", "--out", str(synth), "--scenes", "1",
                    "--duration", "4.5", "--size", "450x800", "--monst3r"],
                   check=True, capture_output=True)
    subprocess.run([GEODRIVE, "build-dataset", "--dataroot", str(synth),
                    "--monst3r", str(synth / "monst3r"), "--out", str(out),
                    "--threads", "2"], check=True, capture_output=True)
    return str(out / "manifest.jsonl")


@pytest.fixture(scope="session")
def rig_pairs(tmp_path_factory):
    """manifest.jsonl of one six-camera surround-view pair (build-dataset
    --cameras all, lidar-dense, 90x160) from a 3-second synthetic world with
    every camera; and the manifest of one single-camera pair of the same
    world (clip scene-0001_0006), as (rig manifest, single manifest)."""
    d = tmp_path_factory.mktemp("rig_pairs")
    synth, rig, single = d / "synth", d / "rig", d / "single"
    subprocess.run([GEODRIVE, "synth", "--out", str(synth), "--scenes", "1",
                    "--duration", "3", "--size", "90x160", "--cameras", "all"],
                   check=True, capture_output=True)
    common = ["build-dataset", "--dataroot", str(synth), "--geometry",
              "lidar-dense", "--size", "90x160", "--quiet"]
    subprocess.run([GEODRIVE] + common + ["--cameras", "all", "--max-clips", "1",
                                          "--out", str(rig)],
                   check=True, capture_output=True)
    subprocess.run([GEODRIVE] + common + ["--clips", "scene-0001_0006",
                                          "--out", str(single)],
                   check=True, capture_output=True)
    return str(rig / "manifest.jsonl"), str(single / "manifest.jsonl")


def require(module):
    """The module, or a skip -- a failure when CI requires every Python
    cross-check (GEODRIVE_REQUIRE_PYTHON_CHECKS=1)."""
    try:
        return importlib.import_module(module)
    except ImportError:
        if os.environ.get("GEODRIVE_REQUIRE_PYTHON_CHECKS") == "1":
            pytest.fail("python module %s missing (GEODRIVE_REQUIRE_PYTHON_CHECKS=1)" % module)
        pytest.skip("python module %s missing" % module)
