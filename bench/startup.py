#!/usr/bin/python3
"""Process start-up of `geodrive` (issue 23), with the peers measured in the same run.

Runs each command RUNS times (after 3 warm-up runs) and prints the median and minimum wall time
of the whole process (fork + exec + dynamic loading + static initialisers + the work), and how
many shared libraries it maps (from /proc/<pid>/maps is not portable across exits, so from
`ldd` of the executable). Peers: `python3 -c pass` (the issue's reference) and NumPy loading the
same .npy file (what a user would otherwise run to look at one).

Usage: /usr/bin/python3 bench/startup.py BUILD_DIR [RUNS=50]
"""
import os
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np


def time_command(argv, runs, env=None):
    for _ in range(3):
        subprocess.run(argv, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=True,
                       env=env)
    times = []
    for _ in range(runs):
        t = time.perf_counter()
        subprocess.run(argv, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=True,
                       env=env)
        times.append(time.perf_counter() - t)
    return 1e3 * statistics.median(times), 1e3 * min(times)


def shared_libraries(path):
    out = subprocess.run(["ldd", path], capture_output=True, text=True, check=True).stdout
    return sum(1 for line in out.splitlines() if "=>" in line)


def main():
    build = sys.argv[1]
    runs = int(sys.argv[2]) if len(sys.argv) > 2 else 50
    geodrive = os.path.join(build, "apps", "geodrive")
    plugin = os.path.join(build, "lib", "geodrive", "libgeodrive-commands.so")
    with tempfile.TemporaryDirectory() as tmp:
        small = os.path.join(tmp, "small.npy")
        np.save(small, np.arange(12, dtype=np.float32).reshape(3, 4))
        rows = [
            ("geodrive --version", [geodrive, "--version"]),
            ("geodrive info small.npy", [geodrive, "info", small]),
            ("geodrive synth --help (loads the commands plugin)", [geodrive, "synth", "--help"]),
            ("python3 -c pass", [sys.executable, "-c", "pass"]),
            ("python3 + numpy: np.load(small.npy)",
             [sys.executable, "-c", f"import numpy; numpy.load('{small}')"]),
        ]
        print(f"{'command':55s} {'median ms':>10s} {'min ms':>8s}")
        for name, argv in rows:
            median, best = time_command(argv, runs, env=dict(os.environ, OMP_NUM_THREADS="1"))
            print(f"{name:55s} {median:10.1f} {best:8.1f}")
    print(f"shared libraries: geodrive {shared_libraries(geodrive)}, "
          f"libgeodrive-commands.so {shared_libraries(plugin)}")


if __name__ == "__main__":
    main()
