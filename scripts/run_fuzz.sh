#!/usr/bin/env bash
# Runs every libFuzzer target of a fuzz build for a fixed time on a scratch copy
# of its seed corpus (fuzz/corpus/<target>/), so the committed seeds never change.
#
# Usage: bash scripts/run_fuzz.sh BUILD_DIR [SECONDS_PER_TARGET=30] [TARGET...]
#   BUILD_DIR  a build configured with -DGEODRIVE_FUZZ=ON (scripts/run_sanitizers.sh makes one)
#   TARGET     names without the fuzz_ prefix (default: every fuzz_* binary in BUILD_DIR/fuzz)
# Environment: FUZZ_WORK (default /tmp/geodrive_fuzz): corpora, logs and any crash inputs.
# Prints one line per target (executions, corpus size, coverage) and exits 1 when any target
# found a crash, a leak, a sanitizer report, a timeout or an out-of-memory (the reproducer is
# kept in FUZZ_WORK/<target>/findings/, and `BUILD_DIR/fuzz/fuzz_<target> FILE` replays it).
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:?usage: run_fuzz.sh BUILD_DIR [SECONDS] [TARGET...]}
seconds=${2:-30}
shift $(( $# >= 2 ? 2 : $# ))
work=${FUZZ_WORK:-/tmp/geodrive_fuzz}
targets=("$@")
if [[ ${#targets[@]} -eq 0 ]]; then
  for b in "$build"/fuzz/fuzz_*; do [[ -x "$b" ]] && targets+=("$(basename "$b" | sed 's/^fuzz_//')"); done
fi
[[ ${#targets[@]} -gt 0 ]] || { echo "run_fuzz: no fuzz targets in $build/fuzz (configure with -DGEODRIVE_FUZZ=ON)" >&2; exit 2; }
export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:allocator_may_return_null=1}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
status=0
for t in "${targets[@]}"; do
  bin="$build/fuzz/fuzz_$t"
  [[ -x "$bin" ]] || { echo "run_fuzz: $bin not built" >&2; exit 2; }
  dir="$work/$t"
  rm -rf "$dir" && mkdir -p "$dir/corpus" "$dir/findings"
  [[ -d fuzz/corpus/$t ]] && cp fuzz/corpus/"$t"/* "$dir/corpus/"
  log="$dir/fuzz.log"
  # -malloc_limit_mb: a reader that allocates more than this for an input of at most
  # max_len bytes has trusted a declared size (issue 19): a finding.
  if "$bin" "$dir/corpus" -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2560 \
       -malloc_limit_mb=1024 -max_len=65536 -print_final_stats=1 \
       -artifact_prefix="$dir/findings/" >"$log" 2>&1; then
    result=ok
  else
    result=FINDING
    status=1
  fi
  runs=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$log" | grep -o '[0-9]*$' || echo "?")
  cov=$(grep -o 'cov: [0-9]*' "$log" | tail -1 | grep -o '[0-9]*' || echo "?")
  echo "fuzz_$t: $result, $runs executions in ${seconds}s, coverage $cov, corpus $(ls "$dir/corpus" | wc -l) inputs"
  if [[ $result != ok ]]; then
    grep -m 5 -E 'ERROR|SUMMARY|==[0-9]+==|deadly|uncaught|Test unit written' "$log" | sed 's/^/  /' || true
  fi
done
exit $status
