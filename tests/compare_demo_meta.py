#!/usr/bin/python3
"""Compares two build-dataset output trees (tests/compare_demo_trees.sh): every file byte for byte
except report.html (run timings) and meta.json, which is compared as JSON after dropping the keys
that newer revisions add or change on purpose:
  frame_source, frame_interval_s                   the clip frame source
  quality.reprojection_rms_px[_before|_after]      no -1 "not computed" sentinel
  quality.scale_inlier_fraction when -1 / absent   no -1 sentinel either
  file_sizes                                       verified resume
Everything else in meta.json (poses, intrinsics, scale, coverage, PSNR, options, files) must be
equal. Exit 0 when the trees agree, 1 listing the differences."""
import filecmp
import json
import os
import sys


def normalise(meta):
    meta.pop("frame_source", None)
    meta.pop("frame_interval_s", None)
    meta.pop("file_sizes", None)
    q = meta.get("quality", {})
    for k in ("reprojection_rms_px", "reprojection_rms_px_before", "reprojection_rms_px_after"):
        q.pop(k, None)
    if q.get("scale_inlier_fraction", -1) == -1:
        q.pop("scale_inlier_fraction", None)
    return meta


def main():
    a, b = sys.argv[1], sys.argv[2]
    diffs = []
    def listing(root):  # the lock file holds a pid: not an output
        return {os.path.relpath(os.path.join(d, f), root) for d, _, fs in os.walk(root)
                for f in fs if not f.startswith(".lock")}
    files_a, files_b = listing(a), listing(b)
    for rel in sorted(files_a ^ files_b):
        diffs.append(f"only in one tree: {rel}")
    for rel in sorted(files_a & files_b):
        if os.path.basename(rel) == "report.html":
            continue  # run timings
        pa, pb = os.path.join(a, rel), os.path.join(b, rel)
        if os.path.basename(rel) == "meta.json":
            if normalise(json.load(open(pa))) != normalise(json.load(open(pb))):
                diffs.append(f"meta differs: {rel}")
        elif not filecmp.cmp(pa, pb, shallow=False):
            diffs.append(f"bytes differ: {rel}")
    for d in diffs:
        print(d)
    n = len(files_a & files_b)
    print(f"{n} files compared, {len(diffs)} difference(s)")
    sys.exit(1 if diffs else 0)


if __name__ == "__main__":
    main()
