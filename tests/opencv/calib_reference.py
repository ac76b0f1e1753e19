#!/usr/bin/env python3
"""OpenCV reference for fitstation's calibration (issue 7).

Usage: calib_reference.py OURS.json OUT.json

OURS.json (written by tests/calibrate_opencv.rs) names the images, the board, and our
corners per image (OpenCV order, pixels). For every image this script finds the board
with cv2.findChessboardCornersSB and with cv2.findChessboardCorners + cv2.cornerSubPix,
matches each of our corners to the nearest OpenCV corner, and calibrates with
cv2.calibrateCamera (flags 0: fx fy cx cy k1 k2 p1 p2 k3) both on OpenCV's own corners
and on ours. OUT.json receives the per-corner differences and the calibrations; the
Rust test applies the tolerances.
"""
import json
import sys

import cv2
import numpy as np


def calibrate(obj, img_pts, size):
    crit = (cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 100, 1e-12)
    rms, k, d, _, _ = cv2.calibrateCamera(obj, img_pts, size, None, None, flags=0, criteria=crit)
    d = d.ravel().tolist()
    return {"rms": float(rms), "fx": float(k[0, 0]), "fy": float(k[1, 1]), "cx": float(k[0, 2]),
            "cy": float(k[1, 2]), "dist": [float(x) for x in d[:5]]}


def nearest_diffs(ours, theirs):
    ours = np.asarray(ours, dtype=np.float64).reshape(-1, 2)
    theirs = np.asarray(theirs, dtype=np.float64).reshape(-1, 2)
    d = np.linalg.norm(ours[:, None, :] - theirs[None, :, :], axis=2)
    return d.min(axis=1).tolist()


def main():
    ours = json.load(open(sys.argv[1]))
    cols, rows, square = ours["cols"], ours["rows"], ours["square_m"]
    size = (ours["width"], ours["height"])
    objp = np.zeros((rows * cols, 3), np.float32)
    objp[:, :2] = np.mgrid[0:cols, 0:rows].T.reshape(-1, 2) * square
    sets = ours["corner_sets"]
    if ours.get("target") == "circles":
        return circles(ours, objp, size, sets)
    out = {"opencv_version": cv2.__version__, "found_sb": 0, "found_classic": 0, "sb_corners": [],
           "subpix_corners": [], "diffs": {name: {"sb": [], "subpix": []} for name in sets}}
    obj_sb, pts_sb, obj_sp, pts_sp = [], [], [], []
    crit = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 40, 0.001)
    for k, path in enumerate(ours["images"]):
        gray = cv2.imread(path, cv2.IMREAD_GRAYSCALE)
        if gray is None:
            raise SystemExit(f"cannot read {path}")
        ok, sb = cv2.findChessboardCornersSB(gray, (cols, rows), flags=cv2.CALIB_CB_ACCURACY)
        out["sb_corners"].append(sb.reshape(-1, 2).tolist() if ok else None)
        if ok:
            out["found_sb"] += 1
            obj_sb.append(objp)
            pts_sb.append(sb.astype(np.float32))
        ok2, cl = cv2.findChessboardCorners(gray, (cols, rows), flags=cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE)
        sp = cv2.cornerSubPix(gray, cl, (5, 5), (-1, -1), crit) if ok2 else None
        out["subpix_corners"].append(sp.reshape(-1, 2).tolist() if ok2 else None)
        if ok2:
            out["found_classic"] += 1
            obj_sp.append(objp)
            pts_sp.append(sp.astype(np.float32))
        for name, views in sets.items():
            our = views[k]
            if our is None:
                continue
            if ok:
                out["diffs"][name]["sb"] += nearest_diffs(our, sb)
            if ok2:
                out["diffs"][name]["subpix"] += nearest_diffs(our, sp)
    if len(pts_sp) >= 3:
        out["calib_subpix"] = calibrate(obj_sp, pts_sp, size)
    if len(pts_sb) >= 3:
        out["calib_sb"] = calibrate(obj_sb, pts_sb, size)
    out["calib_ours"] = {}
    for name, views in sets.items():
        pts = [np.asarray(v, np.float32).reshape(-1, 1, 2) for v in views if v is not None]
        if len(pts) >= 3:
            out["calib_ours"][name] = calibrate([objp] * len(pts), pts, size)
    json.dump(out, open(sys.argv[2], "w"), indent=1)


def circles(ours, objp, size, sets):
    """Symmetric circle grid: cv2.findCirclesGrid centres, diffs and calibrations."""
    cols, rows = ours["cols"], ours["rows"]
    out = {"opencv_version": cv2.__version__, "found": 0, "circle_centres": [],
           "diffs": {name: [] for name in sets}}
    obj, pts = [], []
    for k, path in enumerate(ours["images"]):
        gray = cv2.imread(path, cv2.IMREAD_GRAYSCALE)
        if gray is None:
            raise SystemExit(f"cannot read {path}")
        ok, c = cv2.findCirclesGrid(gray, (cols, rows), flags=cv2.CALIB_CB_SYMMETRIC_GRID)
        out["circle_centres"].append(c.reshape(-1, 2).tolist() if ok else None)
        if not ok:
            continue
        out["found"] += 1
        obj.append(objp)
        pts.append(c.astype(np.float32))
        for name, views in sets.items():
            if views[k] is not None:
                out["diffs"][name] += nearest_diffs(views[k], c)
    if len(pts) >= 3:
        out["calib_circles"] = calibrate(obj, pts, size)
    out["calib_ours"] = {}
    for name, views in sets.items():
        p = [np.asarray(v, np.float32).reshape(-1, 1, 2) for v in views if v is not None]
        if len(p) >= 3:
            out["calib_ours"][name] = calibrate([objp] * len(p), p, size)
    json.dump(out, open(sys.argv[2], "w"), indent=1)


if __name__ == "__main__":
    main()
