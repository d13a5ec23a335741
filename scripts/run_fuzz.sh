#!/usr/bin/env bash
# Runs every libFuzzer target of a fuzz build for a fixed time on a scratch copy
# of its seed corpus (fuzz/corpus/<target>/), so the committed seeds never change,
# with its dictionary (fuzz/dict/<target>.dict) when it has one.
#
# Usage: bash scripts/run_fuzz.sh BUILD_DIR [SECONDS_PER_TARGET=30] [TARGET...]
#   BUILD_DIR  a build configured with -DGEODRIVE_FUZZ=ON (scripts/run_sanitizers.sh makes one)
#   TARGET     names without the fuzz_ prefix (default: every fuzz_* binary in BUILD_DIR/fuzz)
# Environment:
#   FUZZ_WORK      (default /tmp/geodrive_fuzz): corpora, logs and any crash inputs
#   FUZZ_CLOCK     wall (default): SECONDS of wall time per target (libFuzzer's -max_total_time);
#                  cpu: SECONDS of CPU time of the fuzzer process, measured from /proc and
#                  ended with SIGINT (libFuzzer then prints its final stats) -- for long runs
#                  that share the machine with other work (a "one CPU-hour" run)
#   FUZZ_MAX_RUNS  stop earlier after this many executions (libFuzzer's -runs; 10000000 for the
#                  long runs of docs/RELIABILITY.md)
#   FUZZ_TIMEOUT   seconds one input may take before it is a hang finding (default 10)
#   FUZZ_JOBS      targets run at once (default 1; scripts/run_sanitizers.sh uses one per core);
#                  the per-target lines still come out in target order
#   TMPDIR         where each target writes its input file (default /dev/shm when writable: on
#                  a disk the targets spend most of their time in the file system, 3x fewer
#                  executions per second)
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
if [[ -z "${TMPDIR:-}" && -d /dev/shm && -w /dev/shm ]]; then export TMPDIR=/dev/shm; fi
export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:allocator_may_return_null=1}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
clock=${FUZZ_CLOCK:-wall}
[[ $clock == wall || $clock == cpu ]] || { echo "run_fuzz: FUZZ_CLOCK must be wall or cpu, not '$clock'" >&2; exit 2; }
limits=(-timeout="${FUZZ_TIMEOUT:-10}" -runs="${FUZZ_MAX_RUNS:--1}")
[[ $clock == wall ]] && limits+=(-max_total_time="$seconds")
ticks_per_second=$(getconf CLK_TCK)
# One target: its corpus, the fuzzer, the CPU-time watch; its lines go to $work/$t.summary and
# its status is the function's.
run_target() {
  local t=$1
  bin="$build/fuzz/fuzz_$t"
  dir="$work/$t"
  rm -rf "$dir" && mkdir -p "$dir/corpus" "$dir/findings"
  [[ -d fuzz/corpus/$t ]] && cp fuzz/corpus/"$t"/* "$dir/corpus/"
  log="$dir/fuzz.log"
  dict=()
  [[ -f fuzz/dict/$t.dict ]] && dict=(-dict="fuzz/dict/$t.dict")
  # -malloc_limit_mb: a reader that allocates more than this for an input of at most
  # max_len bytes has trusted a declared size: a finding.
  "$bin" "$dir/corpus" "${limits[@]}" "${dict[@]}" -rss_limit_mb=2560 \
    -malloc_limit_mb=1024 -max_len=65536 -print_final_stats=1 \
    -artifact_prefix="$dir/findings/" >"$log" 2>&1 &
  pid=$!
  # Watch the fuzzer's CPU time (utime + stime, fields 14 and 15 of /proc/PID/stat).
  cpu_ticks=0
  interrupted=0
  while kill -0 "$pid" 2>/dev/null; do
    ticks=$(awk '{print $14 + $15}' "/proc/$pid/stat" 2>/dev/null || echo "$cpu_ticks")
    cpu_ticks=$ticks
    if [[ $clock == cpu && $interrupted == 0 ]] && (( cpu_ticks >= seconds * ticks_per_second )); then
      kill -INT "$pid" 2>/dev/null || true
      interrupted=1
    fi
    sleep 2
  done
  rc=0
  wait "$pid" || rc=$?
  # 72: libFuzzer's exit code after the SIGINT sent above at the CPU limit.
  if [[ $rc == 0 || ( $interrupted == 1 && $rc == 72 ) ]]; then
    result=ok
  else
    result=FINDING
  fi
  runs=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$log" | grep -o '[0-9]*$' || echo "?")
  cov=$(grep -o 'cov: [0-9]*' "$log" | tail -1 | grep -o '[0-9]*' || echo "?")
  {
  echo "fuzz_$t: $result, $runs executions in $((cpu_ticks / ticks_per_second)) CPU-s (limit ${seconds}s $clock), coverage $cov, corpus $(ls "$dir/corpus" | wc -l) inputs"
  if [[ $result != ok ]]; then
    grep -m 5 -E 'ERROR|SUMMARY|==[0-9]+==|deadly|uncaught|Test unit written' "$log" | sed 's/^/  /' || true
    # libFuzzer's per-input timeout is wall time: a run that was stopped (SIGSTOP, a suspended
    # virtual machine) reports a timeout for whatever input it was on. Replay each timeout once to tell.
    for unit in "$dir"/findings/timeout-*; do
      [[ -e "$unit" ]] || continue
      if timeout "${FUZZ_TIMEOUT:-10}" "$bin" "$unit" >/dev/null 2>&1; then
        echo "  $(basename "$unit"): replayed in under ${FUZZ_TIMEOUT:-10} s (the process was stalled, not the input)"
      else
        echo "  $(basename "$unit"): times out again on replay"
      fi
    done
  fi
  } > "$dir.summary.part"
  mv "$dir.summary.part" "$dir.summary"  # whole, so the main loop prints it whole
  [[ $result == ok ]]
}

for t in "${targets[@]}"; do
  [[ -x "$build/fuzz/fuzz_$t" ]] || { echo "run_fuzz: $build/fuzz/fuzz_$t not built" >&2; exit 2; }
done
jobs_max=${FUZZ_JOBS:-1}
[[ $jobs_max =~ ^[1-9][0-9]*$ ]] || { echo "run_fuzz: FUZZ_JOBS must be a positive integer, not '$jobs_max'" >&2; exit 2; }
for t in "${targets[@]}"; do rm -f "$work/$t.summary"; done
# Prints the lines of the targets that have finished, in target order, up to the first one
# still running.
printed=0
print_finished() {
  while (( printed < ${#targets[@]} )) && [[ -f "$work/${targets[$printed]}.summary" ]]; do
    cat "$work/${targets[$printed]}.summary"
    printed=$((printed + 1))
  done
}
status=0
running=0
for t in "${targets[@]}"; do
  if (( running >= jobs_max )); then
    wait -n || status=1
    running=$((running - 1))
    print_finished
  fi
  run_target "$t" &
  running=$((running + 1))
done
while (( running > 0 )); do
  wait -n || status=1
  running=$((running - 1))
  print_finished
done
print_finished
exit $status
