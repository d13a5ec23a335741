#!/usr/bin/env bash
# Checks that behaviour is unchanged across the clip -> scene seam: builds `geodrive` at a
# base revision in a git worktree, runs the demo's main job (scripts/demo.sh steps 1 and 3:
# `synth --scenes 2 --seed 7 --monst3r`, then `build-dataset`) with it and with this tree's
# binary, and compares the two output trees: the synthetic dataset byte for byte, every pair
# folder file, manifest.jsonl and failures.jsonl byte for byte, report.html left out (run timings)
# and meta.json as JSON without the fields that newer revisions add or change on purpose
# (tests/compare_demo_meta.py lists them). With --exact, meta.json is compared byte for byte too
# (true between 29169f5 and the seam itself: both write the same meta.json fields, without
# those tests/compare_demo_meta.py drops).
# Exit 0 when the trees agree, 1 with the differing files listed otherwise.
#
# Usage: bash tests/compare_demo_trees.sh [--exact] [OLD_REV [NEW_REV]]
#   OLD_REV  default 29169f5, the last commit before the seam
#   NEW_REV  default "." = this working tree's ./build/apps/geodrive (build it first), or a
#            revision to build in a worktree
# Environment: WORK_DIR (default /tmp/geodrive_compare_demo).
set -euo pipefail
cd "$(dirname "$0")/.."
exact=0
if [[ "${1:-}" == "--exact" ]]; then exact=1; shift; fi
old_rev=${1:-29169f5}
new_rev=${2:-.}
work=${WORK_DIR:-/tmp/geodrive_compare_demo}
mkdir -p "$work"

binary_at() {  # binary_at REV -> prints the path of geodrive built at REV
  local rev=$1
  if [[ "$rev" == "." ]]; then
    [[ -x build/apps/geodrive ]] || { echo "build ./build/apps/geodrive first" >&2; exit 2; }
    echo "$PWD/build/apps/geodrive"
    return
  fi
  local src="$work/src-$(git rev-parse --short "$rev")"
  if [[ ! -d "$src" ]]; then
    git worktree add --detach "$src" "$rev" > /dev/null 2>&1
  fi
  if [[ ! -x "$src/build/apps/geodrive" ]]; then
    cmake -S "$src" -B "$src/build" -G Ninja -DCMAKE_BUILD_TYPE=Release \
      -DGEODRIVE_BUILD_TESTS=OFF > "$work/cmake-$rev.log" 2>&1
    cmake --build "$src/build" --target geodrive > "$work/build-$rev.log" 2>&1
  fi
  echo "$src/build/apps/geodrive"
}

run() {  # run BINARY OUT
  rm -rf "$2"
  "$1" synth --out "$2/synth" --scenes 2 --seed 7 --monst3r > "$2.log" 2>&1
  "$1" build-dataset --dataroot "$2/synth" --version v1.0-mini --monst3r "$2/synth/monst3r" \
    --out "$2/pairs" --threads "$(nproc)" --quiet >> "$2.log" 2>&1
}

old_bin=$(binary_at "$old_rev")
new_bin=$(binary_at "$new_rev")
run "$old_bin" "$work/old"
run "$new_bin" "$work/new"
status=0
if [[ $exact -eq 1 ]]; then
  diff -r -q -x report.html -x '.lock*' "$work/old/pairs" "$work/new/pairs" || status=1
else
  /usr/bin/python3 tests/compare_demo_meta.py "$work/old/pairs" "$work/new/pairs" || status=1
fi
diff -r -q "$work/old/synth" "$work/new/synth" || status=1
files=$(find "$work/new/pairs" "$work/new/synth" -type f ! -name report.html ! -name '.lock*' | wc -l)
pairs=$(wc -l < "$work/new/pairs/manifest.jsonl")
if [[ $status -eq 0 ]]; then
  echo "identical$([[ $exact -eq 1 ]] && echo ' (byte-exact)'): $pairs pairs, $files files" \
    "(report.html aside): $old_rev vs $new_rev"
fi
exit $status
