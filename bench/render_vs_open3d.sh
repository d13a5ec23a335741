#!/usr/bin/env bash
# Our z-buffer renderer against Open3D's CPU `project_to_rgbd_image` on the same
# points and cameras, in one run: bench_render (25 frames at 480x720 from a
# 345,600-point cloud, docs/PERFORMANCE.md "Renderer") writes its scene
# (GEODRIVE_BENCH_RENDER_DUMP) and times ours; then Debian's /usr/bin/python3
# (python3-open3d) renders the same 25 frames with
# o3d.t.geometry.PointCloud.project_to_rgbd_image (depth_scale 1, depth_max
# 100), with 1 and with 2 OpenMP threads, and the ratios Open3D / ours at the
# same thread count are printed. Both sides keep the cloud in memory between
# repetitions and time only the 25 projections; Open3D also allocates its
# output images per call, ours reuses them (RenderFramesInto). The same run
# also times BM_TrafficFloor25Frames (the bytes alone: the cloud read, the
# key buffer read and written, the outputs written, once a frame) and prints
# the time a renderer would need for 20x Open3D at each thread count.
#
#   bash bench/render_vs_open3d.sh [BUILD_DIR]     (default: build)
#
# Environment: REPS (ours: benchmark repetitions, median taken; Open3D: median
# of REPS timed runs after one warm-up; default 5), MODES (bench_render modes
# to time, default "0"; 1 = radius 1.5 px, 2 = soft have no Open3D
# counterpart and are printed for reference), GEODRIVE_BENCH_RENDER_DUMP (scene
# files; default /tmp/geodrive_bench_render), TASKSET (e.g. "taskset -c 0,1"),
# AVX2_ONLY=1 (for machines with AVX-512: also keep glibc's string functions and
# OpenCV's dispatch to AVX2; our renderer has no AVX-512 code, its AVX2 kernels
# are chosen at run time), ROUNDS (default 1: run ours and Open3D that many
# times, alternating, and end with the median over the rounds of each side and
# of each ratio; on a shared machine one round's ratio can be off by 20 % or more).
#
# Besides the ratios at equal thread counts, each round prints ours on one
# thread against Open3D on two threads (Open3D's default on the 2-vCPU
# machines of docs/PERFORMANCE.md).
set -euo pipefail

BUILD_DIR=${1:-build}
BENCH="$BUILD_DIR/bench/bench_render"
REPS=${REPS:-5}
MODES=${MODES:-0}
TASKSET=${TASKSET:-}
export GEODRIVE_BENCH_RENDER_DUMP=${GEODRIVE_BENCH_RENDER_DUMP:-/tmp/geodrive_bench_render}
if [[ ! -x "$BENCH" ]]; then
  echo "no $BENCH: configure with -DGEODRIVE_BUILD_BENCH=ON and build bench_render" >&2
  exit 2
fi
if ! /usr/bin/python3 -c "import open3d" 2>/dev/null; then
  echo "/usr/bin/python3 has no open3d: apt-get install python3-open3d" >&2
  exit 2
fi
mkdir -p "$GEODRIVE_BENCH_RENDER_DUMP"
if [[ "${AVX2_ONLY:-0}" == 1 ]]; then
  export GLIBC_TUNABLES=glibc.cpu.hwcaps=-AVX512F,-AVX512VL,-AVX512BW,-AVX512DQ,-AVX512CD
  export OPENCV_CPU_DISABLE=AVX512_COMMON,AVX512_SKX,AVX512_KNL,AVX512_KNM,AVX512_CNL,AVX512_CLX,AVX512_ICL
fi

echo "== machine"
lscpu | grep -E "^Model name|^CPU\(s\)" || true
echo "flags: $(grep -o -w -E 'avx2|avx512f|avx512bw|avx512vl' /proc/cpuinfo | sort -u | tr '\n' ' ')"
echo "load: $(cut -d' ' -f1-3 /proc/loadavg)${GLIBC_TUNABLES:+; AVX2 only: $GLIBC_TUNABLES}"

