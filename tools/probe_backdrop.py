#!/usr/bin/env python3
"""Copies a PNG recording made by `fitstation synth-set --format png` with every pixel
outside the person (its truth masks) painted one grey level plus sensor noise: a white,
black or grey studio backdrop. The truth folder is copied beside it.

    python3 tools/probe_backdrop.py SRC_RECORDING DST_RECORDING LEVEL
"""
import glob
import os
import shutil
import sys

import cv2
import numpy as np

src, dst, level = sys.argv[1], sys.argv[2], int(sys.argv[3])
shutil.rmtree(dst, ignore_errors=True)
shutil.copytree(src, dst)
shutil.rmtree(dst + ".truth", ignore_errors=True)
shutil.copytree(src + ".truth", dst + ".truth")
rng = np.random.default_rng(7)
for view in ("front", "side"):
    for path in sorted(glob.glob(f"{dst}/{view}/*.png")):
        img = cv2.imread(path).astype(np.float32)
        mask_path = f"{src}.truth/masks/{view}/{os.path.basename(path)}"
        mask = cv2.imread(mask_path, 0) if os.path.exists(mask_path) else None
        if mask is None:
            mask = np.zeros(img.shape[:2], np.uint8)
        # Soft edge (the lens blur of the renderer's own edges).
        alpha = cv2.GaussianBlur((mask > 127).astype(np.float32), (0, 0), 0.8)[..., None]
        backdrop = level + rng.normal(0.0, 2.0, img.shape).astype(np.float32)
        out = img * alpha + backdrop * (1.0 - alpha)
        cv2.imwrite(path, np.clip(out, 0, 255).astype(np.uint8))
