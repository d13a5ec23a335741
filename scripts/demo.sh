#!/usr/bin/env bash
# The main job on built-in demo data: installs dependencies, builds, generates a synthetic
# nuScenes-like dataset with MonST3R-format outputs, and builds its condition/video training pairs
# end to end (LiDAR-scaled MonST3R geometry, 3D dynamic editing, H.264 videos, report).
# Usage (as root on a fresh machine):  bash scripts/demo.sh [OUT_DIR]
set -euo pipefail
cd "$(dirname "$0")/.."
out="${1:-/tmp/geodrive_demo}"
bash scripts/install_deps.sh
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release > /dev/null
cmake --build build --target geodrive
geodrive=./build/apps/geodrive
"$geodrive" --version
rm -rf "$out"
# 1. A synthetic nuScenes-format world (2 scenes, seed 7) with MonST3R folders per clip.
"$geodrive" synth --out "$out/synth" --scenes 2 --seed 7 --monst3r
# 2. What the reader sees in it.
"$geodrive" nuscenes-info --dataroot "$out/synth" --version v1.0-mini
# 3. The training pairs.
"$geodrive" build-dataset --dataroot "$out/synth" --version v1.0-mini \
  --monst3r "$out/synth/monst3r" --out "$out/pairs" --threads "$(nproc)"
first_pair=$(head -n 1 "$out/pairs/manifest.jsonl" | sed 's/.*"pair_dir":"\([^"]*\)".*/\1/')
echo
echo "demo done. Look at:"
echo "  $out/pairs/report.html            (open in a browser: counts, timing, histograms, previews)"
echo "  $out/pairs/$first_pair/preview.png  (GT row over condition row)"
echo "  $out/pairs/manifest.jsonl         (one line per pair; meta.json per pair folder)"
