#!/usr/bin/python3
"""The frames cv2.VideoCapture (OpenCV's FFmpeg backend, python3-opencv) decodes from a video:
the reference tests/render/video_reader_test.cc compares ReadVideoFrames with, frame by frame
(the library reads videos with our own reader, not cv::VideoCapture).

Usage: opencv_video_reference.py VIDEO OUT.rgb
Writes every frame as RGB bytes, frame after frame, to OUT.rgb and prints "frames height width"."""
import sys

import cv2
import numpy as np


def main():
    video, out = sys.argv[1], sys.argv[2]
    cap = cv2.VideoCapture(video, cv2.CAP_FFMPEG)
    if not cap.isOpened():
        print("cannot open", video, file=sys.stderr)
        return 1
    frames = []
    while True:
        ok, bgr = cap.read()
        if not ok or bgr is None:
            break
        frames.append(cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB))
    if not frames:
        print("no frames in", video, file=sys.stderr)
        return 1
    with open(out, "wb") as f:
        for rgb in frames:
            f.write(np.ascontiguousarray(rgb).tobytes())
    h, w = frames[0].shape[:2]
    print(len(frames), h, w)
    return 0


if __name__ == "__main__":
    sys.exit(main())
