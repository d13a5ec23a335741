#!/usr/bin/env bash
# Device check of the diffusion runtime (docs/DIFFUSION.md "On a GPU"): builds the runtime's core
# standalone (diffusion/standalone: LibTorch + header-only nlohmann_json only) against the PyTorch
# installation it finds, then runs geodrive-device-check:
#   - tiny-config agreement: CPU float32 (reference) vs the device in fp32 and in --dtype;
#   - one 5B-shape DiT block forward at 17,776 tokens in bf16 (time, peak memory);
#   - one full 5B sampling step, random weights, 42 backbone + 2 encoder blocks, CFG batch 2;
#   - a 5B-shape VAE decode of 13 latent frames to 49 x 480 x 720.
# Written for one large NVIDIA GPU with CUDA's compiler and a PyTorch installation and no network:
# it downloads nothing and builds only what it finds. Without CUDA it runs the same program on the
# CPU with scaled-down shapes (--shape small), which is what CI can check.
#
# Usage: bash scripts/device_check.sh [geodrive-device-check options]
# Environment: PYTHON (an interpreter with torch), DEVICE_CHECK_BUILD (build folder, default
# build-device-check), DEVICE_CHECK_DEVICE (cuda|cuda:N|cpu; default cuda when torch sees one),
# DEVICE_CHECK_SHAPE (5b|small; default 5b on CUDA, small on the CPU), DEVICE_CHECK_DTYPE (bf16),
# DEVICE_CHECK_TIMEOUT (seconds for the run, default 420), TORCH_PREFIX (a LibTorch CMake prefix
# instead of PyTorch's), NLOHMANN_JSON_INCLUDE_DIR.
# Output: stdout, and $DEVICE_CHECK_BUILD/device_check.txt.
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$PWD
BUILD=${DEVICE_CHECK_BUILD:-$ROOT/build-device-check}
mkdir -p "$BUILD"
LOG=$BUILD/device_check.txt
: >"$LOG"
say() { echo "$*" | tee -a "$LOG"; }
start=$(date +%s)

# 1. A Python with torch (for its LibTorch and to ask it about CUDA).
py=""
for cand in ${PYTHON:-} python3 /usr/bin/python3 python; do
  if command -v "$cand" >/dev/null 2>&1 && "$cand" -c 'import torch' >/dev/null 2>&1; then
    py=$cand
    break
  fi
done
prefix=${TORCH_PREFIX:-}
cuda=0
if [[ -n "$py" ]]; then
  info=$("$py" -c 'import torch, os
p = torch.utils.cmake_prefix_path
print(torch.__version__, int(torch.cuda.is_available()), torch.cuda.device_count(),
      p if os.path.isdir(os.path.join(p, "Torch")) else "-")')
  read -r tver cuda ndev tprefix <<<"$info"
  say "python   $py: torch $tver, CUDA available $cuda ($ndev device(s))"
  [[ -z "$prefix" && "$tprefix" != "-" ]] && prefix=$tprefix
fi
if [[ -z "$prefix" ]]; then
  say "python   no PyTorch CMake prefix found; using the system LibTorch (find_package(Torch))"
fi
if command -v nvidia-smi >/dev/null 2>&1; then
  nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv,noheader 2>/dev/null |
    sed 's/^/gpu      /' | tee -a "$LOG" || true
fi
command -v nvcc >/dev/null 2>&1 && say "nvcc     $(nvcc --version | tail -1)"
say "machine  $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs)"

# 2. Configure and build the standalone core (retry without the CUDA memory statistics when
#    this LibTorch's allocator API differs).
gen=()
command -v ninja >/dev/null 2>&1 && gen=(-G Ninja)
configure() {
  cmake -S diffusion/standalone -B "$BUILD" "${gen[@]}" -DCMAKE_BUILD_TYPE=Release \
    ${prefix:+-DCMAKE_PREFIX_PATH="$prefix"} \
    ${NLOHMANN_JSON_INCLUDE_DIR:+-DNLOHMANN_JSON_INCLUDE_DIR="$NLOHMANN_JSON_INCLUDE_DIR"} "$@" \
    >"$BUILD/configure.log" 2>&1
}
build() { cmake --build "$BUILD" -j "$(nproc)" >"$BUILD/build.log" 2>&1; }
if ! configure; then
  say "configure failed (the end of $BUILD/configure.log follows)"
  tail -20 "$BUILD/configure.log" | tee -a "$LOG"
  exit 2
fi
grep "geodrive core:" "$BUILD/configure.log" | sed 's/^-- /build    /' | tee -a "$LOG"
if ! build; then
  say "build    failed with the CUDA memory statistics; retrying without them"
  configure -DGEODRIVE_CUDA_STATS=OFF && build || {
    say "build failed (the end of $BUILD/build.log follows)"
    tail -30 "$BUILD/build.log" | tee -a "$LOG"
    exit 2
  }
fi
say "build    done in $(($(date +%s) - start)) s"

# 3. Run.
device=${DEVICE_CHECK_DEVICE:-}
[[ -z "$device" ]] && { [[ "$cuda" == 1 ]] && device=cuda || device=cpu; }
shape=${DEVICE_CHECK_SHAPE:-}
[[ -z "$shape" ]] && { [[ "$device" == cpu ]] && shape=small || shape=5b; }
dtype=${DEVICE_CHECK_DTYPE:-bf16}
export OMP_NUM_THREADS=${OMP_NUM_THREADS:-$(nproc)}
rc=0
timeout "${DEVICE_CHECK_TIMEOUT:-420}" "$BUILD/geodrive-device-check" --device "$device" \
  --dtype "$dtype" --shape "$shape" "$@" 2>&1 | tee -a "$LOG" || rc=${PIPESTATUS[0]}
say "total    $(($(date +%s) - start)) s, exit $rc ($(date -u +%Y-%m-%dT%H:%MZ))"
exit "$rc"
