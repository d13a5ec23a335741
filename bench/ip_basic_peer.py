#!/usr/bin/python3
"""The peer of bench_depth_completion: IP-Basic's published CPU pipeline
(Ku, Harakeh and Waslander, CRV 2018; the `fill_in_fast` function of their
repository, gaussian blur option, no extrapolation) in Python with OpenCV
(Debian's python3-opencv), timed on the sparse depth images the benchmark
wrote (GEODRIVE_BENCH_SPARSE_DUMP). Written from the paper's description and
default kernels; one OpenCV thread, CPU time of this process.

    /usr/bin/python3 bench/ip_basic_peer.py DIR [REPS]
"""
import sys
import time

import cv2
import numpy as np

FULL_5 = np.ones((5, 5), np.uint8)
FULL_7 = np.ones((7, 7), np.uint8)
FULL_31 = np.ones((31, 31), np.uint8)
DIAMOND_5 = np.array([[0, 0, 1, 0, 0],
                      [0, 1, 1, 1, 0],
                      [1, 1, 1, 1, 1],
                      [0, 1, 1, 1, 0],
                      [0, 0, 1, 0, 0]], np.uint8)


def fill_in_fast(depth, max_depth=100.0):
    depth = depth.copy()
    valid = depth > 0.1
    depth[valid] = max_depth - depth[valid]
    depth = cv2.dilate(depth, DIAMOND_5)
    depth = cv2.morphologyEx(depth, cv2.MORPH_CLOSE, FULL_5)
    empty = depth < 0.1
    dilated = cv2.dilate(depth, FULL_7)
    depth[empty] = dilated[empty]
    empty = depth < 0.1
    dilated = cv2.dilate(depth, FULL_31)
    depth[empty] = dilated[empty]
    blurred = cv2.medianBlur(depth, 5)
    valid = depth > 0.1
    depth[valid] = blurred[valid]
    blurred = cv2.GaussianBlur(depth, (5, 5), 0)
    depth[valid] = blurred[valid]
    valid = depth > 0.1
    depth[valid] = max_depth - depth[valid]
    return depth


def unproject(depth, fx, fy, cx, cy):
    ys, xs = np.nonzero(depth > 0)
    z = depth[ys, xs]
    return np.stack([(xs - cx) / fx * z, (ys - cy) / fy * z, z], axis=1)


def main():
    cv2.setNumThreads(1)
    folder = sys.argv[1]
    reps = int(sys.argv[2]) if len(sys.argv) > 2 else 10
    for width in (800, 1600):
        sparse = np.load("%s/sparse_%d.npy" % (folder, width))
        h = sparse.shape[0]
        f = 1266.42 * width / 1600.0  # CAM_FRONT-like; the cost does not depend on it
        fill_in_fast(sparse)
        times = []
        for _ in range(reps):
            t0 = time.process_time()
            dense = fill_in_fast(sparse)
            unproject(dense, f, f, width / 2.0, h / 2.0)
            times.append(time.process_time() - t0)
        print("ip_basic_peer %dx%d: completion + unprojection %.1f ms CPU "
              "(median of %d), coverage %.3f" %
              (width, h, 1e3 * float(np.median(times)), reps,
               float(np.count_nonzero(dense > 0)) / dense.size))


if __name__ == "__main__":
    main()
