"""Reference check of the synthetic renderer's camera model against OpenCV.

Reads cases.json written by tests/synth_projection.rs: for each case a station.yaml
path, station-frame points (metres) and the pixels the renderer projected for each
camera. Every station.yaml must open with cv2.FileStorage; cv2.projectPoints on the
same calibration must agree with the renderer to TOLERANCE_PX. Exit status 0 = pass.
"""
import json
import sys

import cv2
import numpy as np

TOLERANCE_PX = 0.05


def read_camera(fs, prefix):
    k = fs.getNode(prefix + "_camera_matrix").mat()
    d = fs.getNode(prefix + "_distortion_coefficients").mat()
    r = fs.getNode(prefix + "_rotation").mat()
    t = fs.getNode(prefix + "_translation").mat()
    w = int(fs.getNode(prefix + "_image_width").real())
    h = int(fs.getNode(prefix + "_image_height").real())
    for name, m, shape in (("camera_matrix", k, (3, 3)), ("distortion", d, None), ("rotation", r, (3, 3)), ("translation", t, None)):
        if m is None:
            raise SystemExit(f"{prefix}_{name} not readable by cv2.FileStorage")
        if shape is not None and m.shape != shape:
            raise SystemExit(f"{prefix}_{name} has shape {m.shape}")
    if w <= 0 or h <= 0:
        raise SystemExit(f"{prefix} image size not readable")
    return k, d.reshape(-1), r, t.reshape(3, 1)


def main():
    cases = json.load(open(sys.argv[1]))
    worst = 0.0
    count = 0
    for case in cases:
        fs = cv2.FileStorage(case["yaml"], cv2.FILE_STORAGE_READ)
        if not fs.isOpened():
            raise SystemExit(f"cv2.FileStorage cannot open {case['yaml']}")
        pts = np.array(case["points"], dtype=np.float64).reshape(-1, 1, 3)
        for cam in ("front", "side"):
            k, d, r, t = read_camera(fs, cam)
            rvec, _ = cv2.Rodrigues(r)
            px, _ = cv2.projectPoints(pts, rvec, t, k, d)
            px = px.reshape(-1, 2)
            ours = np.array(case[cam], dtype=np.float64).reshape(-1, 2)
            err = np.linalg.norm(px - ours, axis=1)
            worst = max(worst, float(err.max()))
            count += len(err)
        fs.release()
    print(f"cv2.projectPoints vs renderer: {count} projections over {len(cases)} calibrations, worst {worst:.2e} px")
    if worst >= TOLERANCE_PX:
        raise SystemExit(f"FAIL: worst difference {worst} px >= {TOLERANCE_PX}")


if __name__ == "__main__":
    main()
