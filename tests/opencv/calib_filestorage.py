#!/usr/bin/env python3
"""Reads a station.yaml with cv2.FileStorage and prints its camera nodes as JSON.

Usage: calib_filestorage.py station.yaml
Fails (non-zero exit) when OpenCV cannot read a required node.
"""
import json
import sys

import cv2

fs = cv2.FileStorage(sys.argv[1], cv2.FILE_STORAGE_READ)
if not fs.isOpened():
    raise SystemExit(f"cv2.FileStorage cannot open {sys.argv[1]}")
out = {}
for cam in ("front", "side"):
    node = {}
    for key in ("camera_matrix", "distortion_coefficients", "rotation", "translation"):
        m = fs.getNode(f"{cam}_{key}").mat()
        if m is None:
            raise SystemExit(f"{cam}_{key} missing or not a matrix")
        node[key] = {"shape": list(m.shape), "data": m.ravel().tolist()}
    for key in ("image_width", "image_height"):
        node[key] = int(fs.getNode(f"{cam}_{key}").real())
    out[cam] = node
out["front_rms_px"] = fs.getNode("front_rms_px").string()
fs.release()
print(json.dumps(out))
