#!/usr/bin/env python3
"""Copies a PNG recording made by `fitstation synth-set --format png` with the subject's
cast shadows coloured, as under a warm key light and a cool ambient light: the renderer's
lights are white, so its shadows only darken the floor. Outside the person (its truth
masks), every pixel darker than the empty backdrop (the mean of the recording's empty
frames) is taken as a shadow whose darkening blocks part of the key light; the pixel is
re-coloured, in linear light, by the ratio of that shadow's coloured factor to its grey
one (texture and noise are kept). The truth folder is copied beside it.

    python3 tools/probe_shadow_tint.py SRC_RECORDING DST_RECORDING STRENGTH

STRENGTH 1: key (1.0, 0.9, 0.75) with 30 % of the light from an ambient (0.85, 0.95,
1.1); 2: key (1.0, 0.8, 0.55), ambient (0.7, 0.9, 1.3).
"""
import glob
import json
import os
import shutil
import sys

import cv2
import numpy as np

src, dst, strength = sys.argv[1], sys.argv[2], int(sys.argv[3])
lights = {
    1: ((1.0, 0.9, 0.75), (0.85, 0.95, 1.1)),
    2: ((1.0, 0.8, 0.55), (0.7, 0.9, 1.3)),
}
key_c, amb_c = lights[strength]
# RGB order; images are read as BGR and flipped.
key = 0.7 * np.array(key_c, np.float32)
amb = 0.3 * np.array(amb_c, np.float32)


def to_linear(v):
    e = v / 255.0
    return np.where(e <= 0.04045, e / 12.92, ((e + 0.055) / 1.055) ** 2.4)


def to_srgb(v):
    v = np.clip(v, 0.0, 1.0)
    return 255.0 * np.where(v <= 0.0031308, 12.92 * v, 1.055 * v ** (1 / 2.4) - 0.055)


shutil.rmtree(dst, ignore_errors=True)
shutil.copytree(src, dst)
shutil.rmtree(dst + ".truth", ignore_errors=True)
shutil.copytree(src + ".truth", dst + ".truth")
truth = json.load(open(src + ".truth/truth.json"))
empty = [f["index"] for f in truth["per_frame"] if not f["subject"]]
for view in ("front", "side"):
    paths = sorted(glob.glob(f"{dst}/{view}/*.png"))
    read = lambda p: to_linear(cv2.imread(p)[..., ::-1].astype(np.float32))
    backdrop = np.mean([read(paths[i]) for i in empty], axis=0)
    b_luma = backdrop.mean(axis=2)
    for path in paths:
        mask_path = f"{src}.truth/masks/{view}/{os.path.basename(path)}"
        if not os.path.exists(mask_path):
            continue
        img = read(path)
        person = cv2.imread(mask_path, 0) > 127
        # Keep the person and a soft band about it (the renderer's blurred edge).
        keep = cv2.GaussianBlur(person.astype(np.float32), (0, 0), 1.5) > 0.01
        # Grey shadow factor from the luminance ratio (smoothed: noise is not shadow).
        ratio = cv2.GaussianBlur(img.mean(axis=2), (0, 0), 2.0) / np.maximum(b_luma, 1e-4)
        ratio = np.clip(ratio, 0.0, 1.0)
        # The part of the key light blocked to give that ratio under white light.
        blocked = np.clip((1.0 - ratio) * (key.mean() + amb.mean()) / key.mean(), 0.0, 1.0)
        coloured = (amb + (1.0 - blocked)[..., None] * key) / (amb + key)
        grey = np.maximum(ratio, 1e-4)[..., None]
        factor = np.where((ratio < 0.995)[..., None] & ~keep[..., None], coloured / grey, 1.0)
        out = to_srgb(img * factor)
        cv2.imwrite(path, np.round(out[..., ::-1]).astype(np.uint8))
