#!/usr/bin/env bash
# The 3D-editing overhead of docs/PERFORMANCE.md ("Dynamic editing"): runs
# BM_PlainRender and BM_Edit3d of bench_edit alternately ROUNDS times (short
# runs, so drifts in a shared machine's speed hit both alike) and prints the medians
# and their ratio, for one thread (pinned to CPU 1) and for two threads.
#
#   bench/edit_overhead.sh [BENCH_EDIT_BINARY] [ROUNDS]
#
# GEODRIVE_MALLOC_DEFAULTS=1 in the environment measures with glibc's default
# allocator policy instead of the geodrive binaries' one (geometry/memory.h).
set -euo pipefail
bin=${1:-build/bench/bench_edit}
rounds=${2:-9}
[[ -x "$bin" ]] || { echo "edit_overhead.sh: $bin is not an executable (build bench_edit first)" >&2; exit 2; }

median() { sort -g | awk '{v[NR]=$1} END {print (NR % 2) ? v[(NR+1)/2] : (v[NR/2]+v[NR/2+1])/2}'; }
run() {  # threads benchmark -> ms
  local t=$1 name=$2 pre=()
  if [[ $t == 1 ]]; then pre=(env OMP_NUM_THREADS=1 taskset -c 1); fi
  "${pre[@]}" "$bin" --benchmark_filter="^${name}/threads:${t}/" --benchmark_min_time=0.5 \
    --benchmark_format=csv 2>/dev/null | awk -F, '/^"BM_/ {print $3}'
}
for t in 1 2; do
  plain=() edit=()
  for ((r = 0; r < rounds; ++r)); do
    plain+=("$(run "$t" BM_PlainRender)")
    edit+=("$(run "$t" BM_Edit3d)")
  done
  p=$(printf '%s\n' "${plain[@]}" | median)
  e=$(printf '%s\n' "${edit[@]}" | median)
  printf 'threads=%s  plain: %s\n            edit3d: %s\n' "$t" "${plain[*]}" "${edit[*]}"
  awk -v p="$p" -v e="$e" -v t="$t" 'BEGIN {printf "threads=%s  median plain %.2f ms, edit3d %.2f ms, ratio %.3f\n", t, p, e, e / p}'
done
