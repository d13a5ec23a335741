#!/usr/bin/python3
"""Names from data never become paths outside --out (geometry/util/names.h).

    hostile_names_test.py GEODRIVE_BINARY WORK_DIR

A synthetic nuScenes world whose scene names hold "..", "/", a leading dot,
quotes, control bytes and 300 characters (two scenes sharing one name), and
whose frame file names hold a quote and a leading dot, is built (`build-dataset --export geodrive-upstream`) and its clips written
(`clips`). Checks: nothing outside the output folders changed (the parent
folder listed, with sizes, before and after; a folder named `escaped` where
"../../escaped" would land is untouched), every scene is built exactly once
in a folder of its own directly under OUT/pairs, and the upstream meta.jsonl
is valid JSON holding the quoted file name. A frame file name with a ".."
component is refused first (exit 2, one line naming sample_data.json). Standard library only.
"""
import json
import os
import shutil
import subprocess
import sys

HOSTILE = ["../../escaped", "../../escaped", '.hid"den\x01/x\'y', "L" * 300]


def listing(root, skip):
    out = {}
    for d, dirs, files in os.walk(root):
        dirs[:] = sorted(x for x in dirs if os.path.join(d, x) not in skip)
        for name in dirs + files:
            p = os.path.join(d, name)
            st = os.lstat(p)
            # A folder's own mtime moves when OUT is created in it: compare
            # folders by their entries (listed), files by size and mtime.
            mtime = None if os.path.isdir(p) else st.st_mtime_ns
            out[os.path.relpath(p, root)] = (st.st_mode, st.st_size if mtime else 0, mtime)
    return out


def run(args):
    r = subprocess.run(args, capture_output=True, text=True, timeout=600)
    print("$", " ".join(args[:2]), "->", r.returncode)
    if r.stderr.strip():
        print(r.stderr.strip()[-2000:])
    return r


def main():
    geodrive, work = sys.argv[1], os.path.abspath(sys.argv[2])
    shutil.rmtree(work, ignore_errors=True)
    # work/a/b/ holds the outputs: "../../escaped" from OUT/pairs would be
    # work/a/b/escaped, from OUT/pairs/<x> work/a/b/out/escaped.
    parent = os.path.join(work, "a", "b")
    os.makedirs(os.path.join(parent, "escaped"))
    with open(os.path.join(parent, "escaped", "keep.txt"), "w") as f:
        f.write("must survive\n")
    data = os.path.join(work, "synth")
    r = run([geodrive, "synth", "--out", data, "--scenes", "4", "--seed", "3",
             "--size", "180x320", "--duration", "3"])
    assert r.returncode == 0
    tables = os.path.join(data, "v1.0-mini")
    scenes = json.load(open(os.path.join(tables, "scene.json")))
    for s, name in zip(scenes, HOSTILE):
        s["name"] = name
    json.dump(scenes, open(os.path.join(tables, "scene.json"), "w"))
    # Hostile frame file names: a quote and a leading dot, a ".." component.
    sd = json.load(open(os.path.join(tables, "sample_data.json")))
    front = sorted((x for x in sd if "CAM_FRONT/" in x["filename"]),
                   key=lambda x: x["timestamp"])
    renames = {0: 'samples/CAM_FRONT/.q"uo\'te.jpg',
               1: "samples/CAM_FRONT/../CAM_FRONT/dotdot.jpg"}
    quoted = None
    for i, new in renames.items():
        old = front[i]["filename"]
        os.rename(os.path.join(data, old), os.path.join(data, new))
        front[i]["filename"] = new
        quoted = quoted or new
    json.dump(sd, open(os.path.join(tables, "sample_data.json"), "w"))

    out = os.path.join(parent, "out")
    clips = os.path.join(parent, "clips")
    before = listing(work, {out, clips})

    build = [geodrive, "build-dataset", "--dataroot", data, "--geometry", "lidar",
             "--clip-frames", "8", "--stride", "40", "--size", "96x160",
             "--export", "geodrive-upstream", "--threads", "2", "--out", out]
    # A file name climbing out of the dataroot is refused, naming the table.
    r = run(build)
    assert r.returncode == 2, r.returncode
    assert "sample_data.json" in r.stderr and "'..'" in r.stderr, r.stderr
    assert len(r.stderr.strip().splitlines()) == 1
    # Refused before anything is written: the output folder was not made.
    assert not os.path.exists(out), out
    os.rename(os.path.join(data, renames[1]),
              os.path.join(data, "samples/CAM_FRONT/dotdot.jpg"))
    front[1]["filename"] = "samples/CAM_FRONT/dotdot.jpg"
    json.dump(sd, open(os.path.join(tables, "sample_data.json"), "w"))
    before = listing(work, {out, clips})

    r = run(build)
    assert r.returncode == 0, r.returncode
    r = run([geodrive, "clips", "--dataroot", data, "--clip-frames", "8",
             "--stride", "40", "--out", clips])
    assert r.returncode == 0, r.returncode

    after = listing(work, {out, clips})
    changed = sorted(k for k in set(before) | set(after) if before.get(k) != after.get(k))
    assert not changed, "changed outside the output folders: %s" % changed
    assert open(os.path.join(parent, "escaped", "keep.txt")).read() == "must survive\n"

    lines = [json.loads(l) for l in open(os.path.join(out, "manifest.jsonl"))]
    ids = [e["clip_id"] for e in lines]
    print("clip ids:", [i[:60] for i in ids])
    assert len(ids) == len(set(ids)) == len(HOSTILE), ids
    assert sorted(e["scene"] for e in lines) == sorted(HOSTILE)
    pair_dirs = sorted(os.listdir(os.path.join(out, "pairs")))
    assert sorted(pair_dirs) == sorted(ids), (pair_dirs, ids)
    for i in ids:
        assert "/" not in i and not i.startswith(".") and len(i) < 255
        assert os.path.isfile(os.path.join(out, "pairs", i, "meta.json"))
    up = [json.loads(l) for l in open(os.path.join(out, "geodrive_upstream", "meta.jsonl"))]
    assert len(up) == len(HOSTILE)
    assert any(quoted in u["gt_frames"] for u in up), "quoted file name kept"
    written = sorted(d for d in os.listdir(clips) if os.path.isdir(os.path.join(clips, d)))
    assert written == sorted(ids), (written, ids)
    assert [json.loads(l)["clip_id"] for l in open(os.path.join(clips, "clips.jsonl"))]
    print("ok: %d hostile scenes built once each, nothing outside the outputs changed"
          % len(ids))


if __name__ == "__main__":
    main()
