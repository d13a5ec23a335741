#!/usr/bin/env bash
# The Python module's overhead, in one run:
#  1. render: geodrive.render() of the bench_render workload (25 frames at
#     480x720 from 345,600 points, z-buffer r = 0; bench_render dumps its
#     scene) against the C++ benchmark's own time, 1 and 2 threads. The
#     Python figure is the whole call: argument checks, the cloud copied in,
#     the 25 frames rendered straight into NumPy arrays -- fresh ones (their
#     first-touch page faults included), or those of a previous result
#     (out=), as the C++ benchmark reuses its frames.
#  2. decoding a pair: geodrive.read_video (our FFmpeg reader) and
#     geodrive.torch.PairDataset.__getitem__ against OpenCV's VideoCapture in
#     Python (python3-opencv, frames converted to RGB) on the same files.
#
#   bash bench/python_vs_cpp.sh [BUILD_DIR] [MANIFEST]
# BUILD_DIR (default build) needs -DGEODRIVE_BUILD_BENCH=ON -DGEODRIVE_WITH_PYTHON=ON; MANIFEST a
# build's manifest.jsonl (default /tmp/geodrive_demo/pairs/manifest.jsonl, scripts/demo.sh).
set -euo pipefail
BUILD_DIR=${1:-build}
MANIFEST=${2:-/tmp/geodrive_demo/pairs/manifest.jsonl}
REPS=${REPS:-7}
TASKSET=${TASKSET:-}   # e.g. "taskset -c 1": one CPU for both (the 1-thread rows without migrations)
export GEODRIVE_BENCH_RENDER_DUMP=${GEODRIVE_BENCH_RENDER_DUMP:-/tmp/geodrive_bench_render}
mkdir -p "$GEODRIVE_BENCH_RENDER_DUMP"
echo "== machine: $(lscpu | grep -E '^Model name' | sed 's/  */ /g'), $(nproc) CPUs, load $(cut -d' ' -f1-3 /proc/loadavg)"
$TASKSET "$BUILD_DIR/bench/bench_render" --benchmark_filter='mode:0/' --benchmark_min_time=1 \
  --benchmark_repetitions="$REPS" --benchmark_report_aggregates_only=true \
  --benchmark_out="$GEODRIVE_BENCH_RENDER_DUMP/ours.json" --benchmark_out_format=json \
  2>/dev/null | grep -E "_median" || true
PYTHONPATH="$BUILD_DIR/python" $TASKSET /usr/bin/python3 - "$GEODRIVE_BENCH_RENDER_DUMP" "$REPS" "$MANIFEST" <<'PY'
import json, os, statistics, sys, time
import numpy as np
import geodrive

d, reps, manifest = sys.argv[1], int(sys.argv[2]), sys.argv[3]
cpp = {}
for b in json.load(open(os.path.join(d, 'ours.json')))['benchmarks']:
    if b.get('aggregate_name') == 'median':
        t = b['run_name'].split('/')[2]          # threads:T
        cpp[int(t.split(':')[1])] = b['real_time']
lines = open(os.path.join(d, 'cameras.txt')).read().split('\n')
w, h, fx, fy, cx, cy = (float(x) for x in lines[0].split())
K = np.array([[fx, 0, cx], [0, fy, cy], [0, 0, 1]])
poses = np.array([[float(x) for x in l.split()] for l in lines[1:] if l.strip()]).reshape(-1, 4, 4)
pts = np.fromfile(os.path.join(d, 'points.f32'), np.float32).reshape(-1, 3)
cols = np.fromfile(os.path.join(d, 'colors.u8'), np.uint8).reshape(-1, 3)
print(f'render: {len(pts)} points, {len(poses)} frames {int(w)}x{int(h)}')
for threads in (1, 2):
    c = cpp.get(threads, float('nan'))
    res = geodrive.render(pts, cols, K, poses, size=(int(h), int(w)), threads=threads)
    for label, out in (('fresh arrays', None), ('out= reused, as the C++ loop', res)):
        times = []
        for _ in range(reps):
            t = time.perf_counter()
            geodrive.render(pts, cols, K, poses, size=(int(h), int(w)), threads=threads, out=out)
            times.append((time.perf_counter() - t) * 1e3)
        py = statistics.median(times)
        print(f'  threads {threads}: C++ benchmark {c:.1f} ms; geodrive.render, {label}: '
              f'{py:.1f} ms ({(py / c - 1) * 100:+.1f} %)')

import cv2
from geodrive.torch import PairDataset
entry = geodrive.read_manifest(manifest)[0]
pair = os.path.join(os.path.dirname(manifest), entry['pair_dir'])
paths = [os.path.join(pair, f) for f in ('gt.mp4', 'cond.mp4')]

def opencv(path):
    cap, frames = cv2.VideoCapture(path), []
    while True:
        ok, f = cap.read()
        if not ok:
            return np.stack(frames)
        frames.append(cv2.cvtColor(f, cv2.COLOR_BGR2RGB))

def median_ms(fn):
    fn()
    out = []
    for _ in range(reps):
        t = time.perf_counter()
        fn()
        out.append((time.perf_counter() - t) * 1e3)
    return statistics.median(out)

import geodrive.torch as gt_mod
ours = median_ms(lambda: [geodrive.read_video(p) for p in paths])
pair_ours = median_ms(lambda: list(gt_mod._pool().map(geodrive.read_video, paths)))
theirs = median_ms(lambda: [opencv(p) for p in paths])
ds = PairDataset(manifest)
item = median_ms(lambda: ds[0])
shape = geodrive.read_video(paths[0]).shape
print(f'decode a pair ({entry["clip_id"]}: gt.mp4 + cond.mp4, {shape[0]} frames {shape[2]}x{shape[1]} each), '
      f'OpenCV {cv2.__version__} with its default FFmpeg threads:')
print(f'  one after the other: geodrive.read_video {ours:.1f} ms, OpenCV VideoCapture + RGB {theirs:.1f} ms '
      f'({theirs / ours:.2f}x)')
print(f'  as PairDataset decodes (both videos at once): {pair_ours:.1f} ms ({theirs / pair_ours:.2f}x OpenCV); '
      f'PairDataset[0] with the [-1, 1] float tensors {item:.1f} ms')
PY
