#!/usr/bin/env bash
# Installs the build tree into a temporary prefix, then configures and builds a downstream project
# that uses find_package(geodrive) and links geodrive::geometry, and runs it.
set -euo pipefail
build_dir="$1"; source_dir="$2"; work="$build_dir/test_tmp/install_consumer"
rm -rf "$work"; mkdir -p "$work"
cmake --install "$build_dir" --prefix "$work/prefix" > "$work/install.log"
cmake -S "$source_dir/tests/install/consumer" -B "$work/build" -DCMAKE_BUILD_TYPE=Release \
  -DCMAKE_PREFIX_PATH="$work/prefix" > "$work/configure.log"
cmake --build "$work/build" -j 2 > "$work/build.log"
"$work/build/consumer"

# The installed `geodrive` finds its installed commands plugin (<prefix>/<libdir>/geodrive), not
# the build tree's (commands are a plugin loaded on use).
installed="$work/prefix/bin/geodrive"
"$installed" --version
loaded=$(LD_DEBUG=files "$installed" synth --help 2>&1 >/dev/null | grep -o '[^ =]*libgeodrive-commands.so' | sort -u)
case "$loaded" in
  "$work/prefix/"*) echo "installed geodrive loads $loaded" ;;
  *) echo "installed geodrive loaded '$loaded', not the plugin under $work/prefix" >&2; exit 1 ;;
esac

# The installed Python package, when the build has it: importable from the prefix with
# Debian's interpreter, outside the build tree.
if [[ -d "$work/prefix/lib/python3/dist-packages/geodrive" ]]; then
  (cd "$work" && PYTHONPATH="$work/prefix/lib/python3/dist-packages" /usr/bin/python3 -c \
    "import geodrive, os; assert geodrive.__file__.startswith('$work/prefix'), geodrive.__file__; print('installed geodrive module:', os.path.dirname(geodrive.__file__), len(geodrive.scene_sources()), 'scene sources')")
fi
