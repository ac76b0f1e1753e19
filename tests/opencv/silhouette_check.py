"""OpenCV reference checks of the silhouette stage (run by tests/silhouette_opencv.rs).

Usage: silhouette_check.py <check> <dir>, where <dir> holds what the Rust side wrote.
Prints one result line per check and exits non-zero when a check fails.
  undistort: points.json {K, dist, distorted, ours}; ours vs cv2.undistortPoints(P=K)
  contour:   mask.png + contour.json {points}; same boundary pixels as cv2.findContours
  canny:     gray.png + edges.png + canny.json {low, high}; agreement with cv2.Canny
  mog2:      frames/*.png (empty scene first); prints MOG2 ms per frame
"""
import glob
import json
import os
import sys
import time

import cv2
import numpy as np


def undistort(d):
    j = json.load(open(os.path.join(d, "points.json")))
    K = np.array(j["K"], dtype=np.float64).reshape(3, 3)
    dist = np.array(j["dist"], dtype=np.float64)
    pts = np.array(j["distorted"], dtype=np.float64).reshape(-1, 1, 2)
    ours = np.array(j["ours"], dtype=np.float64).reshape(-1, 2)
    plain = cv2.undistortPoints(pts, K, dist, P=K).reshape(-1, 2)
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 200, 1e-12)
    if hasattr(cv2, "undistortPointsIter"):  # OpenCV 4.x
        it = cv2.undistortPointsIter(pts, K, dist, None, K, crit).reshape(-1, 2)
    else:  # OpenCV 5: the criteria are an argument of undistortPoints
        it = cv2.undistortPoints(pts, K, dist, None, K, criteria=crit).reshape(-1, 2)
    e_plain = np.linalg.norm(ours - plain, axis=1).max()
    e_iter = np.linalg.norm(ours - it, axis=1).max()
    print(f"undistort: {len(ours)} points, max |ours - cv2.undistortPoints| = {e_plain:.4f} px, "
          f"max |ours - cv2.undistortPoints(200 iterations)| = {e_iter:.5f} px")
    return e_plain < 0.05 and e_iter < 0.05


def contour(d):
    mask = cv2.imread(os.path.join(d, "mask.png"), cv2.IMREAD_GRAYSCALE)
    ours = json.load(open(os.path.join(d, "contour.json")))["points"]
    cs, _ = cv2.findContours((mask > 0).astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    big = max(cs, key=cv2.contourArea).reshape(-1, 2)
    a = {(int(x), int(y)) for x, y in big}
    b = {(int(round(x)), int(round(y))) for x, y in ours}
    same = a == b
    print(f"contour: cv2.findContours {len(big)} points ({len(a)} distinct), ours {len(ours)} points "
          f"({len(b)} distinct); same boundary pixels: {same}; only cv2 {len(a - b)}, only ours {len(b - a)}")
    return same and len(big) == len(ours)


def canny(d):
    gray = cv2.imread(os.path.join(d, "gray.png"), cv2.IMREAD_GRAYSCALE)
    ours = cv2.imread(os.path.join(d, "edges.png"), cv2.IMREAD_GRAYSCALE) > 0
    j = json.load(open(os.path.join(d, "canny.json")))
    ref = cv2.Canny(gray, j["low"], j["high"]) > 0
    both = np.logical_and(ours, ref).sum()
    agree = both / max(ref.sum(), ours.sum(), 1)
    print(f"canny({j['low']}, {j['high']}): cv2 {ref.sum()} edge px, ours {ours.sum()}, "
          f"common {both}: agreement {100 * agree:.2f} %")
    return agree >= 0.95


def mog2(d):
    files = sorted(glob.glob(os.path.join(d, "frames", "*.png")))
    frames = [cv2.imread(f, cv2.IMREAD_COLOR) for f in files]
    sub = cv2.createBackgroundSubtractorMOG2(history=500, detectShadows=True)
    times = []
    for _ in range(3):
        for f in frames:
            t = time.perf_counter()
            sub.apply(f)
            times.append(time.perf_counter() - t)
    h, w = frames[0].shape[:2]
    print(f"mog2: cv2.createBackgroundSubtractorMOG2 on {w}x{h} colour frames: "
          f"median {1e3 * np.median(times):.2f} ms, min {1e3 * np.min(times):.2f} ms per frame")
    return True


if __name__ == "__main__":
    check, d = sys.argv[1], sys.argv[2]
    ok = {"undistort": undistort, "contour": contour, "canny": canny, "mog2": mog2}[check](d)
    sys.exit(0 if ok else 1)
