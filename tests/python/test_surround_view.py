"""Surround-view pairs (build-dataset --cameras all) read through
geodrive.read_pair and geodrive.torch.PairDataset: the schemas, the
(V, T, 3, H, W) layout in meta.json's camera order, every view's frames
against its own video files, mixed manifests and damaged views."""
import json
import os
import shutil

import numpy as np
import pytest

import geodrive
from conftest import require

SIX = ["CAM_FRONT", "CAM_FRONT_LEFT", "CAM_FRONT_RIGHT", "CAM_BACK_LEFT",
       "CAM_BACK", "CAM_BACK_RIGHT"]
SCHEMAS = os.path.join(os.path.dirname(__file__), "..", "..", "data_schema")


def _pair_dir(manifest):
    entry = geodrive.read_manifest(manifest)[0]
    return os.path.join(os.path.dirname(manifest), entry["pair_dir"])


def _as_tensor(frames):
    """What PairDataset makes of (T, H, W, 3) uint8 frames (no resize)."""
    torch = require("torch")
    return torch.from_numpy(frames).permute(0, 3, 1, 2).float() / 127.5 - 1.0


def test_meta_and_manifest_validate_against_schemas(rig_pairs):
    jsonschema = require("jsonschema")
    rig, _ = rig_pairs
    pair = _pair_dir(rig)
    for schema, docs in (
            ("pair_meta.schema.json", [json.load(open(os.path.join(pair, "meta.json")))]),
            ("manifest_line.schema.json", [json.loads(l) for l in open(rig) if l.strip()])):
        validator = jsonschema.Draft202012Validator(
            json.load(open(os.path.join(SCHEMAS, schema))))
        for doc in docs:
            errors = list(validator.iter_errors(doc))
            assert not errors, "%s: %s at %s" % (schema, errors[0].message,
                                                 list(errors[0].path))
    meta = geodrive.read_meta(pair)
    assert [v["channel"] for v in meta["views"]] == SIX
    assert meta["seams"], "neighbouring cameras overlap"
    for v in meta["views"]:
        for role in ("gt", "cond", "boxes"):
            assert meta["files"]["%s:%s" % (role, v["channel"])] == v["files"][role]
    assert os.path.samefile(os.path.join(pair, "cond.mp4"),
                            os.path.join(pair, "cond_CAM_FRONT.mp4"))


def test_read_pair_exposes_views(rig_pairs):
    rig, _ = rig_pairs
    entry = geodrive.read_manifest(rig)[0]
    record = geodrive.read_pair(os.path.dirname(rig), entry)
    meta = geodrive.read_meta(record["dir"])
    assert record["cameras"] == entry["cameras"] == SIX
    assert len(record["views"]) == 6 and len(record["seams"]) == len(meta["seams"])
    for view, mv in zip(record["views"], meta["views"]):
        assert view["channel"] == mv["channel"]
        assert view["cond_video"] == os.path.join(record["dir"], mv["files"]["cond"])
        assert view["gt_video"] == os.path.join(record["dir"], mv["files"]["gt"])
        k = mv["intrinsics"]
        assert np.array_equal(view["K"], [[k["fx"], 0, k["cx"]], [0, k["fy"], k["cy"]],
                                          [0, 0, 1]])
        assert view["image_size"] == (160, 90)
        assert view["world_from_cam"].shape == (25, 4, 4)
        assert np.allclose(view["world_from_cam"], mv["world_from_cam"], atol=1e-9)
        assert view["psnr_static"] == mv["psnr_static"]
        assert view["points_kept"] == mv["points_kept"]
    # The reference camera's poses are the pair's: identity at frame 0.
    assert np.allclose(record["views"][0]["world_from_cam"][0], np.eye(4), atol=1e-9)


def test_pair_dataset_shapes_order_and_frames(rig_pairs):
    torch = require("torch")
    from geodrive.torch import PairDataset
    rig, _ = rig_pairs
    pair = _pair_dir(rig)
    item = PairDataset(rig)[0]
    channels = [v["channel"] for v in geodrive.read_meta(pair)["views"]]
    assert item["cameras"] == channels == SIX
    assert item["meta"]["cameras"] == SIX
    assert item["gt"].shape == item["cond"].shape == (6, 25, 3, 90, 160)
    assert item["gt"].dtype == item["cond"].dtype == torch.float32
    assert -1.0 <= float(item["cond"].min()) and float(item["cond"].max()) <= 1.0
    # View k is camera k's own videos, decoded directly.
    for k, cam in enumerate(channels):
        cond = geodrive.read_video(os.path.join(pair, "cond_%s.mp4" % cam))
        gt = geodrive.read_video(os.path.join(pair, "gt_%s.mp4" % cam))
        assert torch.equal(item["cond"][k], _as_tensor(cond)), cam
        assert torch.equal(item["gt"][k], _as_tensor(gt)), cam
    # The views differ (not one video six times).
    assert not torch.equal(item["cond"][0], item["cond"][3])
    # Selected views, in the order asked, padded and resized like single pairs.
    sel = PairDataset(rig, frames=30, size=(48, 80),
                      cameras=["CAM_BACK", "CAM_FRONT"])[0]
    assert sel["cameras"] == ["CAM_BACK", "CAM_FRONT"]
    assert sel["cond"].shape == (2, 30, 3, 48, 80)
    assert torch.equal(sel["cond"][:, 29], sel["cond"][:, 24])
    full = PairDataset(rig, frames=30, size=(48, 80))[0]
    assert torch.equal(sel["cond"][0], full["cond"][SIX.index("CAM_BACK")])
    # The default collate batches surround-view items.
    batch = next(iter(torch.utils.data.DataLoader(PairDataset(rig), batch_size=1,
                                                  num_workers=1)))
    assert batch["gt"].shape == (1, 6, 25, 3, 90, 160)
    assert [c[0] for c in batch["cameras"]] == SIX
    assert torch.equal(batch["cond"][0], item["cond"])


