#!/usr/bin/env bash
# Re-checks "behaviour is unchanged" (issue 17): builds `geodrive` at a base revision (default:
# 29169f5, the last commit before the clip -> scene seam) in a git worktree, runs the demo's main
# job (scripts/demo.sh steps 1 and 3: synth --scenes 2 --seed 7 --monst3r, then build-dataset)
# with the base binary and with this tree's binary, and compares the two output trees byte for
# byte: every pair folder file, manifest.jsonl and failures.jsonl. report.html is left out (it
# holds run timings). Exit 0 when identical, 1 with the differing files listed otherwise.
#
# Usage: bash tests/compare_demo_trees.sh [BASE_REV] [WORK_DIR]
#   NEW binary: ./build/apps/geodrive (build it first: cmake --build build --target geodrive)
set -euo pipefail
cd "$(dirname "$0")/.."
base_rev=${1:-29169f5}
work=${2:-/tmp/geodrive_compare_demo}
new_bin=$PWD/build/apps/geodrive
[[ -x "$new_bin" ]] || { echo "build ./build/apps/geodrive first" >&2; exit 2; }
mkdir -p "$work"
base_src="$work/base-src"
if [[ ! -d "$base_src" ]]; then
  git worktree add --detach "$base_src" "$base_rev" > /dev/null
fi
if [[ ! -x "$base_src/build/apps/geodrive" ]]; then
  cmake -S "$base_src" -B "$base_src/build" -G Ninja -DCMAKE_BUILD_TYPE=Release \
    -DGEODRIVE_BUILD_TESTS=OFF > /dev/null
  cmake --build "$base_src/build" --target geodrive
fi
run() {  # run BINARY OUT
  rm -rf "$2"
  "$1" synth --out "$2/synth" --scenes 2 --seed 7 --monst3r > "$2.log" 2>&1
  "$1" build-dataset --dataroot "$2/synth" --version v1.0-mini --monst3r "$2/synth/monst3r" \
    --out "$2/pairs" --threads "$(nproc)" --quiet >> "$2.log" 2>&1
}
run "$base_src/build/apps/geodrive" "$work/base"
run "$new_bin" "$work/new"
status=0
if ! diff -r -q -x report.html "$work/base/pairs" "$work/new/pairs"; then status=1; fi
if ! diff -r -q "$work/base/synth" "$work/new/synth" > /dev/null; then
  echo "synthetic datasets differ"; status=1
fi
files=$(find "$work/new/pairs" -type f ! -name report.html | wc -l)
pairs=$(wc -l < "$work/new/pairs/manifest.jsonl")
if [[ $status -eq 0 ]]; then
  echo "identical: $pairs pairs, $files files (report.html aside), base $base_rev vs $(git rev-parse --short HEAD)"
fi
exit $status