ROUNDS=${ROUNDS:-1}
filter="mode:($(echo "$MODES" | tr ' ' '|'))/|TrafficFloor"
DUMP=$GEODRIVE_BENCH_RENDER_DUMP
rm -f "$DUMP"/round_*.json

for ((round = 1; round <= ROUNDS; round++)); do
if ((ROUNDS > 1)); then echo "== round $round of $ROUNDS ($(date -u +%H:%M:%S) UTC)"; fi
echo "== ours ($BENCH, median of $REPS; wall and CPU time of the process)"
$TASKSET "$BENCH" --benchmark_filter="$filter" --benchmark_min_time=1 \
  --benchmark_repetitions="$REPS" --benchmark_report_aggregates_only=true \
  --benchmark_out="$DUMP/ours.json" --benchmark_out_format=json \
  2>/dev/null | grep -E "_median|^BM_.*(mode|threads)" | grep -v -E "_(mean|stddev|cv)" \
  | { if ((REPS > 1)); then grep "_median"; else cat; fi; } || true

echo "== Open3D (median of $REPS), and the ratio Open3D / ours (wall time, same thread count)"
for threads in 1 2; do
  OMP_NUM_THREADS=$threads $TASKSET /usr/bin/python3 - "$DUMP" "$REPS" "$threads" "$round" <<'EOF'
import json, os, statistics, sys, time
import numpy as np
import open3d as o3d

d, reps, threads, rnd = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), sys.argv[4]
ours = {}
# The medians of the repetitions; with REPS=1 Google Benchmark writes no
# aggregates, and the single run is the figure.
benches = json.load(open(os.path.join(d, 'ours.json')))['benchmarks']
want = 'aggregate' if any(b.get('run_type') == 'aggregate' for b in benches) else 'iteration'
for b in benches:
    if b.get('run_type') == want and (want == 'iteration' or b.get('aggregate_name') == 'median'):
        # run_name: BM_Render25Frames/mode:M/threads:T/min_time:.../...
        # or BM_TrafficFloor25Frames/threads:T/...
        parts = b['run_name'].split('/')
        if parts[0] == 'BM_TrafficFloor25Frames':
            ours[f'floor/{parts[1]}'] = b['real_time']
            continue
        m, t = parts[1:3]
        ours[f'{m}/{t}'] = (b['real_time'], b['cpu_time'], b.get('mean_coverage', 0))

lines = open(os.path.join(d, 'cameras.txt')).read().split('\n')
w, h, fx, fy, cx, cy = (float(x) for x in lines[0].split())
w, h = int(w), int(h)
poses = [np.array([float(x) for x in l.split()]).reshape(4, 4) for l in lines[1:] if l.strip()]
pts = np.fromfile(os.path.join(d, 'points.f32'), dtype=np.float32).reshape(-1, 3)
cols = np.fromfile(os.path.join(d, 'colors.u8'), dtype=np.uint8).reshape(-1, 3)
pcd = o3d.t.geometry.PointCloud(o3d.core.Tensor(pts))
pcd.point.colors = o3d.core.Tensor(cols.astype(np.float32) / 255.0)
K = o3d.core.Tensor([[fx, 0, cx], [0, fy, cy], [0, 0, 1]], dtype=o3d.core.Dtype.Float64)
exts = [o3d.core.Tensor(p, dtype=o3d.core.Dtype.Float64) for p in poses]

def run():
    return [pcd.project_to_rgbd_image(w, h, K, e, depth_scale=1.0, depth_max=100.0) for e in exts]

frames = run()  # warm-up; also the coverage check below
coverage = np.mean([(np.asarray(f.depth) > 0).mean() for f in frames])
walls, cpus = [], []
for _ in range(reps):
    t, c = time.perf_counter(), time.process_time()
    run()
    walls.append(time.perf_counter() - t)
    cpus.append(time.process_time() - c)
