#!/usr/bin/env bash
# `geodrive plan` speed: 100 lattice candidates of 25 frames on one clip,
# scored RUNS times on one core; prints per run the library's scoring time
# (the plan line's last figure: ground segmentation and every score) and the
# whole command's wall and CPU time, then the same with --visibility and with
# --visibility --videos 100. docs/PERFORMANCE.md "Planning". No peer: the
# upstream GeoDrive code has no planner, and no other tool scores candidates
# against a clip's boxes and LiDAR.
#
#   bash bench/plan.sh GEODRIVE [DATAROOT VERSION FRAMES CLIP] [RUNS]
#
# Defaults: a synthetic world made here (`geodrive synth --scenes 1`), its
# clip scene-0001_0000, 3 runs. For the real scene-0916:
#   bash bench/plan.sh build/apps/geodrive ../shared/data/real/nuscenes_scene0916 \
#     v1.0-mini-extract keyframes scene-0916_0000_kf
set -euo pipefail
if [[ $# -lt 1 ]]; then
  sed -n '2,15p' "$0" | sed 's/^# \{0,1\}//'
  exit 2
fi
GEODRIVE=$1
ROOT=${2:-}
VERSION=${3:-v1.0-mini}
FRAMES=${4:-all}
CLIP=${5:-scene-0001_0000}
RUNS=${6:-3}
work=$(mktemp -d "${TMPDIR:-/tmp}/plan_bench.XXXXXX")
trap 'rm -rf "$work"' EXIT
if [[ -z $ROOT ]]; then
  ROOT=$work/synth
  "$GEODRIVE" synth --out "$ROOT" --scenes 1 >/dev/null
fi

run() {
  local name=$1
  shift
  for ((i = 1; i <= RUNS; i++)); do
    rm -rf "$work/out"
    /usr/bin/time -f "%e %U %S" -o "$work/time" taskset -c 0 "$GEODRIVE" plan \
      --dataroot "$ROOT" --version "$VERSION" --frames "$FRAMES" --clip "$CLIP" \
      --sample 100 --no-logged --out "$work/out" "$@" >"$work/log" 2>&1 ||
      { cat "$work/log"; exit 1; }
    local scoring wall cpu
    scoring=$(grep -o '[0-9.]* s$' "$work/log" | head -1)
    read -r wall user sys <"$work/time"
    cpu=$(echo "$user + $sys" | bc -l)
    printf '%-28s run %d  scoring %-9s whole command %.2f s wall, %.2f s CPU\n' \
      "$name" "$i" "$scoring" "$wall" "$cpu"
  done
}

echo "$CLIP: 100 lattice candidates of the clip's frames, one core (taskset -c 0)"
run "scores"
run "--visibility" --visibility
run "--visibility --videos 100" --visibility --videos 100
