#!/usr/bin/python3
"""Process start-up of `geodrive`, with the peers measured in the same run.

Runs each command RUNS times (after 3 warm-up runs) and prints the median and minimum wall time
of the whole process (fork + exec + dynamic loading + static initialisers + the work), and how
many shared libraries the executable and the commands plugin link (`ldd`). Peers: `python3 -c
pass` (the reference for a bare interpreter), NumPy loading the same .npy file and Open3D reading the same PLY
(what a user would otherwise run to look at one; Open3D's import is most of its time).

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
        # The benchmark cloud: 345,600 points (a 480x720 pointmap), x y z float32 + r g b uchar,
        # binary little-endian PLY.
        cloud = os.path.join(tmp, "cloud.ply")
        n = 480 * 720
        rng = np.random.default_rng(23)
        rec = np.zeros(n, dtype=[("x", "<f4"), ("y", "<f4"), ("z", "<f4"),
                                 ("red", "u1"), ("green", "u1"), ("blue", "u1")])
        for k in ("x", "y", "z"):
            rec[k] = rng.random(n, dtype=np.float32)
        for k in ("red", "green", "blue"):
            rec[k] = rng.integers(0, 256, n, dtype=np.uint8)
        header = ("ply\nformat binary_little_endian 1.0\nelement vertex %d\n"
                  "property float x\nproperty float y\nproperty float z\n"
                  "property uchar red\nproperty uchar green\nproperty uchar blue\n"
                  "end_header\n" % n)
        with open(cloud, "wb") as f:
            f.write(header.encode())
            f.write(rec.tobytes())
        rows = [
            ("geodrive --version", [geodrive, "--version"]),
            ("geodrive info small.npy", [geodrive, "info", small]),
            ("geodrive info cloud.ply (345,600 points)", [geodrive, "info", cloud]),
            ("geodrive synth --help (loads the commands plugin)", [geodrive, "synth", "--help"]),
            ("python3 -c pass", [sys.executable, "-c", "pass"]),
            ("python3 + numpy: np.load(small.npy)",
             [sys.executable, "-c", f"import numpy; numpy.load('{small}')"]),
            ("python3 + open3d: o3d.io.read_point_cloud(cloud.ply)",
             [sys.executable, "-c",
              f"import open3d as o3d; o3d.io.read_point_cloud('{cloud}')"]),
        ]
        print(f"{'command':55s} {'median ms':>10s} {'min ms':>8s}")
        for name, argv in rows:
            # Python with Open3D takes a second or more per process: fewer runs.
            n = max(5, runs // 10) if "open3d" in name else runs
            median, best = time_command(argv, n, env=dict(os.environ, OMP_NUM_THREADS="1"))
            print(f"{name:55s} {median:10.1f} {best:8.1f}")
    print(f"shared libraries: geodrive {shared_libraries(geodrive)}, "
          f"libgeodrive-commands.so {shared_libraries(plugin)}")


if __name__ == "__main__":
    main()