def test_mixed_manifest_items_have_their_own_shapes(rig_pairs, tmp_path):
    torch = require("torch")
    from geodrive.torch import PairDataset
    rig, single = rig_pairs
    out = tmp_path / "mixed"
    shutil.copytree(os.path.dirname(rig), out)
    line = geodrive.read_manifest(single)[0]
    shutil.copytree(os.path.join(os.path.dirname(single), line["pair_dir"]),
                    out / line["pair_dir"])
    with open(out / "manifest.jsonl", "a") as f:
        f.write(json.dumps(line) + "\n")
    ds = PairDataset(out / "manifest.jsonl")
    shapes = sorted(tuple(ds[i]["gt"].shape) for i in range(len(ds)))
    assert shapes == [(6, 25, 3, 90, 160), (25, 3, 90, 160)]
    assert "cameras" not in ds[[e.get("cameras") for e in ds.entries].index(None)]
    with pytest.raises((RuntimeError, KeyError)):  # the default collate needs one kind
        next(iter(torch.utils.data.DataLoader(ds, batch_size=2)))
    with pytest.raises(ValueError, match=r"pair scene-0001_0006 is a single-camera pair"):
        PairDataset(out / "manifest.jsonl", cameras=["CAM_FRONT"])
    with pytest.raises(ValueError, match=r"pair scene-0001_0000 has no camera CAM_X \(its"):
        PairDataset(rig, cameras=["CAM_FRONT", "CAM_X"])
    with pytest.raises(ValueError, match=r"listed twice"):
        PairDataset(rig, cameras=["CAM_BACK", "CAM_BACK"])
    with pytest.raises(TypeError, match=r"argument 'cameras' must be None or a list of str"):
        PairDataset(rig, cameras="CAM_BACK")


def test_damaged_views_are_refused_naming_the_file(rig_pairs, tmp_path):
    require("torch")
    cv2 = require("cv2")
    from geodrive.torch import PairDataset
    rig, _ = rig_pairs
    src = os.path.dirname(rig)
    entry = geodrive.read_manifest(rig)[0]

    def copy(name):
        root = tmp_path / name
        shutil.copytree(src, root)
        return root, root / entry["pair_dir"]

    # A view video with 10 frames beside 25-frame ones: ReadPair does not
    # decode videos; PairDataset checks every view's frame count.
    root, pair = copy("short")
    frames = geodrive.read_video(str(pair / "cond_CAM_BACK.mp4"))[:10]
    w = cv2.VideoWriter(str(pair / "short.mp4"), cv2.VideoWriter_fourcc(*"mp4v"),
                        10, (frames.shape[2], frames.shape[1]))
    for f in frames:
        w.write(cv2.cvtColor(f, cv2.COLOR_RGB2BGR))
    w.release()
    os.replace(pair / "short.mp4", pair / "cond_CAM_BACK.mp4")
    with pytest.raises(ValueError, match=r"cond_CAM_BACK\.mp4: CAM_BACK video has 10 "
                                         r"frames, meta.json lists 25"):
        PairDataset(root / "manifest.jsonl")[0]
    # Not read when not selected.
    assert PairDataset(root / "manifest.jsonl", cameras=["CAM_FRONT"])[0]["cond"].shape[1] == 25

    # A view video of another size.
    root, pair = copy("size")
    frames = geodrive.read_video(str(pair / "gt_CAM_FRONT_LEFT.mp4"))
    w = cv2.VideoWriter(str(pair / "small.mp4"), cv2.VideoWriter_fourcc(*"mp4v"),
                        10, (80, 48))
    for f in frames:
        w.write(cv2.resize(cv2.cvtColor(f, cv2.COLOR_RGB2BGR), (80, 48)))
    w.release()
    os.replace(pair / "small.mp4", pair / "gt_CAM_FRONT_LEFT.mp4")
    with pytest.raises(ValueError, match=r"gt_CAM_FRONT_LEFT\.mp4: CAM_FRONT_LEFT video is "
                                         r"48x80 \(HxW\), meta.json's intrinsics 90x160"):
        PairDataset(root / "manifest.jsonl")[0]

    # A missing view video: ReadPair's check, naming the file.
    root, pair = copy("missing")
    os.remove(pair / "gt_CAM_BACK_RIGHT.mp4")
    with pytest.raises(ValueError, match=r"gt_CAM_BACK_RIGHT\.mp4"):
        PairDataset(root / "manifest.jsonl")[0]

    # A manifest line whose cameras are not meta.json's views.
    root, pair = copy("cameras")
    line = dict(entry, cameras=SIX[:3])
    (root / "manifest.jsonl").write_text(json.dumps(line) + "\n")
    # ReadPair's check (C++), naming the manifest and the pair.
    with pytest.raises(ValueError, match=r"manifest\.jsonl: pair 'scene-0001_0000' lists other "
                                         r"cameras than its meta\.json views"):
        PairDataset(root / "manifest.jsonl")[0]
