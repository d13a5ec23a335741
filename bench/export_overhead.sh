#!/usr/bin/env bash
# What each --export adds to build-dataset's time per clip: the same clips
# built without an export and with one format at a time, one worker thread,
# process CPU (user + sys) and the builder's worker CPU per clip compared.
# docs/PERFORMANCE.md "Exports".
#
#   bash bench/export_overhead.sh GEODRIVE [REAL_SCENE_ROOT]
#
# Two sets of clips, as each format's frame count allows:
#  - the real scene-0916 extract (REAL_SCENE_ROOT, default
#    ../shared/data/real/nuscenes_scene0916; 3 keyframe clips of 25 frames,
#    --geometry lidar): none, streetcrafter, drivestudio, geodrive-upstream;
#  - one synthetic 121-frame clip at 12 Hz (`geodrive synth --duration 10.5`,
#    1600x900, made here; --clip-frames 121): none, gen3c, rds-hq.
# Each format is measured twice against a build without export at the same
# --size: with the pair at the size the export writes (the trainer's:
# streetcrafter 320x576, drivestudio 900x1600, geodrive-upstream 576x1024,
# gen3c 704x1280; the pair's render then serves it), and at the default
# 480x720 (an export at another size renders the condition again).
# REPEAT rounds (default 3) run every build once in turn, and each build's
# least process CPU counts (a shared machine's noise only adds time).
# Environment: MAX_CLIPS (default 3, real scene), REPEAT, CORE (pin to this
# core).
set -euo pipefail
if [[ $# -lt 1 ]]; then
  sed -n '2,23p' "$0" | sed 's/^# \{0,1\}//'
  exit 2
fi
GEODRIVE=$1
REAL=${2:-../shared/data/real/nuscenes_scene0916}
MAX_CLIPS=${MAX_CLIPS:-3}
REPEAT=${REPEAT:-3}
work=$(mktemp -d "${TMPDIR:-/tmp}/export_overhead.XXXXXX")
trap 'rm -rf "$work"' EXIT
pin=()
[[ -n ${CORE:-} ]] && pin=(taskset -c "$CORE")

# run NAME EXPORT ARGS...: one build-dataset run; keeps in $work/NAME.sum
# "<process CPU s per clip> <worker CPU s per clip>" of the NAME run with the
# least process CPU so far.
run() {
  local name=$1 export=$2
  shift 2
  local log=$work/$name.log
  rm -rf "$work/out_$name"
  /usr/bin/time -f "%U %S" -o "$work/$name.time" "${pin[@]}" "$GEODRIVE" build-dataset \
    --threads 1 --export "$export" --out "$work/out_$name" "$@" >"$log" 2>&1
  # Removed and flushed before the next build: a GEN3C clip leaves 0.55 GB of
  # dirty pages whose write-back would otherwise run into the next build.
  rm -rf "$work/out_$name"
  sync
  local clips worker process p w
  clips=$(grep -o 'pairs built [0-9]*' "$log" | grep -o '[0-9]*$')
  worker=$(grep '^CPU per stage' "$log" | sed 's/.*threads): //' |
    awk '{ s = 0; for (i = 2; i <= NF; i += 2) s += $i; print s }')
  process=$(awk '{ print $1 + $2 }' "$work/$name.time")
  p=$(echo "$process / $clips" | bc -l)
  w=$(echo "$worker / $clips" | bc -l)
  if [[ ! -f $work/$name.sum ]] || (($(echo "$p < $(cut -d' ' -f1 "$work/$name.sum")" | bc -l))); then
    echo "$p $w" >"$work/$name.sum"
  fi
}

# rounds LABEL ARGS... -- EXPORT...: REPEAT rounds, each building with every
# EXPORT once in turn (a shared machine's drift then reaches them all alike),
# then each one's least process CPU per clip (as LABEL_EXPORT).
rounds() {
  local label=$1
  shift
  local args=() r e p w
  while [[ $1 != -- ]]; do
    args+=("$1")
    shift
  done
  shift
  for ((r = 0; r < REPEAT; ++r)); do
    for e in "$@"; do run "${label}_$e" "$e" "${args[@]}"; done
  done
  for e in "$@"; do
    read -r p w <"$work/${label}_$e.sum"
    printf '%-24s process CPU/clip %7.3f s  worker CPU/clip %7.3f s (least of %d)\n' \
      "${label}_$e" "$p" "$w" "$REPEAT"
  done
}

# ratio BASE NAME: the export's process CPU against the build without one.
ratio() {
  local b p
  read -r b _ <"$work/$1.sum"
  read -r p _ <"$work/$2.sum"
  printf '  %-22s adds %+.0f %% (%+.3f s per clip)\n' "$2" "$(echo "($p / $b - 1) * 100" | bc -l)" \
    "$(echo "$p - $b" | bc -l)"
}

real=(--dataroot "$REAL" --version v1.0-mini-extract --frames keyframes --geometry lidar
  --max-clips "$MAX_CLIPS")
"$GEODRIVE" synth --out "$work/synth" --scenes 1 --duration 10.5 >/dev/null
synth=(--dataroot "$work/synth" --geometry lidar --clip-frames 121 --max-clips 1)

echo "== at each trainer's own size (the pair built at the size the export writes)"
echo "real scene-0916, keyframe clips of 25 frames, --geometry lidar:"
rounds sc "${real[@]}" --size 320x576 --resize-mode center-crop -- none streetcrafter
ratio sc_none sc_streetcrafter
rounds ds "${real[@]}" --size 900x1600 --resize-mode center-crop -- none drivestudio
ratio ds_none ds_drivestudio
rounds up "${real[@]}" --size 576x1024 -- none geodrive-upstream
ratio up_none up_geodrive-upstream
echo "synthetic, one clip of 121 frames at 12 Hz, --geometry lidar:"
rounds g3 "${synth[@]}" --size 704x1280 --resize-mode center-crop -- none gen3c
ratio g3_none g3_gen3c

echo "== at build-dataset's default size (480x720: an export at another size renders again)"
echo "real scene-0916, keyframe clips of 25 frames, --geometry lidar:"
rounds real "${real[@]}" -- none streetcrafter drivestudio geodrive-upstream
for f in streetcrafter drivestudio geodrive-upstream; do ratio real_none "real_$f"; done
echo "synthetic, one clip of 121 frames at 12 Hz, --geometry lidar:"
rounds synth "${synth[@]}" -- none gen3c rds-hq
for f in gen3c rds-hq; do ratio synth_none "synth_$f"; done
