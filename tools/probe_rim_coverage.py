#!/usr/bin/env python3
"""Would deciding the rim of the station's masks by coverage raise their IoU? (A probe
of session 33; the station does not do this.)

For each frame of a synthetic recording whose masks the station wrote (`replay REC --out
DIR --masks-out MASKS`), every pixel of the one-pixel rim of the station's mask (inside
or outside its outline) is decided again by its coverage in linear light: its colour
placed between the backdrop (the mean of the recording's first 8 frames, which show no
one) and the person (the mean colour of the mask's interior, 2 px or more inside, within
3 px), foreground at 0.5. Rim pixels with too little interior near them, or whose
person and backdrop colours lie within 15 levels, keep the station's decision. Prints the
station's IoU against the truth's masks and the probe's, over the frames with a subject.

Usage: python3 tools/probe_rim_coverage.py RECORDING MASKS VIEW
   e.g. target/release/fitstation replay out/judge_ansur/subject_05 --out out/fit05 --masks-out out/fit05/masks
        python3 tools/probe_rim_coverage.py out/judge_ansur/subject_05 out/fit05/masks side
"""
import glob
import sys

import numpy as np
from PIL import Image
from scipy import ndimage

BACKDROP_FRAMES = 8
INTERIOR_BOX_PX = 7
MIN_CONTRAST = 15.0


def linear(a):
    a = a / 255.0
    return np.where(a <= 0.04045, a / 12.92, ((a + 0.055) / 1.055) ** 2.4) * 255.0


def main():
    if len(sys.argv) != 4:
        sys.exit(__doc__)
    rec, masks, view = sys.argv[1:]
    frames = sorted(glob.glob(f"{rec}/{view}/*.png"))
    backdrop = np.mean([linear(np.array(Image.open(f)).astype(float))
                        for f in frames[:BACKDROP_FRAMES]], 0)
    inter = {"station": 0, "probe": 0}
    union = {"station": 0, "probe": 0}
    for path in sorted(glob.glob(f"{masks}/{view}/*.png")):
        name = path.split("/")[-1]
        mask = np.array(Image.open(path)) > 127
        truth = np.array(Image.open(f"{rec}.truth/masks/{view}/{name}")) > 127
        if truth.sum() == 0:
            continue
        img = linear(np.array(Image.open(f"{rec}/{view}/{name}")).astype(float))
        rim = ndimage.binary_dilation(mask) & ~ndimage.binary_erosion(mask)
        interior = ndimage.binary_erosion(mask, iterations=2).astype(float)
        share = ndimage.uniform_filter(interior, INTERIOR_BOX_PX)
        person = np.stack([ndimage.uniform_filter(img[..., c] * interior, INTERIOR_BOX_PX)
                           for c in range(3)], -1) / np.maximum(share, 1e-9)[..., None]
        d = person - backdrop
        dd = (d * d).sum(-1)
        alpha = ((img - backdrop) * d).sum(-1) / np.maximum(dd, 1e-9)
        decide = rim & (share > 0.02) & (dd > MIN_CONTRAST ** 2)
        probe = mask.copy()
        probe[decide] = alpha[decide] >= 0.5
        for key, m in (("station", mask), ("probe", probe)):
            inter[key] += int((m & truth).sum())
            union[key] += int((m | truth).sum())
    if not union["station"]:
        sys.exit("no frame with a subject")
    print(f"{masks} {view}: IoU station {inter['station'] / union['station']:.4f}, "
          f"rim by coverage {inter['probe'] / union['probe']:.4f}")


if __name__ == "__main__":
    main()
