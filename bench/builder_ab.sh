#!/usr/bin/env bash
# Two builds of `geodrive build-dataset` side by side: the same dataset built
# ROUNDS times by each binary, alternating, one thread pinned to one core, and
# each run's CPU seconds per clip by stage (the builder's own "CPU per stage"
# line, worker-thread CPU) and the process's CPU per clip (user + sys, start-up
# and table loading included). On a shared machine the CPU time of one binary
# moved by up to 1.9x within twenty minutes, so only runs made side by side
# compare; docs/PERFORMANCE.md "Dataset builder".
#
#   bash bench/builder_ab.sh OLD_GEODRIVE NEW_GEODRIVE [DATAROOT] [MONST3R]
#
# DATAROOT and MONST3R default to the demo set of scripts/demo.sh
# (/tmp/frames/synthm and its monst3r/ folder; made with `geodrive synth --out
# /tmp/frames/synthm --scenes 2 --seed 7 --monst3r` if absent). Environment:
# ROUNDS (default 3), CORE (the core to pin to, default 1), KEEP=1 (keep the
# pair folders, under $TMPDIR, to `diff -r` the two binaries' outputs).
set -euo pipefail

if [[ $# -lt 2 ]]; then
  sed -n '2,16p' "$0" | sed 's/^# \{0,1\}//'
  exit 2
fi
OLD=$1
NEW=$2
ROOT=${3:-/tmp/frames/synthm}
MONST3R=${4:-$ROOT/monst3r}
ROUNDS=${ROUNDS:-3}
CORE=${CORE:-1}
for b in "$OLD" "$NEW"; do
  [[ -x "$b" ]] || { echo "builder_ab: $b is not an executable" >&2; exit 2; }
done
if [[ ! -d "$ROOT" ]]; then
  "$NEW" synth --out "$ROOT" --scenes 2 --seed 7 --monst3r > /dev/null
fi
OUT=$(mktemp -d)
[[ "${KEEP:-0}" == 1 ]] || trap 'rm -rf "$OUT"' EXIT

echo "== machine: $(lscpu | sed -n 's/^Model name: *//p'), load $(cut -d' ' -f1-3 /proc/loadavg)"
echo "== $ROUNDS rounds, old then new, taskset -c $CORE, OMP_NUM_THREADS=1, --threads 1"
printf '%-5s %-4s %8s %8s %8s %8s %10s %12s\n' round bin gt encode geometry render "sum/clip" "process/clip"
for ((r = 1; r <= ROUNDS; ++r)); do
  for side in old new; do
    bin=$OLD
    [[ $side == new ]] && bin=$NEW
    dir="$OUT/${side}_$r"
    log="$OUT/${side}_$r.log"
    OMP_NUM_THREADS=1 /usr/bin/time -f '%U %S' -o "$OUT/${side}_$r.time" \
      taskset -c "$CORE" "$bin" build-dataset --dataroot "$ROOT" --monst3r "$MONST3R" \
      --out "$dir" --threads 1 > "$log" 2>&1
    /usr/bin/python3 - "$log" "$OUT/${side}_$r.time" "$r" "$side" <<'EOF'
import re, sys
log, timing, r, side = sys.argv[1:]
text = open(log).read()
clips = int(re.search(r'pairs built (\d+)', text).group(1))
line = re.search(r'CPU per stage[^:]*: (.*)', text).group(1)
cpu = {k: float(v) for k, v in re.findall(r'(\w+) ([0-9.e+-]+)', line)}
user, sys_ = map(float, open(timing).read().split()[-2:])
per = lambda k: cpu.get(k, 0.0) / clips
print(f'{r:<5} {side:<4} {per("gt"):8.3f} {per("encode"):8.3f} {per("geometry"):8.3f} '
      f'{per("render"):8.3f} {sum(cpu.values()) / clips:10.3f} {(user + sys_) / clips:12.3f}')
EOF
  done
done
[[ "${KEEP:-0}" == 1 ]] && echo "pair folders kept in $OUT"
exit 0
