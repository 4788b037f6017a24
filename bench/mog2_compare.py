#!/usr/bin/env python3
"""Runs OpenCV's MOG2 on the frames of a Y4M file (as dumped by
`cargo bench --bench detect -- --dump DIR`) and prints ns/frame.

    mog2_compare.py FILE.y4m WARM FRAMES {gray,bgr}

With FRAMES = 0 it only decodes and sets up (the baseline that
`mog2_compare.sh` subtracts from callgrind's count).
"""
import sys
import time

import cv2
import numpy as np


def frames(path):
    with open(path, "rb") as f:
        header = f.readline().split()
        w = int(next(t[1:] for t in header if t.startswith(b"W")))
        h = int(next(t[1:] for t in header if t.startswith(b"H")))
        size = w * h * 3 // 2
        while f.readline().startswith(b"FRAME"):
            buf = f.read(size)
            if len(buf) < size:
                return
            yield np.frombuffer(buf, np.uint8, w * h).reshape(h, w)


def main():
    path, warm, n, mode = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), sys.argv[4]
    luma = list(frames(path))[: warm + n]
    imgs = [cv2.cvtColor(y, cv2.COLOR_GRAY2BGR) if mode == "bgr" else y.copy() for y in luma]
    mog = cv2.createBackgroundSubtractorMOG2(history=500, varThreshold=16, detectShadows=True)
    for img in imgs[:warm]:
        mog.apply(img)
    t0 = time.perf_counter()
    for img in imgs[warm:]:
        mog.apply(img)
    dt = time.perf_counter() - t0
    if n:
        print(f"mog2 {mode} {luma[0].shape[1]}x{luma[0].shape[0]}: {dt / n * 1e9:.0f} ns/frame")


if __name__ == "__main__":
    main()
