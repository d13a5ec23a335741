#!/usr/bin/env bash
# The main job on built-in demo data: installs dependencies, builds, generates a small synthetic
# nuScenes-like dataset (with MonST3R-format outputs) and describes what was produced.
# Usage (as root on a fresh machine):  bash scripts/demo.sh [OUT_DIR]
set -euo pipefail
cd "$(dirname "$0")/.."
out="${1:-/tmp/geodrive_demo}"
bash scripts/install_deps.sh
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release > /dev/null
cmake --build build --target geodrive
geodrive=./build/apps/geodrive
"$geodrive" --version
# A real nuScenes LiDAR sweep (read from ../shared/data/real when present).
real=../shared/data/real/nuscenes_n015/n015-2018-07-24-11-22-45+0800__LIDAR_TOP__1532402927647951.pcd.bin
if [[ -f "$real" ]]; then "$geodrive" info "$real"; fi
if "$geodrive" --help | grep -q ' synth'; then
  "$geodrive" synth --out "$out/synth" --scenes 2 --seed 7 --monst3r
  if "$geodrive" --help | grep -q 'nuscenes-info'; then
    "$geodrive" nuscenes-info --dataroot "$out/synth" --version v1.0-mini
  fi
  echo "demo: synthetic dataset written to $out/synth"
fi
