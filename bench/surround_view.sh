#!/usr/bin/env bash
# Surround view against six single-camera runs: the same clips built once
# with `--cameras all` (one scene per clip, rendered into the six cameras)
# and six times with one camera each (`--cameras CAM_X`: that camera's own
# scene and pair), one worker thread. Prints per run the builder's worker
# CPU per clip by stage ("CPU per stage") and the process CPU (user + sys,
# table loading included), then the six-camera figure against the sum of
# the six single runs. docs/PERFORMANCE.md "Surround view".
#
#   bash bench/surround_view.sh GEODRIVE [DATAROOT] [VERSION] [FRAMES]
#
# DATAROOT defaults to a six-camera synthetic world made here
# (`geodrive synth --cameras all --scenes 1 --duration 4`, 1600x900, 4 clips
# of 25 frames at 12 Hz); for the real scene-0916 pass
# ../shared/data/real/nuscenes_scene0916 v1.0-mini-extract keyframes.
# Environment: GEOMETRY (default lidar, build-dataset's default), PRESET
# (default paper, likewise; GEOMETRY=lidar-dense PRESET=footprint for the dense rig),
# MAX_CLIPS (default 4), CORE (pin to this core, default none).
set -euo pipefail
if [[ $# -lt 1 ]]; then
  sed -n '2,18p' "$0" | sed 's/^# \{0,1\}//'
  exit 2
fi
GEODRIVE=$1
ROOT=${2:-}
VERSION=${3:-v1.0-mini}
FRAMES=${4:-all}
GEOMETRY=${GEOMETRY:-lidar}
PRESET=${PRESET:-paper}
MAX_CLIPS=${MAX_CLIPS:-4}
work=$(mktemp -d "${TMPDIR:-/tmp}/surround_view.XXXXXX")
trap 'rm -rf "$work"' EXIT
if [[ -z $ROOT ]]; then
  ROOT=$work/synth6
  "$GEODRIVE" synth --out "$ROOT" --scenes 1 --cameras all --duration 4 >/dev/null
fi
pin=()
[[ -n ${CORE:-} ]] && pin=(taskset -c "$CORE")

# One build; prints "<worker CPU s> <process CPU s> <clips>" and the stages.
run() {
  local name=$1 cams=$2 out=$work/out_$1
  local log=$work/$name.log
  /usr/bin/time -f "%U %S" -o "$work/$name.time" "${pin[@]}" "$GEODRIVE" build-dataset \
    --dataroot "$ROOT" --version "$VERSION" --frames "$FRAMES" --geometry "$GEOMETRY" \
    --preset "$PRESET" --cameras "$cams" --max-clips "$MAX_CLIPS" --threads 1 \
    --out "$out" >"$log" 2>&1
  local clips worker process
  clips=$(grep -o 'pairs built [0-9]*' "$log" | grep -o '[0-9]*$')
  worker=$(grep '^CPU per stage' "$log" | sed 's/.*threads): //' |
    awk '{ s = 0; for (i = 2; i <= NF; i += 2) s += $i; print s }')
  process=$(awk '{ print $1 + $2 }' "$work/$name.time")
  printf '%-16s clips %s  worker CPU/clip %.3f s  process CPU/clip %.3f s  | %s\n' \
    "$name" "$clips" "$(echo "$worker / $clips" | bc -l)" "$(echo "$process / $clips" | bc -l)" \
    "$(grep '^CPU per stage' "$log" | sed 's/.*threads): //')"
  echo "$worker $process $clips" >"$work/$name.sum"
}

run six all
single_worker=0
single_process=0
for cam in CAM_FRONT CAM_FRONT_LEFT CAM_FRONT_RIGHT CAM_BACK_LEFT CAM_BACK CAM_BACK_RIGHT; do
  run "$cam" "$cam"
  read -r w p c <"$work/$cam.sum"
  single_worker=$(echo "$single_worker + $w / $c" | bc -l)
  single_process=$(echo "$single_process + $p / $c" | bc -l)
done
read -r w p c <"$work/six.sum"
printf 'six cameras at once: worker %.3f s, process %.3f s per clip\n' \
  "$(echo "$w / $c" | bc -l)" "$(echo "$p / $c" | bc -l)"
printf 'six single runs:     worker %.3f s, process %.3f s per clip (sum)\n' \
  "$single_worker" "$single_process"
printf 'ratio (six at once / six single): worker %.2f, process %.2f\n' \
  "$(echo "($w / $c) / $single_worker" | bc -l)" "$(echo "($p / $c) / $single_process" | bc -l)"
