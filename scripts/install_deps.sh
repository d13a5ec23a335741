#!/usr/bin/env bash
# Installs the build and test dependencies of the GeoDrive toolkit from Debian bookworm packages.
# Idempotent: packages already present are skipped by apt-get. Run as root (or with sudo).
set -euo pipefail

PACKAGES=(
  build-essential cmake ninja-build pkg-config git procps
  libeigen3-dev libpcl-dev libflann-dev libceres-dev libgoogle-glog-dev libgflags-dev liblzf-dev
  libopencv-dev libturbojpeg0-dev libspng-dev nlohmann-json3-dev libsimdjson-dev libzip-dev libopenexr-dev libcli11-dev
  protobuf-compiler libprotobuf-dev zlib1g-dev
  libavcodec-dev libavformat-dev libavutil-dev libswscale-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  libopenmpi-dev openmpi-bin
  python3 python3-numpy python3-jsonschema python3-skimage python3-scipy python3-opencv python3-open3d
  python3-dev pybind11-dev python3-pytest
  chromium chromium-driver
)
if [[ "${GEODRIVE_WITH_TORCH:-0}" == "1" ]]; then
  PACKAGES+=(libtorch-dev python3-torch)
fi

SUDO=""
if [[ "$(id -u)" != "0" ]]; then SUDO="sudo"; fi

missing=()
for p in "${PACKAGES[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [[ ${#missing[@]} -eq 0 ]]; then
  echo "install_deps: all ${#PACKAGES[@]} packages already installed"
  exit 0
fi

echo "install_deps: installing ${#missing[@]} packages: ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
echo "install_deps: done"
