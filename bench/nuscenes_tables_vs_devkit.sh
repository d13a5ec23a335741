#!/usr/bin/env bash
# Our nuScenes table loading against the nuScenes devkit's on the same tables,
# in one run: bench_nuscenes BM_Load (simdjson, all cores) and
# bench/nuscenes_devkit_tables.py (the devkit 1.2.0 loading code: json.load
# per table + __make_reverse_index__, with Debian's /usr/bin/python3) at
# v1.0-mini size (10 scenes) and v1.0-trainval size (850 scenes), then a table
# with wall time, CPU time (all threads), peak RSS and the ratios. Figures:
# docs/PERFORMANCE.md, "nuScenes reader".
#
#   bash bench/nuscenes_tables_vs_devkit.sh [BUILD_DIR]     (default: build)
#
# Environment: GEODRIVE_BENCH_DIR (tables; default /tmp/geodrive_bench_nuscenes,
# 1.95 GB at 850 scenes, generated on first use), SIZES (default "10 850"),
# REPS (ours: repetitions, best wall taken; devkit: best of REPS loads at
# mini size, one load at trainval size -- it needs ~10 GB; default 3).
# Each size runs in its own processes so the peak RSS is that size's.
set -euo pipefail

BUILD_DIR=${1:-build}
BENCH="$BUILD_DIR/bench/bench_nuscenes"
HERE=$(cd "$(dirname "$0")" && pwd)
export GEODRIVE_BENCH_DIR=${GEODRIVE_BENCH_DIR:-/tmp/geodrive_bench_nuscenes}
SIZES=${SIZES:-"10 850"}
REPS=${REPS:-3}
if [[ ! -x "$BENCH" ]]; then
  echo "no $BENCH: configure with -DGEODRIVE_BUILD_BENCH=ON and build bench_nuscenes" >&2
  exit 2
fi
OUT=$(mktemp -d)
trap 'rm -rf "$OUT"' EXIT

echo "== machine"
lscpu | grep -E "^Model name|^CPU\(s\)" || true
echo "load: $(cut -d' ' -f1-3 /proc/loadavg)"

for n in $SIZES; do
  root="$GEODRIVE_BENCH_DIR/scenes_$n"
  if [[ ! -f "$root/done" ]]; then  # generate the tables outside the measured runs
    "$BENCH" --benchmark_filter="BM_Load/$n/0/" > /dev/null
  fi
  cat "$root"/v1.0-bench/*.json > /dev/null  # both read from the page cache
  /usr/bin/time -v -o "$OUT/ours_$n.time" "$BENCH" --benchmark_filter="BM_Load/$n/0/" \
    --benchmark_repetitions="$REPS" --benchmark_out="$OUT/ours_$n.json" \
    --benchmark_out_format=json > /dev/null
  devkit_reps=$REPS
  [[ $n -gt 100 ]] && devkit_reps=1
  /usr/bin/time -v -o "$OUT/devkit_$n.time" /usr/bin/python3 "$HERE/nuscenes_devkit_tables.py" \
    "$root" v1.0-bench "$devkit_reps" > "$OUT/devkit_$n.json"
done

echo "== ours (bench_nuscenes BM_Load/<scenes>/0, best of $REPS) vs the devkit's loading code"
/usr/bin/python3 - "$OUT" "$SIZES" <<'EOF'
import json, os, re, sys

out, sizes = sys.argv[1], sys.argv[2].split()


def peak_rss_mb(path):
    text = open(path).read()
    return int(re.search(r'Maximum resident set size \(kbytes\): (\d+)', text).group(1)) / 1024


print(f'{"tables":<16}{"sample_data":>12}{"JSON MB":>9}  {"ours wall / CPU s":>18}{"RSS MB":>8}'
      f'  {"devkit wall / CPU s":>20}{"RSS MB":>8}  {"ratio wall":>10}{"ratio CPU":>10}')
for n in sizes:
    runs = [b for b in json.load(open(os.path.join(out, f'ours_{n}.json')))['benchmarks']
            if b.get('run_type') == 'iteration']
    best = min(runs, key=lambda b: b['real_time'])
    wall, cpu = best['real_time'] / 1e3, best['cpu_time'] / 1e3
    dev = json.loads(open(os.path.join(out, f'devkit_{n}.json')).read())
    assert dev['sample_data'] == int(best['sample_data']), (dev, best)
    name = 'v1.0-mini size' if int(n) <= 10 else 'trainval size'
    print(f'{name:<16}{dev["sample_data"]:>12,}{best["MB"]:>9.1f}  {wall:>8.3f} / {cpu:<7.3f}'
          f'{peak_rss_mb(os.path.join(out, f"ours_{n}.time")):>8.0f}  {dev["wall_s"]:>9.3f} / '
          f'{dev["cpu_s"]:<8.3f}{peak_rss_mb(os.path.join(out, f"devkit_{n}.time")):>8.0f}  '
          f'{dev["wall_s"] / wall:>9.1f}x{dev["cpu_s"] / cpu:>9.1f}x')
EOF
