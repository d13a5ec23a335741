#!/usr/bin/env bash
# Start-up: `geodrive` loads no heavy library at start-up. Fails when
#  - the executable links (directly or not, `ldd`) LibTorch, VTK, GDAL, OpenCV's imgcodecs or
#    videoio, FFmpeg, PCL, Ceres or protobuf: those belong to the commands plugin;
#  - the commands plugin links LibTorch, VTK, GDAL, OpenCV's imgcodecs or videoio (LibTorch is
#    the deep-metrics plugin's alone, loaded by `eval --metrics lpips|fid|fvd`);
#  - `geodrive --version` or `geodrive info FILE.npy` opens the commands plugin (LD_DEBUG), or
#    a plugin command does not.
# Usage: check_startup_libraries.sh BUILD_DIR
set -euo pipefail
build=$1
exe=$build/apps/geodrive
plugin=$build/lib/geodrive/libgeodrive-commands.so
never='libtorch|libc10|libvtk|libgdal|libopencv_imgcodecs|libopencv_videoio'
status=0
forbid() {  # FILE PATTERN
  local bad
  bad=$(ldd "$1" | grep -E -o "($2)[^ ]*" | sort -u | tr '\n' ' ' || true)
  if [[ -n $bad ]]; then
    echo "FAIL: $(basename "$1") loads $bad"
    echo "  direct dependencies: $(readelf -d "$1" | grep -o 'NEEDED.*' | grep -o '\[.*\]' | tr -d '[]' | tr '\n' ' ')"
    status=1
  fi
  echo "$(basename "$1"): $(ldd "$1" | grep -c '=>') shared libraries"
}
forbid "$exe" "$never|libavcodec|libavformat|libswscale|libpcl|libceres|libopencv_imgproc|libprotobuf"
forbid "$plugin" "$never"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
# A 2x3 float32 .npy (header v1.0, 128-byte aligned), written byte by byte.
{
  printf '\x93NUMPY\x01\x00\x76\x00'
  printf "%-117s\n" "{'descr': '<f4', 'fortran_order': False, 'shape': (2, 3), }"
  head -c 24 /dev/zero
} > "$tmp/small.npy"
opens_plugin() { LD_DEBUG=files "$@" 2>&1 >/dev/null | grep -c 'libgeodrive-commands.so' || true; }
for args in "--version" "info $tmp/small.npy"; do
  # shellcheck disable=SC2086
  if [[ $(opens_plugin "$exe" $args) != 0 ]]; then
    echo "FAIL: geodrive $args opened libgeodrive-commands.so"; status=1
  fi
done
if [[ $(opens_plugin "$exe" synth --help) == 0 ]]; then
  echo "FAIL: geodrive synth --help did not open libgeodrive-commands.so"; status=1
fi
"$exe" info "$tmp/small.npy" | grep -q '2, 3\|2x3\|(2, 3)' || { echo "FAIL: geodrive info small.npy:"; "$exe" info "$tmp/small.npy"; status=1; }
exit $status
