#!/usr/bin/env bash
# Our depth completion (geometry/depth_completion.h) against IP-Basic's
# published pipeline in Python + OpenCV on the same real sparse depth images,
# in one run: bench_depth_completion (nuScenes scene-0916, clip
# scene-0916_0006_kf, frame 0, causal window, at 800x450 and 1600x900) writes
# its inputs and times ours; /usr/bin/python3 bench/ip_basic_peer.py times the
# peer on them. One core each (OpenCV's pool at one thread, OMP_NUM_THREADS=1),
# CPU time.
#
#   bash bench/depth_completion_vs_ip_basic.sh [BUILD_DIR]   (default: build)
set -euo pipefail
BUILD_DIR=${1:-build}
DUMP=${GEODRIVE_BENCH_SPARSE_DUMP:-/tmp/geodrive_bench_sparse}
mkdir -p "$DUMP"
export GEODRIVE_BENCH_SPARSE_DUMP=$DUMP OMP_NUM_THREADS=1
"$BUILD_DIR/bench/bench_depth_completion" --benchmark_repetitions=5 \
  --benchmark_report_aggregates_only=true --benchmark_min_time=0.5 2>&1 |
  grep -E "median|Benchmark"
/usr/bin/python3 "$(dirname "$0")/ip_basic_peer.py" "$DUMP" 10
