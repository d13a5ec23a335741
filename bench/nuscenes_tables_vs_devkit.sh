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
# bench_nuscenes applies the allocator policy of the geodrive binary
# (geometry/util/memory.h); GEODRIVE_MALLOC_DEFAULTS=1 runs it with glibc's
# defaults. REPS=1 measures each side's first load in a fresh process.
# ROUNDS (default 1): run ours and the devkit that many times, alternating,
# each in fresh processes, and add a line with the median over the rounds of
# each side's best. On a shared machine a fresh python3 process's best-of-10
# load of the mini-size tables came out 0.21 s in some processes and
# 0.33-0.42 s in others within one quiet minute, so one round's ratio can be
# off by 1.7x either way; use ROUNDS=5 or more for a figure.
set -euo pipefail

BUILD_DIR=${1:-build}
BENCH="$BUILD_DIR/bench/bench_nuscenes"
HERE=$(cd "$(dirname "$0")" && pwd)
export GEODRIVE_BENCH_DIR=${GEODRIVE_BENCH_DIR:-/tmp/geodrive_bench_nuscenes}
SIZES=${SIZES:-"10 850"}
REPS=${REPS:-3}
ROUNDS=${ROUNDS:-1}
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
  devkit_reps=$REPS
  [[ $n -gt 100 ]] && devkit_reps=1
  for ((r = 1; r <= ROUNDS; ++r)); do
    /usr/bin/time -v -o "$OUT/ours_${n}_$r.time" "$BENCH" --benchmark_filter="BM_Load/$n/0/" \
      --benchmark_repetitions="$REPS" --benchmark_out="$OUT/ours_${n}_$r.json" \
      --benchmark_out_format=json > /dev/null
    /usr/bin/time -v -o "$OUT/devkit_${n}_$r.time" /usr/bin/python3 \
      "$HERE/nuscenes_devkit_tables.py" "$root" v1.0-bench "$devkit_reps" > "$OUT/devkit_${n}_$r.json"
  done
done

echo "== ours (bench_nuscenes BM_Load/<scenes>/0, best of $REPS) vs the devkit's loading code"
/usr/bin/python3 - "$OUT" "$SIZES" "$ROUNDS" <<'EOF'
import json, os, re, statistics, sys

out, sizes, rounds = sys.argv[1], sys.argv[2].split(), int(sys.argv[3])


def peak_rss_mb(path):
    text = open(path).read()
    return int(re.search(r'Maximum resident set size \(kbytes\): (\d+)', text).group(1)) / 1024


print(f'{"tables":<16}{"sample_data":>12}{"JSON MB":>9}  {"ours wall / CPU s":>18}{"RSS MB":>8}'
      f'  {"devkit wall / CPU s":>20}{"RSS MB":>8}  {"ratio wall":>10}{"ratio CPU":>10}')
for n in sizes:
    name = 'v1.0-mini size' if int(n) <= 10 else 'trainval size'
    rows = []
    for r in range(1, rounds + 1):
        runs = [b for b in json.load(open(os.path.join(out, f'ours_{n}_{r}.json')))['benchmarks']
                if b.get('run_type') == 'iteration']
        best = min(runs, key=lambda b: b['real_time'])
        dev = json.loads(open(os.path.join(out, f'devkit_{n}_{r}.json')).read())
        assert dev['sample_data'] == int(best['sample_data']), (dev, best)
        rows.append(dict(rows=dev['sample_data'], mb=best['MB'],
                         wall=best['real_time'] / 1e3, cpu=best['cpu_time'] / 1e3,
                         rss=peak_rss_mb(os.path.join(out, f'ours_{n}_{r}.time')),
                         dwall=dev['wall_s'], dcpu=dev['cpu_s'],
                         drss=peak_rss_mb(os.path.join(out, f'devkit_{n}_{r}.time'))))
    if rounds > 1:
        med = {k: statistics.median(x[k] for x in rows) for k in rows[0]}
        rows.append(med)
    for i, x in enumerate(rows):
        label = name if i < rounds else f'median of {rounds}'
        print(f'{label:<16}{int(x["rows"]):>12,}{x["mb"]:>9.1f}  {x["wall"]:>8.3f} / {x["cpu"]:<7.3f}'
              f'{x["rss"]:>8.0f}  {x["dwall"]:>9.3f} / {x["dcpu"]:<8.3f}{x["drss"]:>8.0f}  '
              f'{x["dwall"] / x["wall"]:>9.1f}x{x["dcpu"] / x["cpu"]:>9.1f}x')
EOF
