#!/usr/bin/env python3
"""How full the true bodies' waist sections are: tape girth over the ellipse of the
section's breadth and depth, per synthetic set.

For each `SUBJECT.truth/mesh.obj` of each SET_DIR, slices the body (approximately, as
tools/slice_compare.py: 4 mm grid, no bisection) at its smallest torso girth between
crotch + 0.1 x stature and armpit - 0.05 x stature, and prints per set the median, mean,
least and largest of hull perimeter / Ramanujan perimeter of the ellipse of the torso
loop's x and z extents. ANSUR II's real waists: `python3 tools/ansur_priors.py`
(fit/section_prior.rs gives the fitted waist their median).

Usage: python3 tools/section_fullness.py SET_DIR [SET_DIR ...]   (numpy and scipy)
"""
import glob
import json
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from slice_compare import load_obj, scan  # noqa: E402


def ellipse_perimeter(b, d):
    a, c = b / 2.0, d / 2.0
    return np.pi * (3.0 * (a + c) - np.sqrt((3.0 * a + c) * (a + 3.0 * c)))


def main():
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    for set_dir in sys.argv[1:]:
        values = []
        for truth_dir in sorted(glob.glob(os.path.join(set_dir, "*.truth"))):
            with open(os.path.join(truth_dir, "truth.json")) as f:
                truth = json.load(f)
            verts, tris = load_obj(os.path.join(truth_dir, "mesh.obj"))
            cx = np.median(verts[:, 0])
            stature = truth["measurements_mm"]["stature"] / 1000.0
            lm = truth["landmarks"]
            armpit = 0.5 * (lm["left_armpit"][1] + lm["right_armpit"][1])
            crotch = lm["crotch"][1]
            best = scan(verts, tris, crotch + 0.1 * stature, armpit - 0.05 * stature, cx,
                        lambda s: s[2])
            if best is None:
                continue
            breadth, depth, hull, _ = best[1]
            values.append(hull / ellipse_perimeter(breadth, depth))
        if not values:
            print(f"{set_dir}: no subjects")
            continue
        v = np.array(values)
        print(f"{set_dir}: {len(v)} waists, fullness median {np.median(v):.3f} "
              f"mean {v.mean():.3f} least {v.min():.3f} largest {v.max():.3f}")


if __name__ == "__main__":
    main()