wall, cpu = statistics.median(walls) * 1e3, statistics.median(cpus) * 1e3
key = f'mode:0/threads:{threads}'
if threads == 1:
    print(f'open3d {o3d.__version__}, {len(pts)} points, {len(exts)} frames {w}x{h}')
    print(f'{"threads":<8}{"ours ms (cpu)":>18}{"open3d ms (cpu)":>20}{"open3d/ours":>13}'
          f'{"coverage ours":>15}{"open3d":>8}{"bytes-only ms":>15}{"20x needs ms":>14}')
floor = ours.get(f'floor/threads:{threads}')
floor_text = f'{floor:>15.1f}' if floor else f'{"-":>15}'
if key in ours:
    ow, oc, ocov = ours[key]
    print(f'{threads:<8}{ow:>10.1f} ({oc:5.1f}){wall:>12.1f} ({cpu:5.0f}){wall / ow:>12.1f}x'
          f'{ocov:>15.3f}{coverage:>8.3f}{floor_text}{wall / 20:>14.1f}')
else:
    print(f'{threads:<8}{"-":>18}{wall:>12.1f} ({cpu:5.0f})')
# This round's figures, for the pairing line and the medians over rounds.
json.dump({'open3d_ms': wall, 'ours_ms': ours.get(key, (None,))[0], 'floor_ms': floor},
          open(os.path.join(d, f'round_{rnd}_threads_{threads}.json'), 'w'))
EOF
done
/usr/bin/python3 - "$DUMP" "$round" <<'EOF'
import json, os, sys
d, rnd = sys.argv[1], sys.argv[2]
one = json.load(open(os.path.join(d, f'round_{rnd}_threads_1.json')))
two = json.load(open(os.path.join(d, f'round_{rnd}_threads_2.json')))
if one['ours_ms']:
    print(f"ours on 1 thread against Open3D's default: ours {one['ours_ms']:.1f} ms, Open3D on 2 threads "
          f"{two['open3d_ms']:.1f} ms: {two['open3d_ms'] / one['ours_ms']:.1f}x "
          f"(20x needs {two['open3d_ms'] / 20:.1f} ms)")
EOF
done

if ((ROUNDS > 1)); then
  echo "== medians over $ROUNDS rounds (each round's figure is itself a median of $REPS)"
  /usr/bin/python3 - "$DUMP" "$ROUNDS" <<'EOF'
import json, os, statistics, sys
d, rounds = sys.argv[1], int(sys.argv[2])
r = {t: [json.load(open(os.path.join(d, f'round_{i}_threads_{t}.json')))
         for i in range(1, rounds + 1)] for t in (1, 2)}
med = statistics.median
def col(t, k):
    return [x[k] for x in r[t]]
if all(col(1, 'ours_ms')) and all(col(2, 'ours_ms')):
    for t in (1, 2):
        ratios = [o / u for o, u in zip(col(t, 'open3d_ms'), col(t, 'ours_ms'))]
        print(f'{t} thread(s) each: ours {med(col(t, "ours_ms")):.1f} ms, Open3D '
              f'{med(col(t, "open3d_ms")):.1f} ms; ratio median {med(ratios):.1f}x '
              f'(rounds: {", ".join(f"{x:.1f}" for x in ratios)})')
    pairing = [o / u for o, u in zip(col(2, 'open3d_ms'), col(1, 'ours_ms'))]
    print(f"ours on 1 thread against Open3D on 2: median {med(pairing):.1f}x "
          f'(rounds: {", ".join(f"{x:.1f}" for x in pairing)})')
    if all(col(1, 'floor_ms')):
        print(f'bytes only: {med(col(1, "floor_ms")):.1f} ms on 1 thread, '
              f'{med(col(2, "floor_ms")):.1f} ms on 2')
EOF
fi
