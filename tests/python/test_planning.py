"""geodrive.plan: the same numbers as `geodrive plan`'s plan.json on the real
scene-0916, candidates as arrays, dicts and files, one clear error for a bad
candidate."""
import json
import os
import subprocess

import numpy as np
import pytest

import geodrive
from conftest import GEODRIVE


def _clip(real_scene):
    ds = geodrive.open_dataset(real_scene, version="v1.0-mini-extract",
                               frames="keyframes")
    return ds.load_clip("scene-0916_0000_kf")


def test_plan_equals_the_command_line(real_scene, tmp_path):
    clip = _clip(real_scene)
    t = np.arange(25) * 0.5
    straight = np.stack([t, 2.0 * t, 0 * t, 0 * t], axis=1)
    jsonl = tmp_path / "straight.jsonl"
    jsonl.write_text("".join(json.dumps({"t": a, "x": b, "y": 0.0}) + "\n"
                             for a, b in zip(t, 2.0 * t)))
    scores = geodrive.plan(clip, [jsonl, {"name": "arr", "waypoints": straight}],
                           shifts=[1, 2, 3])
    names = [s["name"] for s in scores]
    assert names == ["logged", "logged+1m", "logged-1m", "logged+2m",
                     "logged-2m", "logged+3m", "logged-3m", "straight", "arr"]
    assert sorted(s["rank"] for s in scores) == list(range(1, 10))
    logged = scores[0]
    assert not logged["rejected"] and logged["logged"]["ade_m"] == 0.0
    assert logged["collision"]["min_box_distance_m"] > 1.0
    # The file and the array are the same path: the same scores.
    assert scores[7]["cost"] == pytest.approx(scores[8]["cost"], abs=1e-9)
    shifted_right = scores[4]
    assert shifted_right["reject_reason"] == "collision"
    assert shifted_right["collision"]["first_with_category"] == "vehicle.car"

    out = tmp_path / "cli"
    subprocess.run([GEODRIVE, "plan", "--dataroot", real_scene, "--version",
                    "v1.0-mini-extract", "--frames", "keyframes", "--clip",
                    "scene-0916_0000_kf", "--out", str(out), "--shifts", "1",
                    "2", "3", "--candidates", str(jsonl)],
                   check=True, capture_output=True)
    cli = json.loads((out / "plan.json").read_text())["candidates"]
    assert [c["name"] for c in cli] == names[:8]
    for a, b in zip(cli, scores[:8]):
        assert a == b


def test_bad_candidates_are_one_clear_error(real_scene):
    clip = _clip(real_scene)
    jump = np.array([[0.0, 0, 0, 0], [0.1, 1, 0, 0], [0.2, 101, 0, 0]])
    with pytest.raises(ValueError, match=r"waypoint 2: jumps 100 m in 0.1 s"):
        geodrive.plan(clip, [jump])
    with pytest.raises(ValueError, match=r"\(N, 4\) array"):
        geodrive.plan(clip, [np.zeros((3, 3))])
    with pytest.raises(ValueError, match="no candidates"):
        geodrive.plan(clip, with_logged=False)
    assert os.path.isdir(real_scene)
