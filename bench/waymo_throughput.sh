#!/usr/bin/env bash
# Waymo beside nuScenes through the same builder: the synthetic world written
# in both formats (`geodrive synth`, the same scene, each format's own camera
# size: nuScenes 1600x900 at 12 Hz, Waymo 1920x1280 at 10 Hz), then
#   - records parsed per second: `geodrive info` over the Waymo segment (every
#     Frame proto with its five JPEGs and range image parsed, no decode);
#   - frames read per second: the builder's "gt" stage (decode, Waymo's
#     undistortion, resize to 720x480) over its frames;
#   - pairs per core-hour: `build-dataset --geometry lidar --threads 1`, the
#     worker CPU per pair (all stages), 3600 / that.
# docs/PERFORMANCE.md "Waymo".
#
#   bash bench/waymo_throughput.sh GEODRIVE [SECONDS]
#
# SECONDS: scene length (default 6: 60 Waymo frames, 72 nuScenes frames).
set -euo pipefail
if [[ $# -lt 1 ]]; then
  sed -n '2,15p' "$0" | sed 's/^# \{0,1\}//'
  exit 2
fi
GEODRIVE=$1
SECONDS_LONG=${2:-6}
work=$(mktemp -d "${TMPDIR:-/tmp}/waymo_bench.XXXXXX")
trap 'rm -rf "$work"' EXIT
"$GEODRIVE" synth --out "$work/nuscenes" --scenes 1 --duration "$SECONDS_LONG" >/dev/null
"$GEODRIVE" synth --format waymo --out "$work/waymo" --scenes 1 \
  --duration "$SECONDS_LONG" >/dev/null
segment=$(ls "$work"/waymo/*.tfrecord)
frames=$(awk -v s="$SECONDS_LONG" 'BEGIN { print int(10 * s + 1e-9) }')
/usr/bin/time -f "%e %U %S" -o "$work/info.time" "$GEODRIVE" info "$segment" >/dev/null
read -r _ user sys <"$work/info.time"
printf 'Waymo records parsed: %d frames (%.1f MB) in %.2f s CPU: %.1f frames/s\n' "$frames" \
  "$(echo "$(stat -c %s "$segment") / 1000000" | bc -l)" "$(echo "$user + $sys" | bc -l)" \
  "$(echo "$frames / ($user + $sys)" | bc -l)"

# One build; prints frames/s of the gt stage and pairs per core-hour.
build() {
  local name=$1 root=$2
  "$GEODRIVE" build-dataset --dataroot "$root" --geometry lidar --threads 1 \
    --out "$work/out_$name" >"$work/$name.log" 2>&1
  local pairs stages gt total
  pairs=$(grep -o 'pairs built [0-9]*' "$work/$name.log" | grep -o '[0-9]*$')
  stages=$(grep '^CPU per stage' "$work/$name.log" | sed 's/.*threads): //')
  gt=$(awk '{ for (i = 1; i < NF; i += 2) if ($i == "gt") print $(i + 1) }' <<<"$stages")
  total=$(awk '{ s = 0; for (i = 2; i <= NF; i += 2) s += $i; print s }' <<<"$stages")
  printf '%-9s %d pairs of 25 frames: frames read %.1f/s (gt stage %.2f s CPU), %.2f s CPU per pair = %.0f pairs per core-hour | %s\n' \
    "$name" "$pairs" "$(echo "25 * $pairs / $gt" | bc -l)" "$gt" \
    "$(echo "$total / $pairs" | bc -l)" "$(echo "3600 * $pairs / $total" | bc -l)" "$stages"
}
build nuscenes "$work/nuscenes"
build waymo "$work/waymo"
