#!/usr/bin/env bash
# Rewrites the command reference pages from the binaries' command registries:
# docs/reference/geodrive.md and, when built (LibTorch), docs/reference/geodrive-diffusion.md.
# The test apps/CliReference fails until this is run after an option changes.
# Usage: bash scripts/update_cli_reference.sh [BUILD_DIR]   (default: build)
set -euo pipefail
cd "$(dirname "$0")/.."
build="${1:-build}"
"$build/apps/geodrive" --help-markdown > docs/reference/geodrive.md
echo "wrote docs/reference/geodrive.md"
if [[ -x "$build/diffusion/geodrive-diffusion" ]]; then
  "$build/diffusion/geodrive-diffusion" --help-markdown > docs/reference/geodrive-diffusion.md
  echo "wrote docs/reference/geodrive-diffusion.md"
else
  echo "no $build/diffusion/geodrive-diffusion (built with -DGEODRIVE_WITH_TORCH=ON): its page left as it is"
fi
