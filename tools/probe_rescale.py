#!/usr/bin/env python3
"""Copies a PNG recording at another resolution (frames resized by FACTOR, the camera
matrices of station.yaml scaled to match, pixel centres kept), or re-encoded as JPEG of
the given quality when FACTOR is `jpeg:Q`, or resized by F and encoded by ffmpeg's
libx264 as other tools write MP4s (High profile, B-frames) when FACTOR is `h264:F`. The
truth folder is copied beside it.

    python3 tools/probe_rescale.py SRC_RECORDING DST_RECORDING 0.5
    python3 tools/probe_rescale.py SRC_RECORDING DST_RECORDING jpeg:70
    python3 tools/probe_rescale.py SRC_RECORDING DST_RECORDING h264:1.5
"""
import glob
import os
import re
import shutil
import subprocess
import sys

import cv2

src, dst, how = sys.argv[1], sys.argv[2], sys.argv[3]
shutil.rmtree(dst, ignore_errors=True)
shutil.copytree(src, dst)
shutil.rmtree(dst + ".truth", ignore_errors=True)
shutil.copytree(src + ".truth", dst + ".truth")
frames = sorted(glob.glob(f"{dst}/front/*.png") + glob.glob(f"{dst}/side/*.png"))
if how.startswith("jpeg:"):
    quality = int(how.split(":")[1])
    for path in frames:
        cv2.imwrite(path[:-4] + ".jpg", cv2.imread(path), [cv2.IMWRITE_JPEG_QUALITY, quality])
        os.remove(path)
    sys.exit(0)
h264 = how.startswith("h264:")
f = float(how.split(":")[1]) if h264 else float(how)
for path in frames if f != 1 else []:
    img = cv2.imread(path)
    h, w = img.shape[:2]
    size = (round(w * f), round(h * f))
    interp = cv2.INTER_AREA if f < 1 else cv2.INTER_CUBIC
    cv2.imwrite(path, cv2.resize(img, size, interpolation=interp))
fs = cv2.FileStorage(f"{src}/station.yaml", cv2.FILE_STORAGE_READ)
text = open(f"{src}/station.yaml").read()
for view in ("front", "side"):
    w = int(fs.getNode(f"{view}_image_width").real())
    h = int(fs.getNode(f"{view}_image_height").real())
    k = fs.getNode(f"{view}_camera_matrix").mat()
    k2 = k.copy()
    k2[0, 0] *= f
    k2[1, 1] *= f
    k2[0, 2] = (k[0, 2] + 0.5) * f - 0.5
    k2[1, 2] = (k[1, 2] + 0.5) * f - 0.5
    text = text.replace(f"{view}_image_width: {w}", f"{view}_image_width: {round(w * f)}")
    text = text.replace(f"{view}_image_height: {h}", f"{view}_image_height: {round(h * f)}")
    m = re.search(view + r"_camera_matrix:.*?data: \[([^\]]*)\]", text, re.S)
    text = text[: m.start(1)] + ", ".join(repr(float(x)) for x in k2.ravel()) + text[m.end(1) :]
open(f"{dst}/station.yaml", "w").write(text)
if h264:
    for view in ("front", "side"):
        subprocess.run(
            ["ffmpeg", "-loglevel", "error", "-y", "-framerate", "30",
             "-i", f"{dst}/{view}/%06d.png", "-c:v", "libx264", "-profile:v", "high",
             "-bf", "3", "-crf", "18", "-pix_fmt", "yuv420p", f"{dst}/{view}.mp4"],
            check=True,
        )
        # A frame folder wins over the MP4 (spec/formats.md).
        shutil.rmtree(f"{dst}/{view}")
