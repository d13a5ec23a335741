#!/usr/bin/env bash
# Compiles every installed (public) header of the geometry, util, render, dataset and eval
# libraries alone and fails if one does not compile by itself or pulls in, directly or
# transitively, a PCL, FLANN, VTK, Ceres, nlohmann_json or LibTorch header. The LibTorch runtime
# (diffusion/) is the one library whose API is tensors; it is checked only for PCL, Ceres and
# nlohmann_json. The headers are compiled in parallel (one job per CPU).
# Usage: check_public_headers.sh BUILD_DIR   (reads BUILD_DIR/public_headers.txt and
#        BUILD_DIR/public_header_flags.txt, written by the top-level CMakeLists.txt)
set -euo pipefail
build=$1

# check_one HEADER: prints FAIL lines for HEADER, exits 1 when it fails. The include tree comes
# from the preprocessor alone (-E -H, a tenth of a compile); a header whose tree holds
# <Eigen/Core> then compiles with Eigen/Core precompiled and included first ($pch), which the
# header includes itself anyway: 0.6 s instead of 2 s, Eigen's parse being most of a compile. What
# that precompiled header could hide is a name used before the header's own includes bring Eigen
# (and the standard headers Eigen includes) in; a header whose tree has no Eigen compiles as is.
check_one() {
  local header=$1 cxx flags tree out bad heavy pre=()
  cxx=$(sed -n 1p "$build/public_header_flags.txt")
  read -r -a flags <<< "$(sed -n 2p "$build/public_header_flags.txt")"
  heavy='(/pcl[-/]|/flann/|/vtk|/ceres/|/nlohmann/|/torch/|/ATen/|/c10/|/google/protobuf/)'
  [[ "$header" == */diffusion/* ]] && heavy='(/pcl[-/]|/flann/|/vtk|/ceres/|/nlohmann/)'
  if ! tree=$("$cxx" -std=c++17 -E -H -x c++ "${flags[@]}" "$header" 2>&1 >/dev/null); then
    echo "FAIL: $header does not compile alone:"
    echo "$tree" | grep -v '^\.' | head -5
    return 1
  fi
  bad=$(echo "$tree" | grep -E '^\.+ ' | grep -E "$heavy" | head -3 || true)
  if [[ -n "$bad" ]]; then
    echo "FAIL: $header includes a heavy header:"
    echo "$bad"
    return 1
  fi
  if [[ -f "$pch.gch" ]] && echo "$tree" | grep -qE '^\.+ .*/Eigen/Core$'; then
    pre=(-include "$pch")
  fi
  if ! out=$("$cxx" -std=c++17 -fsyntax-only -x c++ "${flags[@]}" "${pre[@]}" "$header" 2>&1); then
    echo "FAIL: $header does not compile alone:"
    echo "$out" | head -5
    return 1
  fi
}
export -f check_one
export build
# Eigen/Core, precompiled with the headers' own compiler and flags.
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
export pch=$tmp/eigen_core.h
echo '#include <Eigen/Core>' > "$pch"
read -r -a pch_flags <<< "$(sed -n 2p "$build/public_header_flags.txt")"
"$(sed -n 1p "$build/public_header_flags.txt")" -std=c++17 -x c++-header "${pch_flags[@]}" \
  "$pch" -o "$pch.gch" || { echo "FAIL: Eigen/Core does not precompile"; exit 1; }

count=$(grep -c . "$build/public_headers.txt" || true)
fail=0
# xargs exits 123 when any invocation failed; each failing header prints its own lines.
grep . "$build/public_headers.txt" |
  xargs -P "$(nproc)" -I{} bash -c 'check_one "$1"' _ {} || fail=1
echo "checked $count public headers"
[[ $count -gt 30 ]] || { echo "FAIL: expected more than 30 public headers"; exit 1; }
exit $fail
