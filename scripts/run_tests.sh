#!/usr/bin/env bash
# Installs dependencies (Debian bookworm, apt), builds everything in ./build and runs all tests.
# Usage (as root on a fresh machine):  bash scripts/run_tests.sh
set -euo pipefail
cd "$(dirname "$0")/.."
export GEODRIVE_WITH_TORCH=1  # diffusion/ (LibTorch): libtorch-dev + python3-torch
bash scripts/install_deps.sh
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release -DGEODRIVE_BUILD_TESTS=ON -DGEODRIVE_WITH_TORCH=ON -DGEODRIVE_WITH_MPI=ON -DGEODRIVE_WITH_PYTHON=ON -DCMAKE_UNITY_BUILD=ON ${GEODRIVE_CMAKE_ARGS:-}
cmake --build build
# Force numpy/skimage-dependent tests to run (not skip) where CI requires it.
export OMP_NUM_THREADS="${OMP_NUM_THREADS:-2}"
# CTest starts the longest tests first when it knows their times (CTestCostData.txt, which it
# writes after each run); a fresh build has none, so seed it with the times measured on a
# 2-core machine (tests/ctest_costs/). Without it the longest tests, defined last, start
# last and one core idles at the end. Only the order changes; a test not listed runs last.
costs=build/Testing/Temporary/CTestCostData.txt
[[ -f $costs ]] || { mkdir -p "$(dirname "$costs")" && cp tests/ctest_costs/release.txt "$costs"; }
# At their peak the tests hold about 2 GB under build/test_tmp (shared fixtures, and each
# process's folders until its tests pass): say what is free, so a full disk reads as one.
df -Pm build | awk 'NR == 2 { printf "disk: %.1f GB free under build/ (the tests need about 2 GB)\n", $4 / 1024 }'
ctest --test-dir build --output-on-failure -j "$(nproc)" --timeout 900
